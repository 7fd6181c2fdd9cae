"""One path from a file to its calibration record: `calibrate FILE`, every file of a batch and
`accelcal.calibrate()` all go through calibrate_file(path, job), so they follow one rule (a
recording or a points file, --fallback for either, the options checked the same way)."""
from __future__ import annotations

from dataclasses import dataclass

from accelcal.bridge import runtime
from accelcal.errors import InputError, ModelUnsupported
from accelcal.pipeline.results import CalibrationResult
from accelcal.vocabulary import documented

Config = runtime.Config
RUNTIMES = runtime.RUNTIMES
AUTO = "auto"
AUTO_MODEL = "base+temp_offset"


@dataclass
class Job:
    """What every file gets: the pipeline settings and the calibrate options (picklable, for
    the pool and for Dask)."""
    cfg: runtime.Config
    method: str = "device"
    runtime: str = "cpython"
    model: str = AUTO
    engine: str = "vector"
    fallback: str | None = None
    points: str = "bins"
    effects: str | None = None     # a user's effects file, registered in each worker

    @classmethod
    @documented
    def of(cls, *, model: str | None = None, method: str = "device", profile: str = "wear",
           runtime: str = "cpython", engine: str | None = None, fallback: str | None = None,
           points: str = "bins", effects: str | None = None, cfg: runtime.Config | None = None,
           **settings) -> "Job":
        """A job from plain options.  cfg: the pipeline settings (None: the profile's, with any
        settings given as runtime.Config fields: seconds=10, max_count=4, ...).  engine None:
        vector under cpython, device under a MicroPython runtime (as the CLI).  Every argument
        is checked as the CLI checks its option (files/arguments.py): InputError, one line.
        model None: the default, auto (calibrate_auto) for the device method, the paper's
        model (base) for the float reference methods and for --discover (which starts from it)."""
        from accelcal.files import arguments as a
        from accelcal.methods import METHODS
        a.paths(fallback=fallback, effects=effects)
        a.choice("method", method, ["device", *METHODS])
        a.choice("runtime", runtime, RUNTIMES)
        a.choice("points", points)
        if engine is not None:
            a.choice("engine", engine)
        if model is not None and not isinstance(model, str):
            raise InputError(f"model {model!r:.60}: a model name such as base or base+temp_offset")
        if cfg is None:
            cfg = Config.for_profile(a.choice("profile", profile), "+" in (model or ""),
                                     **a.pipeline_settings(settings))
        elif settings:
            raise InputError(f"settings {', '.join(settings)} given with cfg: give one or the other")
        elif not isinstance(cfg, Config):
            raise InputError(f"cfg {cfg!r:.60}: a Config (accelcal.Config.for_profile(...))")
        if model is None:
            model = AUTO if method == "device" and not cfg.discover else "base"
        return cls(cfg, method, runtime, model,
                   engine or ("vector" if runtime == "cpython" else "device"),
                   fallback, points, effects)

    def spec(self):
        """The job's model, its options checked (bad options are bad input, before any file is
        read).  AUTO: the paper's model is checked here; calibrate_file chooses."""
        from accelcal.model.declared import register
        from accelcal.model.effects import ModelSpec
        register(self.effects)   # a worker process starts with the built-in catalogue
        if self.model == AUTO and (self.method not in ("device", "lsq") or self.cfg.discover):
            raise InputError(f"--model {AUTO} chooses between base and {AUTO_MODEL}, fitted by "
                             "--method device or lsq, without --discover")
        try:
            spec = ModelSpec.parse("base" if self.model == AUTO else self.model)
        except ValueError as e:
            raise InputError(str(e)) from None
        if spec.effects and self.method not in ("device", "lsq"):
            raise InputError(f"model {spec}: composed models are fitted by --method device (the "
                             "device's integer optimiser) or lsq (float; --points bins|all)")
        if self.cfg.min_count > self.cfg.max_count:   # the bound itself: runtime.Config
            raise InputError(f"min_count {self.cfg.min_count} > max_count {self.cfg.max_count}")
        if self.points != "bins" and self.method == "device":
            raise InputError("--points applies to the float methods (--method lsq, ...); the "
                             "device method fits the points its bins select")
        if self.fallback:
            from accelcal.files.params import load_params
            load_params(self.fallback)
        return spec


