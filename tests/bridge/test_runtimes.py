"""CPython and the real MicroPython interpreters (the 64-bit unix port and the 32-bit
WebAssembly port, where ints past 2^30 are heap longs) run the same device modules to the same
integers."""
import numpy as np

from accelcal.bridge import runtime
from accelcal import simulate


def random_recording(rng, segments, rate):
    """Rest segments at random orientations mixed with motion, with gaps and clipping."""
    parts = []
    for k in range(segments):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        n = rate * int(rng.integers(3, 12))
        noise = rng.choice([0.001, 0.01, 0.2])  # rest, rest, motion
        parts.append(d * rng.uniform(0.8, 1.2) + rng.normal(scale=noise, size=(n, 3)))
    xyz = np.concatenate(parts)
    xyz[rng.integers(0, len(xyz), 20)] = 17.0  # beyond +-16 g: clipped by the conversion
    gaps = np.sort(rng.integers(1, len(xyz), 3))
    return xyz, gaps


def test_points_identical_on_many_random_devices(rng, mp):
    groups = []
    for i in range(40):
        n = int(rng.integers(5, 400))
        noise = float(rng.choice([0.0, 1e-3, 5e-3, 0.05]))
        _, v = simulate.paper_scenario(rng, n, noise)
        groups.append(runtime.Group(f"d{i}", points=v))
    for policy in ("centre", "first"):
        cfg = runtime.Config(policy=policy, max_count=int(rng.integers(2, 4)))
        a = runtime.run(groups, cfg, "cpython")
        b = runtime.run(groups, cfg, mp)
        assert len(a) == len(b) == 40
        for x, y in zip(a, b):
            assert x == y  # every field: rest points, bins, selection, status, objective, params
        assert sum(r.status == 0 and min(r.counts) >= 2 for r in a) > 10  # many real fits compared


def test_recordings_identical(rng, mp):
    groups = []
    for i in range(4):
        rate = int(rng.choice([10, 25, 100]))
        xyz, gaps = random_recording(rng, 60, rate)
        groups.append(runtime.Group(f"r{i}", samples=xyz, gaps=gaps))
    cfg = runtime.Config(rate_hz=25, seconds=2, axis=int(rng.integers(0, 3)))
    a = runtime.run(groups, cfg, "cpython")
    b = runtime.run(groups, cfg, mp)
    assert [r.rest_int for r in a] == [r.rest_int for r in b]
    assert a == b
    assert sum(len(r.rest_int) for r in a) > 50


def test_divergence_reported_identically(rng, mp):
    _, v = simulate.paper_scenario(rng, 300, 1e-3)
    cfg = runtime.Config(rates_tenths=(30, 80, 20))
    a = runtime.run([runtime.Group("d", points=v)], cfg, "cpython")
    b = runtime.run([runtime.Group("d", points=v)], cfg, mp)
    assert a == b
    assert a[0].status_name == "diverged"
