"""What the host hands the device pipeline and what it gets back: the settings (Config), one
device's data (Group), its outcome (DeviceResult), and the protocol between them
(bridge/scripts/mp_runner.py).  In one process the host calls the runner's methods with ints and
collects ints (no text); a MicroPython child gets the same calls as text lines and answers in
lines, read by the same collector."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from acal.core import bins as dbins
from acal.core import fixed, gaussnewton, rest
from acal.paper import objective, optimiser
from acal.core import profile as dprofile
from accelcal.bridge.scripts.mp_runner import SETTINGS
from accelcal.bridge.boardlog import STATUS_NAMES
from accelcal.errors import InputError
# the groups and the conditions' conversion, re-exported: what the protocol carries
from accelcal.bridge.groups import (Group, PointsGroup, RestMeans, SamplesGroup,  # noqa: F401
                                    condition_changes)
from accelcal.fixedpoint import device_conditions  # noqa: F401

# points per subset the fits take: the nine subsets under the 128 points both fits' integer
# sums are proven for (acal.core.gaussnewton.MAX_POINTS, acal.paper.objective.MAX_POINTS): 14
MAX_PER_SUBSET = min(gaussnewton.MAX_POINTS, objective.MAX_POINTS) // dbins.N_SUBSETS

BATCH = 200  # samples per B record: its ints split on the board (CircuitPython has ~110 kB free)


@dataclass(frozen=True)
class Config:
    """Pipeline settings in physical units; `line()` gives the device's integers.  The defaults
    are the paper profile's; Config.for_profile() gives a profile's (acal/core/profile.py).  Immutable:
    a step that needs other settings makes them with dataclasses.replace."""
    rate_hz: int = 100
    seconds: int = rest.DEFAULT_SECONDS
    threshold_g: float | None = 0.12   # None: from the measured noise (acal.core.rest.AUTO)
    axis: int = 0                      # 3: all axes (acal.core.rest.ALL_AXES)
    min_count: int = 2
    max_count: int = 2
    differ_g: float = 0.1
    policy: str = "centre"
    iterations: int = optimiser.DEFAULT_ITERATIONS
    rates_tenths: tuple[int, int, int] = (fixed.ALPHA_SCALE, fixed.ALPHA_MISALIGN, fixed.ALPHA_OFFSET)
    kinds: tuple[int, ...] = ()  # a composed model's effects (acal.core.effects ids)
    conditions: bool = False     # hand the device each point's temperature and time even without
    # kinds: a model whose effects the host fits (ModelSpec.host_only) needs them on the points
    fit: int = dprofile.GRADIENT
    profile: str = "paper"
    discover: bool = False       # the board's own model discovery after the fit (NEWTON, base)

    def __post_init__(self):
        # the fits' capacity, checked where every caller's settings meet (the CLI, the Python
        # API, a board log's BOOT): past it the device code raises a ValueError
        if not 1 <= self.min_count or self.max_count > MAX_PER_SUBSET:
            raise InputError(f"min_count {self.min_count}, max_count {self.max_count}: need 1 <= "
                             f"min_count <= max_count <= {MAX_PER_SUBSET} (nine subsets under the "
                             "128 points the fits' integer sums are proven for)")

    @classmethod
    def for_profile(cls, name: str, composed: bool = False, **overrides) -> "Config":
        """A profile's settings (acal.core.profile.settings), then any overrides (None: not given).
        composed: a composed model's defaults (more points and iterations for the paper's fit)."""
        s = dprofile.settings(dprofile.parse(name), composed)
        thr = s["threshold"]
        fit = s["fit"]
        if fit == dprofile.NEWTON:
            from acal.core.gaussnewton import DEFAULT_ITERATIONS as iterations
        else:
            iterations = optimiser.COMPOSED_ITERATIONS if composed else optimiser.DEFAULT_ITERATIONS
        cfg = cls(threshold_g=None if thr == rest.AUTO else thr / fixed.SAMPLE_ONE_G,
                  axis=s["axis"], min_count=s["min_count"], max_count=s["max_count"],
                  iterations=iterations, fit=fit, profile=name)
        return replace(cfg, **{k: v for k, v in overrides.items() if v is not None})

    @property
    def threshold_int(self) -> int:
        """The rest threshold as the device holds it, Q10 g (0: rest.AUTO)."""
        if self.threshold_g is None:
            return rest.AUTO
        return int(round(self.threshold_g * fixed.SAMPLE_ONE_G))

    def values(self) -> list[int]:
        """The settings as the device takes them (mp_runner.SETTINGS order), then the learning
        rates and the effect ids: what the C line carries."""
        named = {"rate_hz": self.rate_hz, "seconds": self.seconds, "threshold": self.threshold_int,
                 "axis": self.axis, "min_count": self.min_count, "max_count": self.max_count,
                 "differ": int(round(self.differ_g * fixed.POINT_ONE_G)),
                 "policy": {"first": dbins.FIRST, "centre": dbins.CENTRE}[self.policy],
                 "iterations": self.iterations, "fit": self.fit,
                 "discover": int(self.discover)}
        return [named[k] for k in SETTINGS] + list(self.rates_tenths) + list(self.kinds)


@dataclass
class DeviceResult:
    name: str
    status: int = -1
    iterations: int = 0
    objective_start: int = 0
    objective: int = 0
    params_int: list[int] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)
    rest_int: list[tuple[int, ...]] = field(default_factory=list)  # x y z subset temp time supply
    selected_int: list[tuple[int, ...]] = field(default_factory=list)  # x y z temp time supply
    # the fit's references, a column each (acal.core.bins.COND, QUANTITIES' order: Q2 degC,
    # 64 s units, mV), as the device's Pipeline.ref
    ref: list[int] = field(default_factory=lambda: [0] * dbins.COND)
    step_time: int = 0       # a step's time, 64 s units from ref[C_TIME]
    ready: bool = False      # the bins' own verdict (counts, and a composed model's spread)
    # the held points' range of each condition, the same columns (Bins.span)
    span: list[int] = field(default_factory=lambda: [0] * dbins.COND)
    covered: bool = False    # the held points cover every axis (bins.covered())
    kept: list[int] | None = None   # NEWTON: per selected point, 1 kept by the fit, 0 an outlier
    threshold: int | None = None    # AUTO: the rest threshold at the end, Q10 g
    noise_level: int | None = None  # and the noise level it came from, Q10 g
    discovery: list[int] | None = None   # discover: the (first) V record (mp_runner.py)
    # discover: each later round's V record and its W records (after an adoption)
    rounds: list[tuple[list[int], list]] = field(default_factory=list)
    candidates: list[tuple[int, int, int]] = field(default_factory=list)  # W: kind err betters
    heldout: list[list[int]] = field(default_factory=list)  # H: x y z, COND conditions, weight

    @property
    def status_name(self) -> str:
        return STATUS_NAMES[self.status]

    @property
    def rest_g(self) -> np.ndarray:
        return np.array([r[:3] for r in self.rest_int], dtype=np.float64).reshape(-1, 3) / fixed.POINT_ONE_G

    @property
    def selected_g(self) -> np.ndarray:
        return np.array([r[:3] for r in self.selected_int], dtype=np.float64).reshape(-1, 3) / fixed.POINT_ONE_G

    @property
    def fit_points_g(self) -> np.ndarray:
        """The selected points the device's fit kept (all of them unless it rejected outliers)."""
        sel = self.selected_g
        return sel if self.kept is None else sel[np.asarray(self.kept, bool)]

    @property
    def rest_conditions(self) -> np.ndarray:
        """(N, COND) ints: each rest mean's conditions (fixedpoint.QUANTITIES: temperature degC,
        time in 64 s units, the board's supply mV)."""
        return np.array([r[4:4 + dbins.COND] for r in self.rest_int],
                        dtype=np.int64).reshape(-1, dbins.COND)


