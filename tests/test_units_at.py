"""tools/units_at.py, issue 48's before/after in one run: each install unit's import time and free
heap on the emulated Pico for an older revision's device package and this checkout's.  Its bad
input is refused in one line; a revision whose package equals the checkout's gives the same
figures (the emulator counts the chip's cycles), and the figures are the bench's
(mp_units_bench.py) for this checkout."""
import subprocess
import sys

import pytest

from conftest import ROOT

TOOL = ROOT / "tools" / "units_at.py"


@pytest.mark.parametrize("args, says", [(["no-such-revision"], "is not a revision"),
                                        (["--cases", "base,nowhere"], "no case 'nowhere'")])
def test_bad_input_is_one_line(args, says):
    r = subprocess.run([sys.executable, str(TOOL), *args], capture_output=True, text=True)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and says in r.stderr and "Traceback" not in r.stderr


def test_the_module_order_imports_one_module_at_a_time():
    """--modules imports the package one module at a time so that each import's heap is that
    module's alone: in the order import_order gives, CPython's own import system loads exactly
    the module named at each step, and every module of the package but lis3dh_cp is named."""
    code = (
        "import importlib, sys\n"
        f"sys.path[:0] = [{str(ROOT / 'tools')!r}, {str(ROOT / 'host')!r}, {str(ROOT / 'device')!r}]\n"
        "import units_at\n"
        "from accelcal.locations import DEVICE_PACKAGE\n"
        "order = units_at.import_order(DEVICE_PACKAGE)\n"
        "for k in [k for k in sys.modules if k.split('.')[0] == 'acal']:\n"
        "    del sys.modules[k]\n"
        "for name in order:\n"
        "    before = set(sys.modules)\n"
        "    importlib.import_module(name)\n"
        "    print(name, *sorted(set(sys.modules) - before))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    steps = [line.split() for line in r.stdout.splitlines()]
    for name, *loaded in steps:
        assert [m for m in loaded if m.split(".")[0] == "acal"] == [name], (name, loaded)
    files = {".".join(("acal", *p.relative_to(ROOT / "device" / "acal").with_suffix("").parts))
             for p in (ROOT / "device" / "acal").rglob("*.py")}
    named = {s[0] for s in steps}
    assert named >= (files - {"acal.__init__", "acal.logger.lis3dh_cp"}) | {"acal"}
    assert "acal.logger.lis3dh_cp" not in named and len(named) == len(steps)


@pytest.mark.slow
def test_a_revision_with_this_package_gives_its_figures():
    # HEAD's device/acal is the checkout's when the tree holds no change to it
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    if subprocess.run(["git", "-C", str(ROOT), "diff", "--quiet", "HEAD", "--", "device/acal"]).returncode:
        pytest.skip("device/acal differs from HEAD")
    r = subprocess.run([sys.executable, str(TOOL), "HEAD", "--cases", "base"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    rows = {line.split()[0]: line.split()[1:] for line in r.stdout.splitlines()}
    assert set(rows) == {"units_base_" + k for k in ("import_app_us", "free_after_import_bytes",
                                                     "free_with_processor_bytes", "modules")}
    for before, after, change in rows.values():
        assert before == after and change == "+0.0"
    # the bench's own units_ rows (accelcal bench --runtime rp2040) for this checkout
    from accelcal.bridge import rp2040
    from accelcal.studies import bench_chip
    bench = bench_chip.install_units(rp2040.MICROPYTHON, "")
    assert round(bench["units_base_import_app_ms"] * 1000) == int(rows["units_base_import_app_us"][1])
    for k in ("free_after_import_bytes", "free_with_processor_bytes", "modules"):
        assert bench["units_base_" + k] == int(rows["units_base_" + k][1]), k
