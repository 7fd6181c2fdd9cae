"""Rest data that cannot pin a calibration is refused alike by calibrate, diagnose and compare:
exit 2 and one line on stderr, no parameters at the fit region's edge reported as a result.
Cases: a device lying still in one orientation for hours while its temperature ramps (a
temperature chamber), and one that turned about but never past one hemisphere."""
import numpy as np
import pytest

from accelcal import simulate
from conftest import run_cli

RATE = 2
HOURS = 6
TRUTH = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])


def write(path, xyz, rng):
    n = len(xyz)
    t = np.arange(n) / RATE
    temp = 20 + 20 * t / t[-1]
    xyz = xyz + rng.normal(scale=0.001, size=xyz.shape)
    np.savetxt(path, np.column_stack([t, xyz, temp]), delimiter=",", header="t,x,y,z,temp",
               comments="", fmt="%.5f")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("degenerate")
    rng = np.random.default_rng(3)
    n = HOURS * 3600 * RATE
    one = np.tile(simulate.uncorrect(TRUTH, np.array([[0.0, 0.0, 1.0]])), (n, 1))
    dirs = simulate.unit_points(rng, 400)
    dirs = dirs[dirs[:, 2] > 0.3][: HOURS * 60]   # a minute each, never below the horizon
    held = np.repeat(simulate.uncorrect(TRUTH, dirs), 60 * RATE, axis=0)[:n]
    return {"one orientation": write(d / "chamber.csv", one, rng),
            "one hemisphere": write(d / "hemisphere.csv", held, rng)}


@pytest.mark.parametrize("case", ["one orientation", "one hemisphere"])
@pytest.mark.parametrize("command", [("calibrate",), ("calibrate", "--profile", "paper"),
                                     ("calibrate", "--method", "lsq", "--points", "all"),
                                     ("diagnose",), ("compare",)])
def test_refused_with_one_line(files, case, command):
    r = run_cli(command[0], files[case], *command[1:])
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "hemisphere" in lines[0] or "did not fill" in lines[0], lines[0]
