"""`accelcal bench` prints what a user waits for before anything is done (issue 51): a fresh
interpreter's `import accelcal` and `accelcal --help`, wall ms, the best of five; `--help` is
built from the command table alone, loading neither numpy nor the device code (read from
sys.modules of a fresh interpreter, not timed)."""
import subprocess
import sys

from accelcal.studies import bench


def test_bench_prints_the_import_and_help_times(monkeypatch, capsys):
    # the rest of the bench (a minute of MicroPython runs) is not what this test is about
    monkeypatch.setattr(bench, "bench_points", lambda: [])
    monkeypatch.setattr(bench, "measure", lambda pts: {"optimiser_ms_micropython": 1.0})
    monkeypatch.setattr(bench, "measure_fit_slices", lambda: {})
    monkeypatch.setattr(bench, "measure_app", lambda tmp: {})
    monkeypatch.setattr(bench.measure_startup, "__defaults__", (1,))
    assert bench.bench_main(runtime_name="micropython") == 0
    rows = {ln.split()[0]: ln.split()[1:] for ln in capsys.readouterr().out.splitlines() if ln.strip()}
    for key in ("python_startup_ms", "import_accelcal_ms", "help_wall_ms"):
        assert float(rows[key][0]) > 0, rows.get(key)
    assert rows["help_wall_ms"][1:] == ["<", "300", "ms"]


def test_help_loads_neither_numpy_nor_the_device_code():
    code = ("import sys\nfrom accelcal.cli import main\ntry:\n    main(['--help'])\n"
            "except SystemExit:\n    pass\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'acal'}), "
            "file=sys.stderr)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and "COMMAND" in out.stdout, out.stderr
    assert out.stderr.strip().splitlines()[-1] == "[]", out.stderr
    code = "import sys, accelcal\nprint(sorted(m for m in sys.modules if m.startswith(('numpy', 'acal'))))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "[]"