def calibrate_auto(path: str, job: Job, progress=None) -> CalibrationResult:
    """`--model auto`: the GGIR family's default, a temperature offset beside the paper's model
    where the data has temperature (base+temp_offset, fitted with the composed model's settings:
    pipeline/compare.py composed_config), the paper's model where it has none or the composed
    fit does not calibrate (its spread not reached: too short, too little temperature range).
    The record says which (`model`, and `auto` with the reason); docs/real-recordings.md
    "Temperature in the default" gives the held-out figures it was chosen by."""
    from dataclasses import replace
    from accelcal.pipeline.compare import composed_config
    composed = replace(job, model=AUTO_MODEL, cfg=composed_config(job.cfg),
                       points="all" if job.method == "lsq" else job.points)
    if _without_temperature(path):   # known from the header: no scan spent on the composed try
        rec = calibrate_file(path, replace(job, model="base"), progress)
        rec["auto"] = f"the paper's model: {AUTO_MODEL} does not apply (no temperature column)"
        return rec
    try:
        rec = calibrate_file(path, composed, progress)
        if rec.ok:
            rec["auto"] = "temperature in the data: the paper's model and a temperature offset"
            return rec
        why = f"{AUTO_MODEL} did not calibrate ({rec.get('reason')})"
    except ModelUnsupported as e:   # no temperature column, too little spread (any other bad
        # input stops here: a file cut short while read is not a reason for the paper's model)
        why = f"{AUTO_MODEL} does not apply ({str(e).removeprefix(f'{path}: ')})"
    rec = calibrate_file(path, replace(job, model="base"), progress)
    rec["auto"] = f"the paper's model: {why}"
    return rec


def _without_temperature(path) -> bool:
    """A recording whose header says it has no temperature: a CSV, a .cwa (its first block) or
    samples in memory; other formats are read whole to know, so they are not asked here."""
    from accelcal.files.readers import in_memory, is_recording
    if not (in_memory(path) or str(path).lower().endswith((".csv", ".cwa"))) \
            or not is_recording(path):
        return False
    from accelcal.files.recordings import open_recording
    return not open_recording(path).has_temp


@documented
def calibrate_file(path, job: Job, progress=None) -> CalibrationResult:
    """One file's record, a recording or a points file (one device): status calibrated,
    not_enough_data or failed; with job.fallback a file that did not calibrate takes it, said so.
    Bad input (an unreadable file, bad options) raises InputError; a batch makes it the file's
    record (pipeline/batch.py).  progress(samples read): a recording's reading."""
    from accelcal.files.arguments import paths
    from accelcal.files.arrays import as_input
    from accelcal.files.readers import is_recording
    from accelcal.pipeline.calibrate import calibrate_groups, calibrate_recording, use_fallback
    path = as_input(path)   # a file, or samples in memory (with their times: a frame's own)
    paths(path=path, required=("path",))
    if not isinstance(job, Job):
        raise InputError(f"job={job!r:.60}: a Job (accelcal.Job.of(...))")
    if job.model == AUTO:
        return calibrate_auto(path, job, progress)
    spec = job.spec()
    if is_recording(path):
        return calibrate_recording(path, job.cfg, job.method, job.runtime, spec, job.engine,
                                   progress=progress, fallback=job.fallback, points=job.points)
    from accelcal.files.table import read_table
    rec = CalibrationResult(file=path, format="points", **calibrate_groups(
        read_table(path), None, job.cfg, job.method, job.runtime, spec, job.points)[0])
    rec["calibration"] = "new" if rec.ok else "none"
    if not rec.ok and job.fallback:
        import numpy as np
        use_fallback(rec, job.fallback, np.zeros((0, 3)))
    return rec


def calibrate_by(path: str, by: str, job: Job) -> list[CalibrationResult]:
    """A points file calibrated per value of its column `by` (one record per device)."""
    from accelcal.files.readers import is_recording
    from accelcal.files.table import read_table
    from accelcal.pipeline.calibrate import calibrate_groups
    if job.fallback:
        raise InputError("--fallback is one device's calibration; --by calibrates each device "
                         "of the file")
    if job.model == AUTO:
        raise InputError(f"--model {AUTO} chooses per file; with --by name the model (base or "
                         f"{AUTO_MODEL})")
    spec = job.spec()
    if is_recording(path):
        raise InputError(f"{path}: --by applies to points files; this is a recording")
    return calibrate_groups(read_table(path), by, job.cfg, job.method, job.runtime, spec,
                            job.points)


@documented
def calibrate(path, *, model: str | None = None, method: str = "device", profile: str = "wear",
              runtime: str = "cpython", fallback: str | None = None, points: str = "bins",
              effects: str | None = None, progress=None, rate: float | None = None, temp=None,
              time=None, **settings) -> CalibrationResult:
    """A file's calibration, as `accelcal calibrate FILE --json` gives it: the record
    (CalibrationResult, a dict) with status, params (decoded), params_int (Q24), error before
    and after (mg) and, for a recording, its quality.  model: a spec, "auto" (calibrate_auto),
    or None, the default: auto for the device method, base for the float methods (Job.of).
    settings: Job.of's (engine, cfg, or runtime.Config fields)."""
    from accelcal.files.arrays import as_input
    path = as_input(path, rate, temp, time)
    return calibrate_file(path, Job.of(model=model, method=method, profile=profile,
                                       runtime=runtime, fallback=fallback, points=points,
                                       effects=effects, **settings), progress)
