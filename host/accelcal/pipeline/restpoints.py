"""Rest points of a recording or points file, the unit every float fit and score works on: the
still segments the device's detector finds (through its vectorised twin, pipeline/scan.py), each
with its mean (g), time, mean temperature and the noise of its mean; and the split into training
and held-out blocks.

Split (why it is fair): the recording is cut into 2-hour blocks; even blocks train, odd blocks
test.  Both halves span the whole recording's time and temperature range, so an effect that
depends on either is seen by the fit and tested on it; no rest segment is split between them, and
postures held across a block edge are the only shared context.  Each half must pass the one
coverage rule every fit here shares (coverage_reason: the float methods' own check, and what
compare and diagnose ask of the points they hand the device): a wrist that turns over in only a
few hours can leave the even blocks one-sided, so other blocks are tried in a fixed order
(SPLITS) and the first whose halves both cover is used, or the reason none does is given.

Or, asked for (`compare --split first-half|second-half`, issue 30's criterion on real data), the
rest points cut at the middle of their time span: one half trains, the other is held out.  That
is the harder test: the held-out half lies outside the training half's time, and may lie outside
its temperatures and postures (a day trains, a night is scored).  Both halves must pass the same
coverage rule; there is no fallback, since the cut is what is asked for."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acal.core import fixed
from accelcal.errors import InputError
from accelcal.files.readers import is_recording
from accelcal.files.recordings import open_recording
from accelcal.files.table import Table, read_table
from accelcal.methods import coverage_reason

BLOCK_S = 2 * 3600


@dataclass
class RestPoints:
    v: np.ndarray          # (N, 3) g
    t: np.ndarray          # (N,) s, segment middle
    temp: np.ndarray | None
    noise: np.ndarray      # (N,) g: sd(|v|) / sqrt(n) inside the segment
    source: str
    cols: dict = field(default_factory=dict)   # further columns by name: (N,) segment means

    def __len__(self):
        return len(self.v)

    def take(self, sel):
        return RestPoints(self.v[sel], self.t[sel], None if self.temp is None else self.temp[sel],
                          self.noise[sel], self.source, {k: c[sel] for k, c in self.cols.items()})


def rest_points(path, seconds: int = 5, threshold: int = 0, axis: int = 3) -> RestPoints:
    """path: a recording (any size or format: one streaming pass of the vectorised twin of the
    device's detector, accelcal.pipeline.scan; the still segments calibrate keeps, gaps honoured, imputed,
    clipped and non-wear ones left out), or a points file or
    Table.  seconds, threshold (Q10 g; 0: from the noise), axis (3: all): the rest test, by
    default the wear profile's."""
    if not isinstance(path, Table) and not is_recording(path):
        path = read_table(path)
    if isinstance(path, Table):
        if path.kind != "points":
            raise InputError(f"{path.path}: recordings are read by name (streamed)")
        c = path.columns
        n = len(path.xyz)
        further = {k: v for k, v in c.items() if k not in ("x", "y", "z", "t", "temp")}
        return RestPoints(path.xyz, c["t"] if "t" in c else np.arange(n, dtype=float),
                          c.get("temp"), np.zeros(n), path.path, further)
    from accelcal.pipeline.scan import scan
    rec = open_recording(path)
    sc = scan(rec, seconds, threshold, axis, extras=True)
    # the segments calibrate keeps: still, and not imputed, clipped or off the wrist (scan.masks)
    still = sc.masks()["kept"]
    if not still.any():
        raise InputError(f"{path}: no rest segments found (beside any imputed, clipped or "
                         "non-wear ones)")
    m = sc.seg_means[still]
    sd = np.sqrt(np.maximum(m[:, 3] - m[:, 2] ** 2, 0.0))
    return RestPoints(sc.segments.mean[still] / fixed.POINT_ONE_G, m[:, 0], m[:, 1] if rec.has_temp else None,
                      sd / np.sqrt(sc.length), str(path),
                      {c: sc.seg_column(c)[still] for c in sc.columns})


def usable(p: RestPoints) -> RestPoints:
    mag = np.linalg.norm(p.v, axis=1)
    return p.take((mag > 0.5) & (mag < 1.5))  # as the device's bins: not gravity otherwise


def check_coverage(p: RestPoints) -> None:
    """Exit 2 (methods.coverage_reason, the one rule) for rest points that cannot pin a
    calibration: calibrate (its bins, its methods' checks), compare and diagnose refuse the same
    data."""
    why = coverage_reason(p.v, 9, "a calibration")
    if why:
        raise InputError(f"{p.source}: {why}")


