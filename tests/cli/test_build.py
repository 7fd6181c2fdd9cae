"""`make build` (accelcal.cli.build): per board with an arch, the prebuilt `.mpy` with a mip
package.json that puts them, the board file, main.py and the settings where `deploy` does, and a
freeze manifest.py.  The mip route then gives the same running code as deploy: a build for the
unix port's own arch (x64, viper) installed with the real `mpremote mip` onto the virtual board,
every module loading from its `.mpy` and `acquire` running with the recorded settings."""
import json
import subprocess
import sys

import numpy as np

import test_app
from accelcal.board import deploy, tree, virtual
from accelcal.cli.build import build_board, default_settings
from accelcal.locations import DEVICE_UNITS
from conftest import ROOT, mpremote
from test_units import frozen

DEVICE = ROOT / "device" / "acal"


def test_each_board_gets_mpy_a_package_json_and_a_manifest(tmp_path):
    options, app = default_settings()
    assert options["rate"] == 100 and app == {"rate_hz": 100, "profile": 1}
    for board, arch in (("pico", "armv6m"), ("esp32", "xtensawin")):
        made = build_board(board, tmp_path)
        d = tmp_path / board
        assert made["what"] == f".mpy for {arch}"
        urls = json.loads((d / "package.json").read_text())["urls"]
        want = [f"lib/acal/{p.with_suffix('.mpy').as_posix()}" for p in tree.package_sources(False)]
        assert [dst for dst, _ in urls] == want + ["acal_board.py", "main.py", "acal_settings.json"]
        assert all(dst == src and (d / src).is_file() for dst, src in urls)
        assert all((d / m).read_bytes()[:2] == b"M\x06" for m in want)   # MicroPython's .mpy v6
        assert (d / "acal_board.py").read_text() == (ROOT / "boards" / f"{board}.py").read_text()
        assert (d / "main.py").read_text() == deploy.main_py(app)
        rec = json.loads((d / "acal_settings.json").read_text())
        assert rec["options"] == options and rec["app"] == app and rec["board"] == board
        # the firmware freezes the units the default settings run (core, logger) and the board file
        assert frozen(d / "freeze" / "manifest.py", tmp_path / "mf") == \
            sorted(f"acal/{p.as_posix()}" for p in tree.package_sources(False, units=("core", "logger"))) + ["acal_board.py"]
        assert all((d / "freeze" / "manifests" / u / "manifest.py").is_file() for u in DEVICE_UNITS)
        sources = sorted(p.relative_to(d / "freeze" / "acal").as_posix()
                         for p in (d / "freeze" / "acal").rglob("*.py"))
        assert sources == sorted(p.as_posix() for p in tree.package_sources(False))
        # the hot loops frozen as viper, as the .mpy have them
        marked = [p for p in DEVICE.rglob("*.py") if "\n@viper\n" in p.read_text()
                  or "    @viper\n" in p.read_text()]
        assert marked and all("@micropython.viper" in (d / "freeze" / "acal" / p.relative_to(DEVICE)).read_text()
                              for p in marked)


def test_the_mip_route_runs_what_deploy_runs(tmp_path):
    build_board("virtual", tmp_path / "build", dict(deploy.board_info("virtual"), ARCH="x64"))
    stim = tmp_path / "stim.bin"
    test_app.stimulus(stim, np.random.default_rng(2), n_rest=4)
    flash = tmp_path / "flash"

    with virtual.Running(flash, stim) as b:
        # --target .: the board's current folder, / on a board (the unix port's flash folder)
        mpremote(b.port, "mip", "install", "--target", ".", str(tmp_path / "build" / "virtual" / "package.json"))
        names = ["acal." + tree.module_name(p) if tree.module_name(p) else "acal"
                 for p in tree.package_sources(False)]
        out = mpremote(b.port, "exec", "import sys\nfor m in %r:\n    __import__(m)\n"
                       "    print(m, sys.modules[m].__file__)" % names)
        r = subprocess.run([sys.executable, "-m", "accelcal.cli", "acquire", "--port", b.port,
                            "--hours", "0.01"], capture_output=True, text=True)
    files = dict(line.split() for line in out.splitlines())
    assert sorted(files) == sorted(names) and all(f.endswith(".mpy") for f in files.values())
    assert r.returncode == 0, r.stderr
    assert "ACAL_DONE 3600 " in r.stdout + r.stderr   # 36 s at the recorded 100 Hz
    assert (flash / "main.py").read_text() == deploy.main_py(default_settings()[1])
