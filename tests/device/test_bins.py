"""Bins: the nine subsets, counts, the differs-enough test, first-come and centre policies."""
import numpy as np

from acal.core import bins, fixed
from acal.core.bins import Bins, subset_of
from acal.core.fixed import C_SUPPLY, C_TEMP, C_TIME
from acal.core.fixed import TEMP_Q

TEMP_DIFFER, TIME_DIFFER, SUPPLY_DIFFER = fixed.DIFFERS   # C_TEMP, C_TIME, C_SUPPLY
from accelcal.fixedpoint import g_to_point

G = 65536


def at(temp=0, time=0, supply=0):
    """A point's conditions, the columns bins.offer takes (C_TEMP, C_TIME, C_SUPPLY)."""
    return [temp, time, supply]


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


def test_composed_bins_keep_the_same_orientation_seen_warmer_or_later():
    b = Bins(2, 4, differ=G // 10, differs=(TEMP_DIFFER, TIME_DIFFER, 0))
    q = 1 << TEMP_Q                                     # temperatures in Q2 degC
    assert b.offer(G, 0, 0, at(25 * q, 0)) >= 0
    assert b.offer(G, 0, 0, at(27 * q + 3, 100)) == -1      # 2.75 degC, 1.8 h: the same point
    assert b.offer(G, 0, 0, at(28 * q, 100)) >= 0           # 3 degC warmer: differs
    assert b.offer(G, 0, 0, at(26 * q, 100 + TIME_DIFFER)) >= 0  # 12 h after both: differs
    assert b.total() == 3 and b.span(C_TEMP) == 3 * q and b.span(C_TIME) == 100 + TIME_DIFFER
    plain = Bins(2, 4, differ=G // 10)                  # the paper's model: conditions ignored
    assert plain.offer(G, 0, 0, at(25, 0)) >= 0 and plain.offer(G, 0, 0, at(40, 10 ** 5)) == -1
    assert plain.span(C_TEMP) == 0


def test_a_full_composed_subset_takes_points_that_widen_its_spread():
    b = Bins(1, 2, differ=G // 10, differs=(3, 0, 0))

    def only_xp(x, y, z):  # y and z between the bands: these points belong to C_xp alone
        return int(x * G), int(y * G), int(z * G)

    assert b.offer(*only_xp(0.8, 0.4, 0.4), at(30)) == 2
    assert b.offer(*only_xp(0.8, 0.55, 0.3), at(31)) == 2
    assert b.offer(*only_xp(0.8, 0.45, 0.35), at(38)) == 2  # full; widens 30..31 -> 30..38
    assert sorted(b.condition(2, k)[0] for k in range(2)) == [30, 38] and b.replaced == 1
    assert b.offer(*only_xp(0.8, 0.3, 0.5), at(34)) == -1   # inside the range, no better placed
    # Slot 0 keeps placement, slot 1 spread: 20 degC widens 30..38 to 20..30 through slot 1.
    assert b.offer(*only_xp(0.8, 0.5, 0.5), at(20)) == 2
    assert [b.condition(2, k)[0] for k in range(2)] == [30, 20] and b.total() == 2
    assert b.offer(*only_xp(0.8, 0.35, 0.45), at(25)) == -1  # would narrow: refused


def test_a_full_temperature_subset_keeps_its_spread_slots_without_a_gain():
    """With temperature alone tracked a quarter threshold is 0.75 degC (3 degC in Q2 >> 2; in
    whole degC it was 0, taken as 1): a point that only keeps the range does not replace a spread
    slot (before that rule every such point did, and the placement slots kept the first points
    ever seen); a better placed one replaces the placement slot (the CENTRE rule)."""
    b = Bins(1, 2, differ=G // 10, differs=(TEMP_DIFFER, 0, 0))
    q = 1 << TEMP_Q

    def only_xp(x, y, z):  # y and z between the bands: C_xp alone
        return int(x * G), int(y * G), int(z * G)

    assert b.offer(*only_xp(0.8, 0.4, 0.4), at(30 * q)) == 2
    assert b.offer(*only_xp(0.8, 0.55, 0.3), at(31 * q)) == 2
    assert b.offer(*only_xp(0.78, 0.45, 0.6), at(31 * q)) == -1   # keeps 30..31, placed worse
    assert b.offer(*only_xp(0.78, 0.45, 0.6), at(31 * q + 2)) == -1   # widens by 0.5 degC: too little
    assert b.offer(*only_xp(0.9, 0.45, 0.6), at(30 * q)) == 2     # keeps 30..31, placed better
    assert b.point(2, 0)[0] == int(0.9 * G) and b.condition(2, 1)[0] == 31 * q
    assert b.offer(*only_xp(0.78, 0.45, 0.6), at(31 * q + 3)) == 2   # widens by 0.75 degC: taken
    assert b.condition(2, 1)[0] == 31 * q + 3


def test_a_full_time_subset_keeps_its_early_spread_points():
    """Time only grows, so every later point widens the range by replacing any spread slot but
    the oldest.  It replaces the newest: a subset keeps its first points and rolls one slot
    forward.  When it replaced the worst placed, the better placed points of later days took
    every spread slot in turn, and a wrist's shock 19 h into 3 days had 8 of 110 fit points
    before it (docs/model-discovery.md "Bins for composed models")."""
    b = Bins(2, 8, differ=G // 10, differs=(0, TIME_DIFFER, 0))
    ys = (0.3, 0.4, 0.5, 0.6, -0.3, -0.4, -0.5, -0.6)   # y and z between the bands: C_xp alone

    def only_xp(x, y):
        return int(x * G), int(y * G), int(0.4 * G)

    for k, y in enumerate(ys):                # the first hour: 8 points placed 0.2 g off the axis
        assert b.offer(*only_xp(0.8, y), at(0, 7 * k)) == 2
    later = [TIME_DIFFER // 2 * (i + 1) for i in range(6)]   # every 6 h for 3 days
    for i, t in enumerate(later):             # placed 0.05 g off the axis: better
        assert b.offer(*only_xp(0.95, ys[i % 8]), at(0, t)) == 2
    held = sorted(b.condition(2, k)[1] for k in range(8))
    assert held == [7 * k for k in range(7)] + [later[-1]], held


def test_a_condition_no_longer_tracked_does_not_freeze_the_points_that_hold_it():
    """An adoption that ends a board's discovery stops tracking the conditions its model does
    not read (pipeline.track); the held points keep their old values and new ones store 0.  Those
    values weigh nothing in the spread any more: a better placed point replaces the placement
    slot holding a stale time.  When they still counted, that slot could not be replaced (its
    time range would "narrow") and the point was refused."""
    b = Bins(1, 2, differ=G // 10, differs=(TEMP_DIFFER, TIME_DIFFER, 0))
    q = 1 << TEMP_Q

    def only_xp(x, y, z):  # y and z between the bands: C_xp alone
        return int(x * G), int(y * G), int(z * G)

    assert b.offer(*only_xp(0.8, 0.4, 0.4), at(30 * q, 2 * TIME_DIFFER)) == 2   # placement
    assert b.offer(*only_xp(0.8, 0.55, 0.3), at(34 * q, 0)) == 2                     # spread
    b.set_differ((TEMP_DIFFER, 0, 0))         # time no longer tracked
    assert b.offer(*only_xp(0.95, 0.45, 0.35), at(30 * q, 5 * TIME_DIFFER)) == 2
    assert b.point(2, 0)[0] == int(0.95 * G) and b.condition(2, 0) == (30 * q, 0, 0)


def test_composed_bins_are_ready_only_with_the_spread():
    b = Bins(1, 1, differs=(3, 0, 0))
    for s, (x, y, z) in enumerate([(-G, 0, 0), (0, G, G // 10), (G, 0, 0), (0, -G, 0), (G // 10, 0, G),
                                   (0, G, 0), (0, 0, -G), (G, G // 10, 0), (0, 0, G)]):
        b.offer(x, y, z, at(30))
    assert min(b.counts) == 1 and not b.ready()       # every subset held, all at 30 degC
    b2 = Bins(1, 1, differs=(3, 0, 0))
    for k, (x, y, z) in enumerate([(-G, 0, 0), (0, G, G // 10), (G, 0, 0), (0, -G, 0), (G // 10, 0, G),
                                   (0, G, 0), (0, 0, -G), (G, G // 10, 0), (0, 0, G)]):
        b2.offer(x, y, z, at(30 + (k == 4) * 4))
    assert min(b2.counts) == 1 and b2.ready()


def test_the_board_supply_is_a_third_condition():
    """With supply_differ (a model following the board's supply, mV) the same orientation at a
    supply 100 mV away differs, a full subset widens its supply range, and ready() needs the
    span; without it the supply is ignored."""
    b = Bins(1, 2, differ=G // 10, differs=(0, 0, SUPPLY_DIFFER))

    def only_xp(x, y, z):
        return int(x * G), int(y * G), int(z * G)

    assert b.offer(*only_xp(0.8, 0.4, 0.4), at(0, 0, 3900)) == 2
    assert b.offer(*only_xp(0.8, 0.4, 0.4), at(0, 0, 3950)) == -1       # 50 mV: the same point
    assert b.offer(*only_xp(0.8, 0.4, 0.4), at(0, 0, 4000)) == 2        # 100 mV: differs
    assert b.offer(*only_xp(0.8, 0.45, 0.35), at(0, 0, 3700)) == 2      # full: widens 3900..4000
    assert sorted(b.condition(2, k)[2] for k in range(2)) == [3700, 3900]
    assert b.span(C_SUPPLY) == 200 and b.span(C_TEMP) == 0
    r = Bins(1, 1, differs=(0, 0, SUPPLY_DIFFER))
    pts = [(-G, 0, 0), (0, G, G // 10), (G, 0, 0), (0, -G, 0), (G // 10, 0, G), (0, G, 0),
           (0, 0, -G), (G, G // 10, 0), (0, 0, G)]
    for k, p in enumerate(pts):
        r.offer(*p, at(30, 0, 3900 + (k == 4) * 60))
    assert min(r.counts) == 1 and not r.ready()            # 60 mV: not spread enough
    r.remove(*pts[4])
    r.offer(*pts[4], at(30, 0, 4000))
    assert r.ready()
    plain = Bins(2, 4, differ=G // 10)
    assert plain.offer(G, 0, 0, at(0, 0, 3900)) >= 0 and plain.offer(G, 0, 0, at(0, 0, 4500)) == -1


def test_the_spread_score_stays_small_with_three_conditions():
    """The CENTRE rule's spread score with all three conditions tracked, at ranges of 125 degC
    (in Q2), 2**20 time units (776 days) and 65 V: below 2**30 (a 32-bit board's small ints).  The
    score is each range per its threshold times the thresholds' product over their common
    divisor: the whole ranges' score, computed here from the thresholds, is reached."""
    import math
    from accelcal.bridge.ranges import Tracer, traced
    tr = Tracer()
    T = traced(tr)
    b = Bins(2, 4, differ=G // 10, differs=bins.DIFFERS)
    b.cond = [T(0)] * len(b.cond)
    b.c = [T(0)] * bins.COND    # the offered point's conditions, traced too
    x, z = int(0.8 * G), int(0.4 * G)        # y and z between the bands: C_xp alone
    q = 1 << TEMP_Q
    for k, (temp, time, mv) in enumerate([(-40, 0, 0), (85, 1 << 20, 65535), (20, 5, 3900),
                                          (30, 1 << 19, 4100), (-40, 1 << 20, 0),
                                          (85, 0, 65535), (-40, 1 << 20, 65535)]):
        b.offer(T(x), T(int((0.3 + 0.02 * k) * G)), T(z), [T(temp * q), T(time), T(mv)])
    assert b.counts[2] == 4             # full: the last three offers score the spread
    a, t, c = TEMP_DIFFER, TIME_DIFFER, SUPPLY_DIFFER
    g = math.gcd(t * c, a * c, a * t)
    whole = (125 * q * t * c + (1 << 20) * a * c + 65535 * a * t) // g
    assert tr.ops > 50 and whole <= tr.max_abs < 2 ** 30, (whole, tr.max_abs)


def test_the_bins_and_the_fit_points_answer_the_span_question_alike(rng):
    """pipeline.spanned (the bins' held points) and search.testable (the same points gathered
    flat for the fit) ask one question through effects.condition_of and bins.DIFFERS: for every
    effect kind, on points whose ranges straddle each threshold, they answer alike, and as the
    threshold of the condition the effect's regressor reads says (by name, independently)."""
    from acal.discover import search
    from acal.core import effects
    from acal.core.pipeline import spanned
    reads = {"temp": 0, "time": 1, "drift": 1, "step": 1, "supply": 2}
    for trial in range(40):
        b = Bins(2, 4, differ=G // 10, differs=(1, 1, 1))
        lo = [int(v) for v in rng.integers(0, 5000, 3)]
        width = [int(d + rng.integers(-2, 3)) for d in bins.DIFFERS]
        for k, (x, y, z) in enumerate([(G, 0, 0), (-G, 0, 0), (0, G, 0), (0, -G, 0), (0, 0, G)]):
            cond = [lo[c] + (width[c] if k == 1 else 0 if k == 0 else rng.integers(0, width[c] + 1))
                    for c in range(3)]
            assert b.offer(x, y, z, [int(v) for v in cond]) >= 0
        flat = bins.conditions(b.total())
        n = b.gather(bins.int32s(3 * b.total()), flat)
        for kind, name in effects.NAMES.items():
            want = next((c for key, c in reads.items() if key in name), -1)
            if name == "nonlinear":
                want = -1
            expect = want < 0 or width[want] >= bins.DIFFERS[want]
            assert spanned(b, (kind,)) == search.testable(kind, flat, n) == expect, (name, width)
