"""Rest points of a recording or points file, the unit every float fit and score works on: the
still segments the device's detector finds (through its vectorised twin, pipeline/scan.py), each
with its mean (g), time, mean temperature and the noise of its mean; and the split into training
and held-out blocks.

Split (why it is fair): the recording is cut into 2-hour blocks; even blocks train, odd blocks
test.  Both halves span the whole recording's time and temperature range, so an effect that
depends on either is seen by the fit and tested on it; no rest segment is split between them, and
postures held across a block edge are the only shared context."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acal import fixed
from accelcal.errors import InputError
from accelcal.files.readers import is_recording
from accelcal.files.recordings import open_recording
from accelcal.files.table import Table, read_table
from accelcal.methods import one_side_margin

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
    """Exit-2 reason for rest points that cannot pin a calibration: fewer than the 9 parameters,
    or all on one side of a plane through 0 g (one orientation or one hemisphere: a device lying
    still, in a temperature chamber say); the fit would only extrapolate to the other side.
    calibrate (its bins, its methods' checks) and compare refuse the same data."""
    if len(p) < 9:
        raise InputError(f"{p.source}: {len(p)} usable rest points; a calibration needs at "
                         "least 9, in different orientations")
    if one_side_margin(p.v) > 1e-9:
        raise InputError(f"{p.source}: the {len(p)} rest points cover one hemisphere only (all lie "
                         "on one side of a plane through 0 g: one orientation, or a device that "
                         "never turned over); a calibration needs both sides of every axis")


def split(p: RestPoints):
    block = ((p.t - p.t.min()) // BLOCK_S).astype(int)
    train = block % 2 == 0
    return p.take(train), p.take(~train), block[~train]
