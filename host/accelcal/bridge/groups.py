"""One device's data as the host hands it to the device pipeline, one type per mode:

    PointsGroup   rest points in g (a points file, a study's devices)
    RestMeans     rest means the host's twin found in a recording (Q16 g ints, as they are)
    SamplesGroup  raw samples in g with their gaps and unworn runs (the device finds rest)

Each turns itself into the runner's calls (`calls`, bridge/protocol.py protocol_items).
`Group(name, points=... | points_q16=... | samples=..., ...)` makes the type its data names.
For a composed model each point or sample also has its temperature (degC) and time (s), and the
recording's further columns by name (cols): the device sees them as its conditions
(fixedpoint.device_conditions: Q2 degC rounded, 64 s units from the group's first time, mV)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from accelcal.fixedpoint import board_columns, device_conditions, g_to_point, g_to_sample


@dataclass
class Group:
    """What every mode has: a name, per point (or sample) temperature and time, further columns
    (host-only column effects are fitted on them; those the board reads, fixedpoint.QUANTITIES,
    are also handed to the device as conditions)."""
    name: str
    temp: np.ndarray | None = None
    t: np.ndarray | None = None
    cols: dict = field(default_factory=dict)
    n_samples = None   # samples behind the points, when the group came from a recording

    def __new__(cls, *args, **kw):
        if cls is Group:   # pick the mode by the data given
            cls = (SamplesGroup if "samples" in kw else
                   RestMeans if "points_q16" in kw else PointsGroup)
        return object.__new__(cls)

    @property
    def t_first(self) -> float:
        return float(self.t[0]) if self.t is not None and len(self.t) else 0.0

    def conditions(self, n: int) -> np.ndarray:
        return device_conditions(self.temp, self.t, self.t_first, n, **board_columns(self.cols))


@dataclass
class PointsGroup(Group):
    points: np.ndarray | None = None   # (N, 3) g

    def __len__(self) -> int:
        return len(self.points)

    def point_ints(self) -> np.ndarray:
        """The rest points as the device's bins take them, Q16 g ints."""
        return g_to_point(self.points)

    def calls(self, composed: bool, batch: int, bulk: bool):
        """Each point, led by its conditions where they change (a composed model's), or
        bulk: all points as one call (bridge/feed.py)."""
        q = self.point_ints()
        if bulk:
            yield "points", (np.asarray(q, np.int64),
                             np.asarray(self.conditions(len(q)), np.int64) if composed else None)
            return
        last = None
        for (x, y, z), c in zip(q.tolist(), self.conditions(len(q)).tolist()):
            if composed and c != last:
                yield "conditions", tuple(c)
                last = c
            yield "point", (x, y, z)


@dataclass
class RestMeans(Group):
    """A recording's rest means as the twin (bridge/twin.py) found them: handed to the bins as
    they are, never through floats, each with the device conditions the closing sample of its
    segment had; t_origin: the recording's first time."""
    points_q16: np.ndarray | None = None
    cond: np.ndarray | None = None
    t_origin: float | None = None
    n_samples: int | None = None

    def __len__(self) -> int:
        return len(self.points_q16)

    def point_ints(self) -> np.ndarray:
        return self.points_q16

    calls = PointsGroup.calls

    @property
    def t_first(self) -> float:
        return self.t_origin if self.t_origin is not None else super().t_first

    def conditions(self, n: int) -> np.ndarray:
        return self.cond if self.cond is not None else super().conditions(n)


@dataclass
class SamplesGroup(Group):
    samples: np.ndarray | None = None   # (N, 3) g
    # indices where a new contiguous run starts
    gaps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    # sample runs [start, stop) where rest segments closing are not offered to the bins (the
    # host's non-wear and quality checks, accelcal.pipeline.scan): the pipeline's worn = False
    unworn: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.samples)

    @property
    def n_samples(self) -> int:
        return len(self.samples)

    def calls(self, composed: bool, batch: int, bulk: bool = False):
        """The samples in runs cut at gaps, wear changes and (a composed model) condition
        changes, each run led by what changed, batch samples a call at most."""
        q = g_to_sample(self.samples)
        n = len(q)
        gaps = {int(i) for i in self.gaps if 0 < i < n}
        cuts = set(gaps)
        worn = np.ones(n + 1, bool)
        if self.unworn is not None and len(self.unworn):
            for a, b in self.unworn.tolist():
                worn[a:b] = False
            cuts.update((np.flatnonzero(np.diff(worn[:n])) + 1).tolist())
            cuts.discard(0)
        state = True
        if composed:  # a new run wherever the conditions change, led by its conditions
            cond = self.conditions(n)
            cuts.update(condition_changes(cond).tolist())
        bounds = [0, *sorted(cuts), n]
        for a, b in zip(bounds[:-1], bounds[1:]):
            if a in gaps:
                yield "gap", ()
            if bool(worn[a]) != state:
                state = bool(worn[a])
                yield "worn", (state,)
            if composed:
                yield "conditions", tuple(int(x) for x in cond[a])
            for s in range(a, b, batch):
                chunk = q[s:min(b, s + batch)]
                yield "samples", (chunk.ravel().tolist(), len(chunk))


def condition_changes(cond: np.ndarray) -> np.ndarray:
    """Indices where a sample's conditions differ from the previous sample's."""
    return np.flatnonzero(np.any(np.diff(cond, axis=0) != 0, axis=1)) + 1
