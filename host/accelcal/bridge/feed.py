"""Rest points offered to the device's bins in bulk, under CPython: the same bins (acal/core/bins.py),
fewer calls.  A points group's rest means go to `Bins.offer` one at a time on a board; here a
numpy judge first finds every point that `offer` is certain to refuse, given what the bins hold,
and only the others are offered.  A refusal changes nothing but the `offered` count, so the
judgement stays true until a point is kept; then the rest of the block is judged again.  The
bins end holding the same points in the same slots, bit for bit (tests/bridge/test_feed.py compares
both feeds on recordings).

`offer` refuses a point (docs/method-and-formats.md "Point selection"):
* beyond 1.25 g on an axis, or with |v| outside [0.5, 1.5] g;
* when a subset it falls in has room (the one with fewest points takes it), if it lies within
  `differ` (max-norm) of a held point, in orientation and in every tracked condition;
* when every subset it falls in is full: FIRST keeps nothing more; CENTRE, with no condition
  tracked, tries each subset in axis order: it replaces the first of the worst-placed held points
  if that one is placed worse than it (badness) and no other held point lies within `differ`.
  A composed model's spread rule (tracked conditions) is left to `offer`.
"""
from __future__ import annotations

import numpy as np

from acal.core import bins as dbins
from acal.core.fixed import C_TIME
from acal.discover.heldout import held_out
from accelcal.fixedpoint import QUANTITIES

BLOCK = 256     # points judged against one snapshot of the bins


def subset_of_vec(c: np.ndarray, axis: int, lo_out: int) -> np.ndarray:
    """acal.core.bins.subset_of for an array of components (Q16 g ints): subset index or -1."""
    s = np.full(c.shape, -1, np.int64)
    s[(-dbins._HI_OUT <= c) & (c <= -lo_out)] = 3 * axis
    s[(lo_out <= c) & (c <= dbins._HI_OUT)] = 3 * axis + 2
    s[(-dbins._HI_MID <= c) & (c <= dbins._HI_MID)] = 3 * axis + 1
    return s


def badness_vec(q: np.ndarray, axis: int, middle: bool) -> np.ndarray:
    """acal.core.bins.badness of points q (n, 3) Q16 g for the subset of `axis` (its 0 subset when
    `middle`, else n or p: the same formula for both)."""
    c = np.abs(q[:, axis])
    if not middle:
        return np.abs(c - dbins.POINT_ONE_G)
    a = q[:, 1 if axis == 0 else 0]
    b = q[:, 1 if axis == 2 else 2]
    return c + np.abs(np.abs(a) - np.abs(b))


def never_kept(q: np.ndarray) -> np.ndarray:
    """Points (n, 3) Q16 g that Bins.offer refuses whatever it holds: beyond 1.25 g on an axis,
    or |v|^2 (Q24, after the device's 4-bit shift) outside [0.5, 1.5] g squared."""
    out = (np.abs(q) > dbins._HI_OUT).any(axis=1)
    s = q >> 4
    mag2 = (s * s).sum(axis=1)
    return out | (mag2 < dbins._MAG2_MIN) | (mag2 > dbins._MAG2_MAX)


def _held(b: dbins.Bins):
    """The bins' held points: (slots (h,), xyz (h, 3), conditions (h, 3)) as int64."""
    m = b.max_count
    slots = np.array([s * m + k for s in range(dbins.N_SUBSETS) for k in range(b.counts[s])],
                     np.int64)
    xyz = np.frombuffer(b.xyz, np.int32).reshape(-1, 3)[slots].astype(np.int64)
    cond = np.frombuffer(b.cond, np.int32).reshape(-1, dbins.COND)[slots].astype(np.int64)
    return slots, xyz, cond


def _differs(b: dbins.Bins) -> list[int]:
    # the bins' least differences of each condition (0: not tracked), in QUANTITIES' order
    return list(b.differs)


