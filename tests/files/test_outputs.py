"""Nothing lost: no command replaces one of its own inputs (by name, by another path to it, or
through a symlink), an existing output needs --force, every output path is checked before any
work, and outputs are written whole or not at all (a failed or killed apply leaves no file that
looks like a shorter recording).  Most cases run the CLI's main(argv) in-process; a few run it
as a real subprocess for the exit code and the absence of a traceback end to end."""
import os
import signal
import subprocess
import sys
import time

import pytest

from accelcal import cli
from conftest import run_cli


def run_main(capsys, *argv):
    """main(argv) in-process: (exit code, stdout, stderr)."""
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as e:   # argparse's own errors
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line(code, err):
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A short wrist recording and parameters saved from it."""
    d = tmp_path_factory.mktemp("outputs")
    rec = d / "rec.csv"
    assert run_cli("simulate", "wrist", "--days", "1", "--rate", "10", "-o", rec).returncode == 0
    r = run_cli("calibrate", rec, "--save", d / "p.json")
    assert r.returncode == 0, r.stderr
    return d, rec, d / "p.json"


def snapshot(*paths):
    return {str(p): p.read_bytes() for p in paths}


def test_no_command_replaces_its_own_input(work, capsys, tmp_path):
    d, rec, params = work
    keep = snapshot(rec, params)
    link = tmp_path / "link.csv"
    link.symlink_to(rec)
    cases = [
        ("apply", params, rec, "-o", rec),
        ("apply", params, rec, "-o", rec, "--force"),
        ("apply", params, rec, "-o", params, "--force"),
        ("apply", params, rec, "-o", link, "--force"),                   # a symlink to the input
        ("apply", params, rec, "-o", d / ".." / d.name / "rec.csv", "--force"),   # another path
        ("calibrate", rec, "--save", rec, "--force"),
        ("calibrate", rec, "--save", link, "--force"),
        ("calibrate", rec, rec, "--summary", rec, "--force"),
        ("calibrate", rec, "--fallback", params, "--save", params, "--force"),
        ("diagnose", rec, "--history", rec),
        ("diagnose", rec, "--plots", rec),
        ("compare", rec, "--plots", rec),
    ]
    for argv in cases:
        code, _, err = run_main(capsys, *argv)
        line = one_line(code, err)
        assert "input" in line or "is a file" in line, (argv, line)
        assert snapshot(rec, params) == keep, argv


def test_an_existing_output_needs_force_and_outputs_are_checked_before_the_work(work, capsys,
                                                                                 tmp_path):
    d, rec, params = work
    out = tmp_path / "cal.csv"
    out.write_text("precious\n")
    code, _, err = run_main(capsys, "apply", params, rec, "-o", out)
    assert "exists; add --force" in one_line(code, err)
    assert out.read_text() == "precious\n"
    code, _, err = run_main(capsys, "apply", params, rec, "-o", out, "--force")
    assert code == 0, err
    assert out.read_text().startswith("t,x,y,z")
    # outputs that cannot be written fail at once, before the analysis (fast)
    folder = tmp_path / "a_folder"
    folder.mkdir()
    afile = tmp_path / "a_file.txt"
    afile.write_text("x")
    missing = tmp_path / "missing" / "p.json"
    cases = [
        (("calibrate", rec, "--save", folder), "is a folder"),
        (("calibrate", rec, "--save", missing), "does not exist"),
        (("calibrate", rec, rec, "--summary", folder), "is a folder"),
        (("calibrate", rec, "--save", afile), "exists; add --force"),
        (("diagnose", rec, "--history", folder), "is a folder"),
        (("diagnose", rec, "--plots", afile), "is a file"),
        (("compare", rec, "--plots", afile), "is a file"),
        (("paper", "gietzelt", "--plots", afile), "is a file"),
        (("report", tmp_path / "none.jsonl", "--plot", folder), "is a folder"),
        (("simulate", "wrist", "--days", "0.01", "-o", afile), "exists; add --force"),
        (("simulate", "wrist", "--days", "0.01", "-o", missing), "does not exist"),
        (("simulate", "paper", "-o", folder), "is a folder"),
        (("simulate", "wrist", "--days", "0.01", "-o", tmp_path / "w.csv", "--stimulus",
          afile), "exists; add --force"),
        (("pull", "--port", "/dev/nonexistent", "-o", afile), "is a file"),
    ]
    for argv, want in cases:
        t0 = time.perf_counter()
        code, _, err = run_main(capsys, *argv)
        assert want in one_line(code, err), (argv, err)
        assert time.perf_counter() - t0 < 5, argv   # refused before the work, not after
    assert afile.read_text() == "x"


def test_pull_refuses_a_folder_holding_an_earlier_pull(capsys, tmp_path):
    (tmp_path / "log.bin").write_bytes(b"earlier")
    code, _, err = run_main(capsys, "pull", "--port", "/dev/nonexistent", "-o", tmp_path)
    assert "already holds log.bin" in one_line(code, err)
    assert (tmp_path / "log.bin").read_bytes() == b"earlier"


def test_virtual_board_never_deletes_a_file_it_did_not_make(tmp_path):
    keep = tmp_path / "notes.txt"
    keep.write_text("mine")
    r = subprocess.run([sys.executable, "-m", "accelcal.cli", "board", "virtual", "--flash",
                        str(tmp_path / "flash"), "--link", str(keep)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr and "exists" in r.stderr
    assert keep.read_text() == "mine"


def test_a_failed_apply_leaves_no_file(work, capsys, tmp_path, monkeypatch):
    """The disk fills while apply writes: one line, exit 2, no output file and no temporary
    left beside it."""
    d, rec, params = work
    from accelcal.pipeline import apply as calibrate

    def failing(*a, **k):
        raise OSError(28, "No space left on device", str(tmp_path / "cal.csv"))
    monkeypatch.setattr(calibrate, "apply_to_samples", failing)
    code, _, err = run_main(capsys, "apply", params, rec, "-o", tmp_path / "cal.csv")
    assert "No space left" in one_line(code, err)
    assert list(tmp_path.iterdir()) == []


def test_a_killed_apply_leaves_no_file_that_looks_whole(work, tmp_path):
    """apply killed (SIGKILL) while it writes: the output path does not exist; only a hidden
    temporary, named as such, may remain."""
    d, rec, params = work
    big = tmp_path / "big.csv"
    lines = rec.read_text().splitlines()
    body = lines[1:]
    with open(big, "w") as fh:
        fh.write(lines[0] + "\n")
        t = 0.0
        for _ in range(6):   # ~5 M samples: seconds of work
            for ln in body:
                f = ln.split(",")
                fh.write(f"{t:.4f}," + ",".join(f[1:]) + "\n")
                t += 0.1
    out = tmp_path / "cal.csv"
    p = subprocess.Popen([sys.executable, "-m", "accelcal.cli", "apply", str(params), str(big),
                          "-o", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline:   # kill it once it has started writing
        if any(f.name.endswith(".partial") and f.stat().st_size > 100000
               for f in tmp_path.iterdir()):
            break
        if p.poll() is not None:
            break
        time.sleep(0.05)
    assert p.poll() is None, "apply finished before it could be killed: make the input larger"
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    assert not out.exists()
    left = [f.name for f in tmp_path.iterdir() if f.name not in ("big.csv",)]
    assert all(n.startswith(".cal.csv.") and n.endswith(".partial") for n in left), left
