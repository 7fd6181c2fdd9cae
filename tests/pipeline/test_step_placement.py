"""The two placements of a step's time among the held-out points of its gap are one rule: the
host's (pipeline/diagnose.py place_step, floats) and the board's (device/acal/discover/stepplace.py,
integers), fed the same simulated points and the same model, split the gap's points alike and
score them leave-one-out alike.

Both are given exactly the same numbers: readings in Q16 g (the board's held-out points; the host
reads the same values in g), times in 64 s units (the host's seconds are 64 times them) and the
model's parameters as the board's Q24 integers (the host's floats are those integers / 2**24).
A shock at a known time: inside the gap, just after its lower end (every gap point stepped),
at its upper end (none stepped), and no shock at all (with the step in the model, and with a zero
step: every split ties, and both take the later).  Three seeds draw 12, 30 and 6 gap points
(stepplace.GAP_MAX = 32 keeps them all), some at equal times (a split falls between distinct
times only), and 20 held-out points either side of the gap (some at a fit point's time).

What they are expected to differ in, by design: the placed time's convention (the board's is the
first stepped gap point's time, as its change-point search places the fitted time; the host's
halfway between the split's neighbours, as its search does), compared here as the split (the gap
points before it); and the per-point error: the host's | |a| - 1 g |, diagnose's metric, the
board's | |a|^2 - 1 g^2 | (score.py).  So the errors are compared with the host's rule fed the
board's per-point error (diagnose.residuals returning |a|^2 - 1): then they differ only by the
board's fixed point.  Tolerance, from its formats: the residual is computed in Q22 g^2
(model.residual: allowed 8 Q22 LSB of truncation) and taken to Q16 g^2 by a floor
(heldscore.ERR_SHIFT: under 1 Q16 LSB, down for a positive residual, up in absolute value for a
negative one), so 2**-16 + 8 * 2**-22 g^2 a point, over every held-out point of a sum (the sums
here differ by 2-9.4 Q16 LSB over 46-70 points, the board's below: its floor)."""
import numpy as np
import pytest

from acal.core import effects
from acal.core.bins import COND
from acal.discover.heldout import HeldOut, block_of
from acal.discover.score import HeldScore
from acal.discover.stepplace import GAP_MAX, StepPlace
from accelcal import simulate
from accelcal.model.effects import ModelSpec
from accelcal.pipeline import diagnose
from accelcal.pipeline.restpoints import RestPoints

TRUTH = np.array([1.02, 0.98, 1.01, 0.004, -0.006, 0.003, 0.03, -0.02, 0.04])
J_TRUE = np.array([0.012, -0.009, 0.015])   # the shock's offset step, g
NOISE = 0.001                                # g per axis of a rest mean
SPEC = ModelSpec.parse("base+step")
LO, HI = 1000, 1225                          # the gap: fit points at these times (64 s units)
Q16 = 1 << 16
TOL_PER_POINT = 2.0 ** -16 + 8 * 2.0 ** -22    # g^2: see above


def scene(seed, shock, n_gap):
    """Held-out points (Q16 g, times): n_gap inside the gap (a few sharing a time), 20 outside
    it on either side; the readings of a sensor with errors TRUTH and the step J_TRUE from time
    `shock` (None: no step)."""
    rng = np.random.default_rng(seed)
    gap = np.sort(rng.integers(LO + 1, HI, n_gap))
    gap[1::7] = gap[0::7][:len(gap[1::7])]           # some equal times
    gap = np.sort(gap)
    outside = np.r_[rng.integers(LO - 400, LO + 1, 20), rng.integers(HI, HI + 400, 20)]
    t = np.r_[gap, outside]
    d = simulate.unit_points(rng, len(t))
    v = simulate.uncorrect(TRUTH, d) + rng.normal(scale=NOISE, size=(len(t), 3))
    if shock is not None:
        v += J_TRUE * (t >= shock)[:, None]
    return np.rint(v * Q16).astype(np.int64), t


def held(xyz, t, weight=None):
    """A HeldOut holding these points, weight 1 each unless given."""
    h = HeldOut()
    for i in range(len(t)):
        for c in range(3):
            h.xyz[3 * i + c] = int(xyz[i, c])
        h.cond[COND * i + 1] = int(t[i])
        h.block[i] = block_of(int(t[i]))
        h.weight[i] = 1 if weight is None else int(weight[i])
    h.count = len(t)
    return h


def scored_at(xyz, t, p_int, ts):
    """The step model's held-out error with its step at ts, every point scored (HeldScore)."""
    from array import array
    return HeldScore().score(array("i", p_int), (effects.STEP,), held(xyz, t), None, ts)


