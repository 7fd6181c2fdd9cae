"""The mistakes people make, caught kindly (issue 51): readings in m/s^2 or raw counts named with
the fix in one line, a long option taken only as spelled in full (the nearest one named), and
bins that did not fill named as the orientations still missing and how long to hold each."""
import argparse

import numpy as np
import pytest

from accelcal.cli import build_parser, main
from accelcal.files.checks import STANDARD_GRAVITY, unit_hint

FACES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def recording(path, scale=1.0, rate=10, seconds=600, rng=None):
    """A still device turned to each face in turn (60 s each), noise 2 mg, in g times scale."""
    rng = rng or np.random.default_rng(5)
    n = rate * seconds
    t = np.arange(n) / rate
    xyz = FACES[(t // 60).astype(int) % 6] + rng.normal(0, 0.002, (n, 3))
    np.savetxt(path, np.column_stack([t, xyz * scale]), delimiter=",", header="t,x,y,z",
               comments="", fmt="%.6f")
    return path


def one_line(capsys, argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:   # an option error: the parser's exit
        code = e.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_a_recording_in_m_s2_is_named_with_the_fix(tmp_path, capsys):
    line = one_line(capsys, ["calibrate", recording(tmp_path / "ms2.csv", STANDARD_GRAVITY)])
    assert "m/s^2, not g" in line and f"divide x, y, z by {STANDARD_GRAVITY}" in line, line


def test_a_recording_in_counts_is_named_with_the_fix(tmp_path, capsys):
    # the LIS3DH at +-2 g high resolution: 1 mg/digit (datasheet table 3), 1000 counts a g
    line = one_line(capsys, ["calibrate", recording(tmp_path / "counts.csv", 1000.0)])
    assert "raw counts (about 1000 per g?)" in line and "counts per g" in line, line
    # an AX3's 256 counts a g stay within the 256 g bound of a reading: the median names them
    line = one_line(capsys, ["diagnose", recording(tmp_path / "c256.csv", 200.0)])
    assert "raw counts (about 200 per g?)" in line, line


def test_points_in_m_s2_are_named_and_readings_in_g_pass(tmp_path, capsys, rng):
    a = rng.normal(size=(60, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    assert unit_hint(a) is None and unit_hint(a * 1.9) is None   # g, even a 2 g scale error
    f = tmp_path / "pts.csv"
    np.savetxt(f, a * STANDARD_GRAVITY, delimiter=",", header="x,y,z", comments="", fmt="%.6f")
    assert "m/s^2, not g" in one_line(capsys, ["calibrate", f])


def test_a_long_option_is_taken_only_in_full(tmp_path, capsys):
    f = recording(tmp_path / "r.csv")
    line = one_line(capsys, ["diagnose", f, "--effect", "drift"])
    assert "unrecognized arguments: --effect drift; did you mean --effects? (see `accelcal " \
        "diagnose --help`)" in line, line
    line = one_line(capsys, ["calibrate", f, "--meth", "lsq"])
    assert "unrecognized arguments: --meth lsq; did you mean --method?" in line, line
    line = one_line(capsys, ["simulate", "wrist", "--day", "1", "-o", tmp_path / "w.csv"])
    assert "did you mean --days? (see `accelcal simulate wrist --help`)" in line, line
    assert "did you mean" not in one_line(capsys, ["calibrate", f, "--zzz"])

    def parsers(p):
        yield p
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for q in a.choices.values():
                    yield from parsers(q)
    found = list(parsers(build_parser()))
    assert len(found) > 15 and not any(p.allow_abbrev for p in found)


@pytest.mark.parametrize("seconds", [5, 7])
def test_bins_that_did_not_fill_name_the_orientations_and_the_hold(tmp_path, capsys, seconds):
    f = tmp_path / "few.csv"
    f.write_text("x,y,z\n1,0,0\n-1,0,0\n0,1,0\n0,-1,0\n0,0,1\n")
    main(["calibrate", str(f), "--profile", "paper", "--seconds", str(seconds)])
    out = capsys.readouterr().out
    # five points, one per subset of the first five (acal.core.bins.subset_of): the rest are empty
    assert "x-down 1, x-level 1, x-up 1, y-down 1, y-level 1, y-up 2, z-down 2" in out, out
    assert f"each held still >= {2 * seconds} s" in out and "up: the axis reads +1 g" in out
