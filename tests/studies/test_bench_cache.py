"""bench_files' cache of simulated recordings: made once per arguments and code version, put in
place whole, reused, and entries of another code version (or of a run that died) removed."""
import os

import pytest

from accelcal.studies import bench_files


def test_cache_made_reused_and_stale_removed(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    root.mkdir()
    stale = root / "wrist-0.01d-100hz-s14-000000000000"
    stale.mkdir()
    dead = root / ".partial-999999999-wrist-x"      # no such PID
    dead.mkdir()
    mine = root / f".partial-{os.getpid()}-wrist-y"   # a run still running: kept
    mine.mkdir()
    csv, cwa = bench_files.cached(root, 0.01, 100)
    assert csv.exists() and cwa is not None and cwa.exists() and cwa.stat().st_size > 0
    assert csv.parent.name == f"wrist-0.01d-100hz-s14-{bench_files.code_version()}"
    assert csv.with_suffix(".truth.json").exists()
    assert not stale.exists() and not dead.exists() and mine.exists()
    assert sorted(p.name for p in root.iterdir()) == sorted([csv.parent.name, mine.name])
    made = csv.read_bytes()

    def no_simulation(*a, **k):
        raise AssertionError("simulated again")
    monkeypatch.setattr(bench_files, "simulated", no_simulation)
    assert bench_files.cached(root, 0.01, 100) == (csv, cwa)
    assert bench_files.cached(root, 0.01, 100, cwa=False) == (csv, None)
    assert csv.read_bytes() == made

    # another code version: a new entry, the old one removed; a failed simulation leaves none
    monkeypatch.setattr(bench_files, "code_version", lambda: "111111111111")
    with pytest.raises(AssertionError):
        bench_files.cached(root, 0.01, 100)
    assert sorted(p.name for p in root.iterdir()) == [mine.name]


def test_code_version_follows_the_simulator(monkeypatch, tmp_path):
    import shutil
    from pathlib import Path

    import accelcal
    v = bench_files.code_version()
    assert len(v) == 12 and v == bench_files.code_version()
    copy = tmp_path / "accelcal"
    shutil.copytree(Path(accelcal.__file__).parent, copy)
    assert bench_files.code_version(copy) == v
    (copy / "report" / "__init__.py").write_text("# not the simulator's\n")
    assert bench_files.code_version(copy) == v
    wearer = copy / "simulate" / "wearer.py"
    wearer.write_text(wearer.read_text() + "\n# changed\n")
    assert bench_files.code_version(copy) != v
    monkeypatch.setenv("ACCELCAL_BENCH_CACHE", str(tmp_path))
    assert bench_files.cache_root() == tmp_path
