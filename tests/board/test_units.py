"""The install units (issue 48 part 1): device/UNIT.json for mip, device/manifests/UNIT for a
firmware that freezes only what its board runs, and package.json, all as the one walk of the
package gives them (tools/units.py --check); what a firmware build would freeze from each unit,
read by MicroPython's own manifest code (tests/data/third_party/micropython/manifestfile.py, v1.28.0)."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from accelcal.board import tree
from accelcal.locations import DEVICE_UNITS, device_modules, package_sources
from conftest import ROOT, mpremote


def frozen(manifest: Path, tmp: Path) -> list[str]:
    """The files a MicroPython firmware built with FROZEN_MANIFEST=manifest freezes (targets in
    the firmware, e.g. acal/core/bins.py), as its build reads the manifest (a port whose own
    boards/manifest.py freezes nothing)."""
    spec = importlib.util.spec_from_file_location(
        "manifestfile", ROOT / "tests" / "data" / "third_party" / "micropython" / "manifestfile.py")
    mf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mf)
    port = tmp / "port"
    (port / "boards").mkdir(parents=True, exist_ok=True)
    (port / "boards" / "manifest.py").write_text("")
    m = mf.ManifestFile(mf.MODE_FREEZE, {"MPY_DIR": str(tmp), "MPY_LIB_DIR": None,
                                         "PORT_DIR": str(port), "BOARD_DIR": str(port)})
    m.execute(str(manifest))
    return sorted(f.target_path for f in m.files())


def micropython_files(*units: str) -> list[str]:
    return sorted(f"acal/{p.as_posix()}" for p in package_sources(False, units=units))


def test_the_units_files_are_the_walks():
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "units.py"), "--check"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_check_names_a_unit_file_that_differs(tmp_path, monkeypatch):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import units
    finally:
        sys.path.pop(0)
    monkeypatch.setattr(units, "ROOT", tmp_path)
    (tmp_path / "device").mkdir()
    assert units.main([]) == 0 and units.main(["--check"]) == 0
    (tmp_path / "device" / "paper.json").write_text("{}\n")
    assert units.main(["--check"]) == 1


@pytest.mark.parametrize("unit", DEVICE_UNITS)
def test_a_units_manifest_freezes_the_unit_and_what_it_needs(unit, tmp_path):
    """core freezes core (and the package's __init__); every other unit itself and core; no
    unit the CircuitPython driver, which no MicroPython firmware runs."""
    got = frozen(ROOT / "device" / tree.UNIT_MANIFEST.format(unit=unit), tmp_path)
    assert got == micropython_files(*{"core", unit})
    assert not [f for f in got if "lis3dh_cp" in f]


def test_a_base_board_freezes_core_and_logger_only(tmp_path):
    base = tmp_path / "base.py"
    base.write_text("".join(f'include("{ROOT / "device" / "manifests" / u}")\n' for u in ("core", "logger")))
    got = frozen(base, tmp_path)
    assert got == micropython_files("core", "logger")
    assert not [f for f in got if f.startswith(("acal/paper/", "acal/discover/"))]
    everything = tmp_path / "all.py"
    everything.write_text("".join(f'include("{ROOT / "device" / "manifests" / u}")\n' for u in DEVICE_UNITS))
    assert frozen(everything, tmp_path) == micropython_files(*DEVICE_UNITS)


def test_one_walk_for_the_interpreters_and_the_boards():
    """The host's interpreters load what a CircuitPython deploy copies: the same walk."""
    assert device_modules() == [p.as_posix() for p in package_sources(True)]
    assert device_modules() == sorted(p.relative_to(ROOT / "device" / "acal").as_posix()
                                      for p in (ROOT / "device" / "acal").rglob("*.py"))


def test_mip_takes_a_unit_by_http_and_by_path_not_by_file_url(tmp_path):
    """The routes that need no repository name (docs/boards-and-logs.md "Install units"): a unit
    served over http (`python -m http.server` in the checkout) and a local path, each resolving
    the unit's relative urls against its own folder; mpremote takes no file:// url."""
    import functools
    import http.server
    import threading

    import numpy as np

    import test_app
    from accelcal.board import virtual
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(ROOT))
    handler.log_message = lambda *a: None
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    stim = tmp_path / "stim.bin"
    test_app.stimulus(stim, np.random.default_rng(1), n_rest=2)
    try:
        with virtual.Running(tmp_path / "flash", stim) as b:
            mpremote(b.port, "mip", "install", "--target", "lib",
                     f"http://127.0.0.1:{srv.server_address[1]}/device/core.json")
            mpremote(b.port, "mip", "install", "--target", "lib", "device/logger.json", cwd=ROOT)
            out = mpremote(b.port, "exec", "from acal.logger.processor import Processor\n"
                           "print(type(Processor(None, 10)).__name__)")
            r = subprocess.run([sys.executable, "-m", "mpremote", "connect", b.port, "mip", "install",
                                "--target", "lib", f"file://{ROOT}/device/paper.json"],
                               capture_output=True, text=True, timeout=120)
    finally:
        srv.shutdown()
    assert out.strip() == "Processor"
    lib = tmp_path / "flash" / "lib"
    assert sorted(p.relative_to(lib).as_posix() for p in lib.rglob("*.py")) == \
        sorted(f"acal/{f}" for u in ("core", "logger") for f in tree.unit_files(u))
    assert r.returncode != 0 and "file://" in r.stdout + r.stderr