# The blocks tried, in order, for a split whose halves both cover (coverage_reason): (block
# length s, offset of the first edge s, which parity trains).  The first is the standing split.
SPLITS = [(BLOCK_S, 0, 0), (BLOCK_S, 0, 1), (BLOCK_S, BLOCK_S // 2, 0), (BLOCK_S, BLOCK_S // 2, 1),
          (BLOCK_S // 2, 0, 0), (BLOCK_S // 2, 0, 1), (BLOCK_S // 4, 0, 0), (BLOCK_S // 4, 0, 1)]


class Halves(tuple):
    """(train, held out, each held-out point's block), `train_block` (each training point's
    block) and `how`: the split in words (its blocks, or which time half trains)."""
    how: str
    train_block: np.ndarray


# How rest points may be split (module doc): alternate time blocks (the standing split), or the
# two halves of their time span, the first or the second training.
SPLIT_RULES = ("blocks", "first-half", "second-half")


def check_rule(rule: str) -> None:
    """InputError unless rule is one of SPLIT_RULES (callers check it before reading a file)."""
    if rule not in SPLIT_RULES:
        raise InputError(f"unknown split {rule!r}; choose from {', '.join(SPLIT_RULES)}")


def split(p: RestPoints, rule: str = "blocks") -> Halves:
    """The rest points into training and held-out halves by rule (SPLIT_RULES, module doc), both
    halves passing the coverage rule; InputError saying why when they cannot."""
    check_rule(rule)
    if rule == "blocks":
        return block_split(p)
    return time_halves(p, first_trains=rule == "first-half")


def time_halves(p: RestPoints, first_trains: bool) -> Halves:
    """The rest points cut at the middle of their time span (a point on it goes to the second
    half): the first half trains and the second is held out, or the reverse.  Each point's
    block is its half (0 first, 1 second).  InputError naming the half that does not cover."""
    t0, span = p.t.min(), p.t.max() - p.t.min()
    second = p.t >= t0 + span / 2
    train = ~second if first_trains else second
    names = ("first", "second") if first_trains else ("second", "first")
    hours = {"first": f"0-{span / 7200:.1f} h", "second": f"{span / 7200:.1f}-{span / 3600:.1f} h"}
    for role, sel, which in (("training", train, names[0]), ("held-out", ~train, names[1])):
        why = coverage_reason(p.v[sel], 9, f"the {role} half ({which} half by time, "
                                           f"{hours[which]} of the rest points' span)")
        if why:
            raise InputError(f"{p.source}: split {names[0]}-half: {why}; the device must turn "
                             "over in each half by time (split blocks interleaves 2-hour blocks)")
    block = second.astype(int)
    out = Halves((p.take(train), p.take(~train), block[~train]))
    out.train_block = block[train]
    out.how = (f"time halves, cut at {span / 7200:.1f} h of the rest points' {span / 3600:.1f}-h "
               f"span: the {names[0]} half trains, the {names[1]} is held out")
    return out


def block_split(p: RestPoints) -> Halves:
    """The rest points into training and held-out halves by time blocks (module doc): the first
    of SPLITS whose halves both pass the coverage rule; InputError saying why when none does."""
    first_why = None
    for length, offset, parity in SPLITS:
        block = ((p.t - p.t.min() + offset) // length).astype(int)
        train = block % 2 == parity
        bad = [(half, why) for half, why in
               (("training", coverage_reason(p.v[train], 9, "a fit on the training half")),
                ("held-out", coverage_reason(p.v[~train], 9, "a fit on the held-out half"))) if why]
        if not bad:
            out = Halves((p.take(train), p.take(~train), block[~train]))
            out.train_block = block[train]
            first, other = ("even", "odd") if parity == 0 else ("odd", "even")
            shift = f" from {offset / 3600:g} h" if offset else ""
            out.how = f"{length / 3600:g}-hour blocks{shift}: {first} train, {other} held out"
            if first_why:
                out.how += f" (2-hour even/odd blocks left the {first_why[0]} half one-sided " \
                           "or too small)"
            return out
        first_why = first_why or bad[0]
    raise InputError(f"{p.source}: no split into alternate time blocks (2 h, 1 h or 30 min, "
                     f"either half training) leaves both halves covering the sphere; with 2-hour "
                     f"even/odd blocks, {first_why[1]}.  A held-out score needs a recording in which "
                     "the device turns over more often")