def board(xyz, t, p_int, weight=None):
    """The board's placement (StepPlace on a HeldOut holding these points, weight 1 each unless
    given, the model scored at the fitted time HI, as search.py drives it)."""
    from array import array
    h = held(xyz, t, weight)
    p = array("i", p_int)
    kinds = (effects.STEP,)
    s = HeldScore()
    err = s.score(p, kinds, h, None, HI)
    s.begin(p, kinds, h, None, HI)
    place = StepPlace()
    place.begin(s, h, 0, LO, HI, err, 48)
    while not place.step():
        pass
    return place


def host(xyz, t, theta):
    """The host's placement: the same points in g and seconds, fit points at LO and HI (and
    beyond), the fitted time halving the gap as its change-point search places it."""
    test = RestPoints(xyz / Q16, 64.0 * t, None, np.zeros(len(t)), "tie")
    ft = np.array([LO - 300, LO, HI, HI + 300])
    train = RestPoints(np.zeros((4, 3)), 64.0 * ft, None, np.zeros(4), "tie")
    return diagnose.place_step(SPEC, theta, train, test, {"ts": 64.0 * (LO + HI) / 2})


def squared(spec, theta, p, ref):
    """diagnose's residuals with the board's per-point error: |a|^2 - 1 g^2."""
    a = spec.correct(theta, p.v, np.zeros(len(p.t)), p.t, ref, p.cols)
    return a, (a * a).sum(axis=1) - 1.0


CASES = [(seed, where, n_gap) for seed, n_gap in ((3, 12), (17, 30), (29, 6))
         for where in ("inside-early", "inside", "inside-late", "lower-edge", "upper-edge",
                       "none", "zero-step")]


@pytest.mark.parametrize("seed,where,n_gap", CASES)
def test_host_and_board_place_a_step_alike(seed, where, n_gap, monkeypatch):
    assert n_gap <= GAP_MAX
    shock = {"inside-early": LO + 40, "inside": (LO + HI) // 2, "inside-late": HI - 40,
             "lower-edge": LO + 1, "upper-edge": HI, "none": None, "zero-step": None}[where]
    xyz, t = scene(seed, shock, n_gap)
    j = np.zeros(3) if where == "zero-step" else J_TRUE
    p_int = SPEC.to_int(np.r_[TRUTH, j])
    theta = SPEC.from_int(p_int)              # the very numbers the board holds
    gap = np.sort(t[(t > LO) & (t < HI)])
    assert len(gap) == n_gap

    pl = board(xyz, t, p_int)
    out = host(xyz, t, theta)
    assert pl.n == out["step_gap_points"] == n_gap
    # the split: the gap points before the placed time (the board's time is the first stepped
    # point's, the host's lies strictly between the split's neighbours)
    k_board = int((gap < pl.step_time).sum())
    k_host = int((gap < out["step_time_placed_s"] / 64).sum())
    assert k_board == k_host, (k_board, k_host)
    assert pl.step_time == (HI if k_board == n_gap else gap[k_board])
    edges = np.r_[LO, gap, HI]
    assert edges[k_host] < out["step_time_placed_s"] / 64 < edges[k_host + 1]

    # against the simulated truth: with no shock in the gap's data every point stays unstepped
    # (split after them all); with one, the split separates the points either side of it, but
    # for points the shock barely moves (by under 5 noise sds in |a|: a point's noise may then
    # fit it better on the other side; seed 3 "inside": one point, moved 3.4 mg, fits
    # unstepped by 0.14 mg; the other 20 splits here are the truth's)
    truth = n_gap if shock is None or shock >= HI else int((gap < shock).sum())
    g_xyz = xyz[np.argsort(np.where((t > LO) & (t < HI), t, HI + 1000), kind="stable")][:n_gap]
    moved = np.abs(g_xyz @ J_TRUE) / np.linalg.norm(g_xyz, axis=1)
    off = moved[min(k_board, truth):max(k_board, truth)]
    assert np.all(off < 5 * NOISE), (k_board, truth, off)

    # the errors, the host's rule fed the board's per-point error
    monkeypatch.setattr(diagnose, "residuals", squared)
    same = host(xyz, t, theta)
    n = len(t)
    tol = n * TOL_PER_POINT
    assert int((gap < same["step_time_placed_s"] / 64).sum()) == k_board
    assert abs(same["heldout_error_placed_mg"] / 1e3 * n - pl.placed_loo / Q16) <= tol
    assert abs(same["heldout_error_placed_insample_mg"] / 1e3 * n
               - pl.placed_insample / Q16) <= tol


