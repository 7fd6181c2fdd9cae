"""accelcal: accelerometer self-calibration (Farago 2024) on the device and beside it.

The public API, what the commands do, callable from Python (docs/command-line.md "From Python"):

    import accelcal
    rec = accelcal.calibrate("wrist.csv", model="base+temp_offset")   # a CalibrationResult
    rec.status, rec.params["kxx"].value, rec.error_after_mg   # or rec["status"], as the JSON
    print(rec.summary())
    accelcal.diagnose("wrist.csv").report()                            # a DiagnoseResult

Each name is imported on first use, so `import accelcal` (and the `accelcal` command) stays fast.
"""
from __future__ import annotations

import importlib

# name -> the module that defines it
_WHERE = {
    "calibrate": "accelcal.pipeline.job",
    "calibrate_file": "accelcal.pipeline.job",
    "Job": "accelcal.pipeline.job",
    "diagnose": "accelcal.pipeline.diagnose",
    "compare": "accelcal.pipeline.compare",
    "apply": "accelcal.pipeline.apply",
    "simulate_wrist": "accelcal.simulate.public",
    "CalibrationResult": "accelcal.pipeline.results",
    "DiagnoseResult": "accelcal.pipeline.results",
    "CompareResult": "accelcal.pipeline.results",
    "ApplyResult": "accelcal.pipeline.results",
    "Params": "accelcal.pipeline.record",
    "Param": "accelcal.pipeline.record",
    "ModelSpec": "accelcal.model.effects",
    "CATALOGUE": "accelcal.model.effects",
    "Config": "accelcal.bridge.protocol",
    "InputError": "accelcal.errors",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name == "__version__":   # the project's one version number (device/acal/__init__.py)
        from acal import __version__
        return __version__
    if name not in _WHERE:
        raise AttributeError(f"module 'accelcal' has no attribute {name!r}")
    value = getattr(importlib.import_module(_WHERE[name]), name)
    globals()[name] = value   # the next use is a plain attribute
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
