"""The bulk feed of rest points (bridge/feed.py) leaves the device's bins exactly as offering each
point one at a time does: the same points in the same slots, the same counters, the same records,
the same fit; on simulated wrist recordings and on streams made to hit every branch of
Bins.offer."""
import functools
from dataclasses import replace

import numpy as np
import pytest

from acal.core import bins as dbins
from acal.core import effects as deff
from accelcal.bridge import feed
from accelcal.bridge.protocol import Collector, Config, Group, device_conditions, protocol_items
from accelcal.bridge.scripts import mp_runner
from conftest import simulate_wrists


def run_feed(groups, cfg, bulk):
    """The runner fed one way; (the bins' state where each group's fit would begin, the records
    so far).  The fit itself is left out: it reads only the bins."""
    collector = Collector()
    runner = mp_runner.Runner(collector.emit)
    point = runner.point
    offers = []

    def counted(x, y, z):
        offers.append(1)
        point(x, y, z)
    runner.point = counted
    states = []
    for method, args in protocol_items(groups, cfg, bulk=bulk):
        if method == "end":
            b = runner.pipe.bins
            states.append((list(b.counts), list(b.xyz), list(b.cond), b.offered, b.kept,
                           b.replaced, runner.pipe.rest_count))
            continue
        if method == "group":
            run_feed.offers = offers = []
        if method == "points":
            feed.offer_points(runner, collector, *args)
        else:
            getattr(runner, method)(*args)
    return states, [vars(r) for r in collector.results]


def assert_same_feed(groups, cfg):
    one, one_res = run_feed(groups, cfg, bulk=False)
    bulk, bulk_res = run_feed(groups, cfg, bulk=True)
    assert bulk == one
    assert bulk_res == one_res
    return one


def test_vector_twins_match_the_device(rng):
    q = rng.integers(-90000, 90000, (4000, 3))
    q[:500] = rng.integers(-300, 300, (500, 3)) + np.array([0, 65536, 0])   # on the edges
    for lo in (dbins._LO_OUT, dbins.COVER_LEVEL):
        for axis in range(3):
            s = feed.subset_of_vec(q[:, axis], axis, lo)
            assert s.tolist() == [dbins.subset_of(int(c), axis, lo) for c in q[:, axis]]
    for s in range(9):
        axis = s // 3
        got = feed.badness_vec(q, axis, s % 3 == 1)
        assert got.tolist() == [dbins.badness(*map(int, p), s) for p in q]
    # in a subset on some axis (the edges are the same for every axis)
    can = ~feed.never_kept(q) & (feed.subset_of_vec(q, 0, dbins._LO_OUT) >= 0).any(axis=1)
    assert 100 < can.sum() < len(q) - 100
    for p, k in zip(q.tolist(), can.tolist()):   # empty bins keep every point they can
        assert (dbins.Bins().offer(*p) >= 0) == k


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("feed")
    return simulate_wrists(folder, {"a": (11, ()), "b": (12, ("temp_offset",)),
                                    "c": (13, ("drift",))}, days=1, rate=10)


@functools.lru_cache(maxsize=None)
def recording_group(path, seconds, threshold, axis):
    from accelcal.files.recordings import open_recording
    from accelcal.pipeline.scan import scan
    sc = scan(open_recording(path), seconds, threshold, axis)
    kept = sc.masks()["kept"]
    temp = None if sc.seg_temp is None else sc.seg_temp[kept]
    cond = device_conditions(temp, sc.seg_t[kept], sc.t_first, int(kept.sum()))
    return Group("recording", points_q16=sc.segments.mean[kept], temp=temp, t=sc.seg_t[kept],
                 cond=cond, t_origin=sc.t_first)


@pytest.mark.parametrize("profile,kinds", [("wear", ()), ("paper", ()),
                                           ("wear", (deff.TEMP_OFFSET,)),
                                           ("wear", (deff.DRIFT,))])
def test_bulk_feed_keeps_what_one_at_a_time_keeps(recordings, profile, kinds):
    cfg = replace(Config.for_profile(profile, composed=bool(kinds)), kinds=kinds)
    groups = [recording_group(p, cfg.seconds, cfg.threshold_int, cfg.axis)
              for p in recordings.values()]
    states = assert_same_feed(groups, cfg)
    for counts, *_, offered, kept, replaced, rest_count in states:
        assert offered == rest_count > 1000 and kept == sum(counts) and kept > 0
    if profile == "wear" and not kinds:   # the CENTRE rule did replace points
        assert any(s[5] > 0 for s in states), [s[5] for s in states]
    if not kinds:     # the judge spared the bins most of the last group's offers
        assert len(run_feed.offers) < states[-1][3] / 4


@pytest.mark.parametrize("policy", ["first", "centre"])
def test_bulk_feed_on_streams_that_hit_every_rule(rng, policy):
    """Points bunched near a few orientations (so that many lie within `differ` of a held one),
    some off the sphere, some in no subset, with conditions that drift and jump."""
    centres = rng.normal(size=(12, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    n = 6000
    pick = rng.integers(0, 12, n)
    g = centres[pick] + rng.normal(0, 0.06, (n, 3))
    g[::37] *= 1.6                                  # off the sphere
    q = np.round(g * 65536).astype(np.int64)
    cond = np.column_stack([rng.integers(20, 34, n), np.arange(n) // 7, 3700 + rng.integers(0, 300, n)])
    for kinds in ((), (deff.TEMP_OFFSET,), (deff.TEMP_OFFSET, deff.DRIFT)):
        cfg = Config.for_profile("wear", composed=bool(kinds), policy=policy, kinds=kinds,
                                 max_count=3)
        assert_same_feed([Group("s", points_q16=q, cond=cond)], cfg)
