"""Bins: the nine subsets, counts, the differs-enough test, first-come and centre policies."""
import numpy as np

from acal import bins
from acal.bins import Bins, subset_of
from accelcal.io import g_to_point

G = 65536


def test_subset_limits():
    assert subset_of(G, 0) == 2 and subset_of(-G, 1) == 3 and subset_of(0, 2) == 7
    assert subset_of(int(0.75 * G), 0) == 2 and subset_of(int(1.25 * G), 0) == 2
    assert subset_of(int(0.5 * G), 0) == -1 and subset_of(int(0.25 * G) + 1, 0) == -1
    assert subset_of(-int(0.25 * G), 1) == 4


def test_fills_evenly_and_stops_at_max(rng):
    b = Bins(2, 2, policy=bins.FIRST)
    a = rng.normal(size=(2000, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    for x, y, z in g_to_point(a).tolist():
        b.offer(x, y, z)
    assert b.counts == [2] * 9 and b.ready() and b.total() == 18


def test_differs_enough():
    b = Bins(2, 2, differ=G // 10)
    assert b.offer(G, 0, 0) >= 0
    assert b.offer(G - G // 20, G // 20, 0) == -1  # 0.05 g away: too close
    assert b.offer(G - G // 20, G // 5, 0) >= 0    # 0.2 g away on y: kept
    assert b.total() == 2


def test_not_gravity_is_never_kept():
    b = Bins()
    assert b.offer(G, G, G) == -1            # |v| = 1.73 g
    assert b.offer(G // 4, G // 4, 0) == -1  # 0.35 g
    assert b.offer(2 * G, 0, 0) == -1        # component beyond 1.25 g
    assert b.total() == 0


def test_centre_policy_moves_towards_ideal_points():
    b = Bins(1, 1, differ=G // 100, policy=bins.CENTRE)
    far = (int(0.8 * G), int(0.55 * G), 0)
    near = (int(0.99 * G), int(0.1 * G), 0)
    s = b.offer(*far)
    assert s == 2  # C_xp (y and z subsets cannot take it: y is 0.55 g)
    assert b.offer(*near) in (2, 4, 7)
    # once C_xp is held, a point nearer the x axis replaces the far one when its other subsets are full
    f = Bins(1, 1, differ=G // 100, policy=bins.FIRST)
    f.offer(*far)
    c = Bins(1, 1, differ=G // 100, policy=bins.CENTRE)
    c.offer(*far)
    c.counts[4] = c.counts[7] = 1  # pretend C_y0 and C_z0 are full
    assert f.offer(*near) == 4  # first-come puts it elsewhere
    assert c.offer(*near) == 2 and c.point(2, 0) == near and c.replaced == 1


def test_centre_is_closer_to_axes_than_first(rng):
    a = rng.normal(size=(600, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    q = g_to_point(a).tolist()
    res = {}
    for pol in (bins.FIRST, bins.CENTRE):
        b = Bins(policy=pol)
        for x, y, z in q:
            b.offer(x, y, z)
        bad = [bins.badness(*b.point(s, k), s) for s in range(9) for k in range(b.counts[s])]
        res[pol] = np.mean(bad)
    assert res[bins.CENTRE] < 0.5 * res[bins.FIRST]
