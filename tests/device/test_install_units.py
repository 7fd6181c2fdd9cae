"""The device package's install units (docs/method-and-formats.md "The device package"), under
the real MicroPython: a board given core and logger alone (no acal/paper, no acal/discover on its
path) runs the wear profile's base model through its calibrations and logs the same bytes as with
the whole package, and loads no module of the units it lacks (sys.modules); a paper-profile board
loads acal.paper and a discovering one acal.discover, which the base-only install cannot import."""
import shutil
from pathlib import Path

import numpy as np
import pytest

from accelcal.bridge import runtime
from accelcal.errors import InterpreterFailed
from posture_stream import STREAM as SCRIPT
from test_discover import C_TRUE, GAP_SAMPLES, postures

POSTURES = 200     # 26 h of rest postures: the wear bins fill and the board calibrates


@pytest.fixture(scope="module")
def script(tmp_path_factory):
    f = tmp_path_factory.mktemp("units") / "units.py"
    f.write_text(SCRIPT % (postures(np.random.default_rng(5), C_TRUE, POSTURES), GAP_SAMPLES))
    return f


@pytest.fixture(scope="module")
def base_only(tmp_path_factory):
    """A device path holding the package's core and logger units only, as a base board's (as
    the unix port runs the whole package: emitted, runtime.emitted_device_dir)."""
    root = tmp_path_factory.mktemp("base_only")
    whole = Path(runtime.emitted_device_dir()) / "acal"
    (root / "acal").mkdir()
    shutil.copy(whole / "__init__.py", root / "acal" / "__init__.py")
    for unit in ("core", "logger"):
        shutil.copytree(whole / unit, root / "acal" / unit)
    assert sorted((root / "acal").iterdir()) != sorted(whole.iterdir())
    return root


def _run(script, tmp_path, name, settings, device_path=None):
    log_path = tmp_path / f"{name}.bin"
    kw = {"device_path": str(device_path)} if device_path else {}
    out = runtime.run_micropython_script(str(script), str(log_path), repr(settings), **kw)
    lines = dict(line.split(" ", 1) for line in out.splitlines() if " " in line)
    return int(lines["CALIBRATIONS"]), lines["MODULES"].split(), log_path.read_bytes()


def test_a_base_board_loads_no_discovery_nor_paper(script, base_only, tmp_path):
    n, mods, data = _run(script, tmp_path, "base_only", {}, base_only)
    assert n >= 1, "the stream must reach a calibration, or the fit's imports went untested"
    assert "acal.core.gaussnewton" in mods and "acal.logger.processor" in mods
    assert not [m for m in mods if m.startswith(("acal.discover", "acal.paper"))], mods
    n_all, mods_all, data_all = _run(script, tmp_path, "whole", {})
    assert (n_all, mods_all, data_all) == (n, mods, data)   # the whole package: the same run


def test_the_other_units_load_where_used_and_only_there(script, base_only, tmp_path):
    _, mods, _ = _run(script, tmp_path, "paper", {"profile": 0})
    assert "acal.paper.optimiser" in mods and not [m for m in mods if m.startswith("acal.discover")]
    _, mods, _ = _run(script, tmp_path, "discover", {"discover": True})
    assert "acal.discover.search" in mods and not [m for m in mods if m.startswith("acal.paper")]
    with pytest.raises(InterpreterFailed, match="acal.discover"):
        _run(script, tmp_path, "missing", {"discover": True}, base_only)
