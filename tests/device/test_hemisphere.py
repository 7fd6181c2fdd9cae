"""The coverage rule's hemisphere test on the device (acal/core/hemisphere.py): the same verdict as the
host's linear programme (methods.one_side_margin, which every float method, compare and diagnose
ask through coverage_reason), small ints only, the same under MicroPython; and the wear profile's
bins not ready on one-sided points, where they were before (calibrate then says why)."""
import numpy as np

from acal.core import bins as dbins
from acal.core import hemisphere
from accelcal.bridge import runtime
from accelcal.bridge.ranges import SMALL_INT_LIMIT, Tracer, traced
from accelcal.methods import coverage_reason, one_side_margin


def point_sets(rng, count):
    """Random sets of 9-72 points near |v| = 1 g, cut by a random plane at a random height: some
    one-sided (the cut above 0), some covering; Q16 ints."""
    for _ in range(count):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        u = rng.normal(size=(int(rng.integers(9, 73)), 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        u = u[u @ d > rng.uniform(-0.6, 0.3)]
        if len(u) >= 4:
            yield np.round(u * rng.uniform(0.9, 1.1, (len(u), 1)) * 65536).astype(np.int64)


def test_the_device_decides_as_the_hosts_linear_programme(rng):
    verdicts = []
    for q in point_sets(rng, 300):
        dev = hemisphere.one_sided(q.ravel().tolist(), [len(q)], len(q), len(q))
        at_q8 = np.floor(q / 256) * 256 / 65536     # the points as the device takes them
        verdicts.append(dev)
        assert dev == (one_side_margin(at_q8) > 1e-9)
    assert 50 < sum(verdicts) < len(verdicts) - 50     # both verdicts well represented


def test_held_points_in_the_bins_layout():
    """Groups of m slots with counts[s] held: unheld slots are never read (garbage there), and
    held() gives one_sided's verdict on the held points alone."""
    m = 4
    xyz = [12345678] * (3 * 9 * m)                 # unheld slots: a point far off the sphere
    counts = [0] * 9
    pts = [(65536, 0, 0), (0, 65536, 0), (0, 0, 65536), (-40000, -40000, 0)]
    for s, p in zip((0, 4, 8, 8), pts):
        k = counts[s]
        xyz[3 * (s * m + k):3 * (s * m + k) + 3] = p
        counts[s] += 1
    flat = [c for p in pts for c in p]
    assert hemisphere.held(xyz, counts, m) == hemisphere.one_sided(flat, [4], 4, 4) is True
    xyz[3 * (2 * m):3 * (2 * m) + 3] = (0, 0, -65536)    # a face-down point: not one-sided
    counts[2] = 1
    assert not hemisphere.held(xyz, counts, m)


def test_small_ints_at_the_bins_extremes():
    """Points up to the bins' 1.5 g gate on every axis' sign: every value < 2^30."""
    tracer = Tracer()
    T = traced(tracer)
    e = 98304   # 1.5 g, Q16
    corners = [(sx * e, sy * e, sz * e) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    for pts in (corners, corners[:4] + [(e, 0, 0), (0, -e, 0)], corners[1::2]):
        flat = [T(c) for p in pts for c in p]
        hemisphere.one_sided(flat, [len(pts)], len(pts), len(pts))
    assert tracer.ops > 0 and tracer.big == 0 and tracer.max_abs < SMALL_INT_LIMIT


SCRIPT = r'''
from acal.core import hemisphere
print("".join("1" if hemisphere.one_sided(f, [len(f) // 3], len(f) // 3, len(f) // 3) else "0"
              for f in %r))
'''


def test_micropython_decides_alike(rng, tmp_path):
    sets = [q.ravel().tolist() for q in point_sets(rng, 40)]
    f = tmp_path / "hemi.py"
    f.write_text(SCRIPT % (sets,))
    got = runtime.run_micropython_script(str(f)).strip()
    want = "".join("1" if hemisphere.one_sided(s, [len(s) // 3], len(s) // 3, len(s) // 3)
                   else "0" for s in sets)
    assert got == want and "0" in want and "1" in want


def one_sided_wrist(rng, n=600):
    """Rest directions all within 87 degrees of (1, 1, 1): each axis still reaches -0.3 g and
    beyond, and the bins' nine subsets fill, but every point is on one side of a plane."""
    d = np.ones(3) / np.sqrt(3)
    u = rng.normal(size=(4 * n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return u[u @ d > 0.05][:n]


def test_the_wear_bins_are_not_ready_on_one_hemisphere(rng):
    u = one_sided_wrist(rng)
    assert coverage_reason(u) and "one hemisphere" in coverage_reason(u)
    b = dbins.Bins(2, 8, coverage=True)
    for x, y, z in np.round(u * 65536).astype(int).tolist():
        b.offer(x, y, z)
    assert min(b.counts) >= 2 and b._axes_covered()   # ready before the hemisphere test
    assert not b.covered() and not b.ready()
    mirrored = dbins.Bins(2, 8, coverage=True)         # the same wrist turned over too
    for x, y, z in np.round(np.vstack([u, -u[::7]]) * 65536).astype(int).tolist():
        mirrored.offer(x, y, z)
    assert mirrored.covered() and mirrored.ready()


def test_calibrate_refuses_one_hemisphere_as_every_method_does(tmp_path, rng):
    """The default device path said 'calibrated' on points where lsq and compare refused."""
    from conftest import run_cli
    v = one_sided_wrist(rng, 400) * [1.01, 0.99, 1.0] + [0.02, -0.01, 0.015]
    f = tmp_path / "points.csv"
    np.savetxt(f, v, delimiter=",", header="x,y,z", comments="")
    for extra in ((), ("--method", "lsq")):
        r = run_cli("calibrate", f, *extra)
        assert r.returncode == 2 and "one hemisphere only" in r.stderr
        assert len(r.stderr.strip().splitlines()) == 1
    r = run_cli("compare", f)
    assert r.returncode == 2 and "one hemisphere only" in r.stderr