def refused(b: dbins.Bins, q: np.ndarray, cond: np.ndarray) -> np.ndarray:
    """True for each point (n, 3) Q16 g, seen at cond (n, 3) ints, that `b.offer` refuses with
    the bins as they are now (module doc)."""
    skip = never_kept(q)
    m = b.max_count
    slots, hx, hc = _held(b)
    near = np.ones((len(q), len(slots)), bool)
    for c in range(3):
        near &= np.abs(q[:, c, None] - hx[None, :, c]) < b.differ
    for c, differ in enumerate(_differs(b)):
        if differ:
            near &= np.abs(cond[:, c, None] - hc[None, :, c]) < differ
    n_near = near.sum(axis=1)
    counts = np.array(b.counts, np.int64)
    subsets = [subset_of_vec(q[:, axis], axis, b.lo_out) for axis in range(3)]
    room = np.zeros(len(q), bool)
    for s in subsets:
        room |= (s >= 0) & (counts[np.maximum(s, 0)] < m)
    tracked = any(_differs(b))
    if b.policy == dbins.FIRST:
        closed = ~room
    elif tracked:
        closed = np.zeros(len(q), bool)       # the spread rule: offer decides
    else:
        closed = ~room & _no_replacement(b, q, subsets, slots, near, n_near)
    return skip | (room & (n_near > 0)) | closed


def _no_replacement(b, q, subsets, slots, near, n_near) -> np.ndarray:
    # CENTRE, no condition tracked, every subset of the point full: True where no subset has a
    # worst-placed held point (the first of equals) placed worse than the point with no other
    # held point near it.
    m = b.max_count
    worst_bad = np.full(dbins.N_SUBSETS, -1, np.int64)
    worst_col = np.zeros(dbins.N_SUBSETS, np.int64)   # its column in `near`
    col = {int(v): i for i, v in enumerate(slots.tolist())}
    for s in range(dbins.N_SUBSETS):
        for k in range(b.counts[s]):
            bad = dbins.badness(*b.point(s, k), s)
            if bad > worst_bad[s]:
                worst_bad[s], worst_col[s] = bad, col[s * m + k]
    rows = np.arange(len(q))
    none = np.ones(len(q), bool)
    for axis, s in enumerate(subsets):
        inside = s >= 0
        si = np.maximum(s, 0)
        bad = np.where(s == 3 * axis + 1, badness_vec(q, axis, True), badness_vec(q, axis, False))
        better = inside & (worst_bad[si] > bad)
        if len(slots):
            others = n_near - near[rows, worst_col[si]]
        else:
            others = n_near
        none &= ~(better & (others == 0))
    return none


def offer_points(runner, collector, q: np.ndarray, cond: np.ndarray | None) -> None:
    """Offer the rest means q (n, 3) Q16 ints, each seen at cond (n, COND) ints (QUANTITIES;
    None: the conditions are not sent, as protocol_items does for the base model), to
    runner's pipeline: the records and the bins as `runner.point` one at a time leaves them."""
    pipe = runner.pipe
    b = pipe.bins
    rest = collector.results[-1].rest_int
    seen = np.zeros((len(q), len(QUANTITIES)), np.int64) if cond is None else cond
    last = None
    now = _conditions_now(pipe)
    a = 0
    while a < len(q):
        block = q[a:a + BLOCK]
        skip = refused(b, block, _as_offered(b, seen[a:a + BLOCK])).tolist()
        rows = block.tolist()
        conds = cond[a:a + BLOCK].tolist() if cond is not None else None
        changes = b.kept + b.replaced
        for i, (x, y, z) in enumerate(rows):
            a += 1
            if conds is not None and conds[i] != last:
                last = conds[i]
                runner.conditions(*last)
                now = _conditions_now(pipe)
            # a discovering pipeline's held-out blocks take points the bins would refuse
            if skip[i] and not (pipe.plug is not None and pipe.plug.held is not None
                                and held_out(pipe.now[C_TIME])):
                # what offer and on_rest do for a refusal
                pipe.rest_count += 1
                b.offered += 1
                rest.append((x, y, z, -1) + now)
                continue
            runner.point(x, y, z)
            if b.kept + b.replaced != changes:
                break       # the bins changed: judge the rest again


def _conditions_now(pipe) -> tuple:
    # the pipeline's current conditions, as its rest records carry them (QUANTITIES' order is
    # the device's columns, fixed.C_TEMP ...)
    return tuple(pipe.now[i] for i in range(len(QUANTITIES)))


def _as_offered(b: dbins.Bins, cond: np.ndarray) -> np.ndarray:
    # offer zeroes the conditions it does not track
    out = cond.copy()
    for c, differ in enumerate(_differs(b)):
        if not differ:
            out[:, c] = 0
    return out