def protocol_items(groups: list[Group], cfg: Config, batch: int = BATCH, bulk: bool = False):
    """The runner's calls, in order, as (method, args): configure, then per group its points or
    samples (batch a call at most) with their conditions, gaps and wear, and end.  All ints.
    bulk: a group's points as one ("points", (q (n, 3) ints, their conditions (n, 3) or None))
    for bridge/feed.py."""
    yield "configure", (cfg.values(),)
    composed = bool(cfg.kinds) or cfg.conditions
    for g in groups:
        yield "group", (g.name,)
        yield from g.calls(composed, batch, bulk)
        yield "end", ()


_LINE_TAGS = {"configure": "C", "group": "G", "conditions": "T", "point": "P", "gap": "X",
              "worn": "W", "end": "E"}


def protocol_lines(groups: list[Group], cfg: Config, batch: int = BATCH):
    """The same calls as the text lines a MicroPython child reads (mp_runner.py's protocol)."""
    for method, args in protocol_items(groups, cfg, batch):
        if method == "samples":
            buf, n = args
            yield f"B {n} " + " ".join(map(str, buf))
        elif method == "configure":
            yield "C " + " ".join(map(str, args[0]))
        elif method == "worn":
            yield f"W {int(args[0])}"
        else:
            yield " ".join([_LINE_TAGS[method], *map(str, args)])


class Collector:
    """The runner's records (emit(tag, values)) into one DeviceResult per group."""

    def __init__(self):
        self.results: list[DeviceResult] = []

    def emit(self, tag: str, v) -> None:
        if tag == "G":
            self.results.append(DeviceResult(str(v[0])))
            return
        cur = self.results[-1]
        if tag == "R":
            cur.rest_int.append(tuple(v[:4 + dbins.COND]))
        elif tag == "S":
            cur.selected_int.append(tuple(v[:3 + dbins.COND]))
        elif tag == "Z":
            cur.step_time, cur.ref = v[0], list(v[1:1 + dbins.COND])
        elif tag == "Y":
            cur.ready, cur.covered = v[0] == 1, v[1] == 1
            cur.span = list(v[2:2 + dbins.COND])
        elif tag == "K":
            cur.counts = list(v)
        elif tag == "D":
            cur.kept = list(v[1:])
        elif tag == "N":
            cur.threshold, cur.noise_level = v[0], v[1]
        elif tag == "V":
            if cur.discovery is None:
                cur.discovery = list(v)
            else:
                cur.rounds.append((list(v), []))
        elif tag == "W":
            (cur.rounds[-1][1] if cur.rounds else cur.candidates).append(tuple(v[:3]))
        elif tag == "H":
            cur.heldout.append(list(v[:4 + dbins.COND]))
        elif tag == "F":
            cur.status, cur.iterations, cur.objective_start, cur.objective = v[:4]
            cur.params_int = list(v[4:])
        else:
            raise InputError(f"the device runner said: {tag} {' '.join(map(str, v))[:200]}")


def parse(out_lines) -> list[DeviceResult]:
    """A MicroPython child's output lines into results."""
    c = Collector()
    for line in out_lines:
        f = line.split()
        if not f:
            continue
        if f[0] == "G":
            c.emit("G", f[1:2])
            continue
        try:
            c.emit(f[0], [int(x) for x in f[1:]])
        except (ValueError, IndexError):
            raise InputError(f"the device runner said: {line.strip()[:200]}") from None
    return c.results