@pytest.mark.parametrize("shock", [HI - 30, LO + 10])
def test_past_gap_max_the_board_places_among_its_latest_gap_points_only(shock):
    """More gap points than stepplace.GAP_MAX (40 here): the board keeps the latest 32 and
    leaves the earliest ones unstepped, where the host weighs them all.  A shock among the
    latest: the same split.  A shock before them (a limit of the board's memory, 12 bytes a gap
    point, not met in the slow study's gaps of 6-10 points): the host splits at the truth, the
    board at the earliest kept time after every dropped one, the nearest it can (here a
    dropped point shares the earliest kept time, 1030: that kept point stays unstepped with
    it).  Either way its in-sample error is the step model's with the step at the placed time."""
    n_gap = 40
    xyz, t = scene(5, shock, n_gap)
    p_int = SPEC.to_int(np.r_[TRUTH, J_TRUE])
    pl = board(xyz, t, p_int)
    out = host(xyz, t, SPEC.from_int(p_int))
    gap = np.sort(t[(t > LO) & (t < HI)])
    k_board = int((gap < pl.step_time).sum())
    k_host = int((gap < out["step_time_placed_s"] / 64).sum())
    truth = int((gap < shock).sum())
    assert pl.n == GAP_MAX and out["step_gap_points"] == n_gap
    if truth >= n_gap - GAP_MAX:
        assert k_board == k_host == truth, (k_board, k_host, truth)
    else:
        after_dropped = gap[gap > gap[n_gap - GAP_MAX - 1]][0]
        assert k_host == truth and pl.step_time == after_dropped, (k_board, k_host, truth)
    assert pl.placed_insample == scored_at(xyz, t, p_int, pl.step_time)


def test_a_weighted_point_places_and_scores_as_its_rest_means(monkeypatch):
    """A board's held-out point stands for up to heldout.WEIGHT_CAP rest means of one posture
    (its weight); the host holds each.  Given a point of weight w on the board and w copies of it
    on the host: the same split and the same in-sample error (to the fixed point, a tolerance a
    rest mean).  Leave-one-out they differ by design: the board leaves the whole point out, the
    host one copy while its w - 1 twins still place the time, so it is not compared."""
    monkeypatch.setattr(diagnose, "residuals", squared)
    for seed in (7, 8):
        xyz, t = scene(seed, (LO + HI) // 2 + 13, 14)
        w = np.random.default_rng(seed).integers(1, 5, len(t))
        p_int = SPEC.to_int(np.r_[TRUTH, J_TRUE])
        pl = board(xyz, t, p_int, w)
        out = host(np.repeat(xyz, w, axis=0), np.repeat(t, w), SPEC.from_int(p_int))
        gap = np.sort(t[(t > LO) & (t < HI)])
        assert int((gap < pl.step_time).sum()) == int((gap < out["step_time_placed_s"] / 64).sum())
        n = int(w.sum())
        assert abs(out["heldout_error_placed_insample_mg"] / 1e3 * n
                   - pl.placed_insample / Q16) <= n * TOL_PER_POINT


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_past_gap_max_a_dropped_point_at_the_earliest_kept_time_stays_with_it(seed):
    """More gap points than GAP_MAX, the latest dropped one at the same 64 s time as the earliest
    kept one (made so), a shock before them all: the board may not place the time there (a
    split falls between distinct times: its calibration would step the dropped point it scored
    unstepped).  Its in-sample error is the step model's held-out error with the step at the
    placed time (HeldScore over every point, independent of the placement's sums)."""
    n_gap = 40
    xyz, t = scene(seed, LO + 10, n_gap)
    order = np.argsort(np.where((t > LO) & (t < HI), t, HI + 1000), kind="stable")[:n_gap]
    first_kept = order[n_gap - GAP_MAX]
    t[order[n_gap - GAP_MAX - 1]] = t[first_kept]    # the latest dropped: the same time
    gap = np.sort(t[(t > LO) & (t < HI)])
    assert gap[n_gap - GAP_MAX - 1] == gap[n_gap - GAP_MAX] < gap[n_gap - GAP_MAX + 1]
    p_int = SPEC.to_int(np.r_[TRUTH, J_TRUE])
    pl = board(xyz, t, p_int)
    assert pl.n == GAP_MAX
    # not at the earliest kept time, which the dropped point shares (the host, holding every
    # point, splits before them all; the board cannot: see test_past_gap_max_...)
    assert pl.step_time > gap[n_gap - GAP_MAX], (pl.step_time, gap[n_gap - GAP_MAX])
    assert pl.placed_insample == scored_at(xyz, t, p_int, pl.step_time)
