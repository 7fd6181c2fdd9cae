"""Range tracing: run device code under CPython on ints that record every value they produce.

TracedInt behaves as an int; each arithmetic result is again a TracedInt and is checked against
the small-int limit of 32-bit MicroPython ports (|v| < 2**30).  Used by the tests (worst-case
ranges of the device code) and the bench (how many optimiser values would be longs on a 32-bit
board: none).

It also records the amount of every shift made inside a `@viper` function (acal/core/emit.py): a viper
shift is one machine instruction, and the architectures disagree past 31 (ARMv6-M gives Python's
answer, Xtensa and RV32 take the amount mod 32: `1000 >> 32` is 1000 there), so an amount the
worst cases drive outside 0..31 is a defect on some board (Tracer.wild_shifts)."""
from __future__ import annotations

import ast
import importlib
import sys
from pathlib import Path

from acal.core import fixed
from accelcal.locations import DEVICE_PACKAGE

SMALL_INT_LIMIT = 1 << 30
SHIFT_MAX = 31                  # a viper shift amount every architecture takes as Python does


def viper_functions(path: Path, module: str) -> dict:
    """{code object: name} of the functions marked `@viper` in one device module's source, its
    classes' methods among them (module.Class.method)."""
    mod = importlib.import_module(module)
    out = {}
    for node in ast.parse(path.read_text()).body:
        scopes = [(mod, module, node)]
        if isinstance(node, ast.ClassDef):
            cls = getattr(mod, node.name)
            scopes = [(cls, f"{module}.{node.name}", n) for n in node.body]
        for owner, prefix, fn in scopes:
            if isinstance(fn, ast.FunctionDef) and any(
                    isinstance(d, ast.Name) and d.id == "viper" for d in fn.decorator_list):
                out[getattr(owner, fn.name).__code__] = f"{prefix}.{fn.name}"
    return out


_DEVICE_VIPER: dict = {}


def device_viper_functions() -> dict:
    """viper_functions of every module of the device package (found by walking it)."""
    if not _DEVICE_VIPER:
        for path in sorted(DEVICE_PACKAGE.rglob("*.py")):
            rel = path.relative_to(DEVICE_PACKAGE.parent).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            _DEVICE_VIPER.update(viper_functions(path, ".".join(parts)))
    return _DEVICE_VIPER


class Tracer:
    def __init__(self, viper: dict | None = None):
        self.max_abs = 0
        self.ops = 0
        self.big = 0
        # shifts inside viper functions: {(function, line): [min amount, max amount, count]}
        self.viper = device_viper_functions() if viper is None else viper
        self.shifts: dict = {}

    def see(self, v: int) -> None:
        self.ops += 1
        a = -v if v < 0 else v
        if a > self.max_abs:
            self.max_abs = a
        if a >= SMALL_INT_LIMIT:
            self.big += 1

    def see_shift(self, amount: int, frame) -> None:
        name = self.viper.get(frame.f_code)
        if name is None:          # bytecode (not viper): Python's shift on every port
            return
        key = (name, frame.f_lineno)
        r = self.shifts.get(key)
        if r is None:
            self.shifts[key] = [amount, amount, 1]
        else:
            r[0] = min(r[0], amount)
            r[1] = max(r[1], amount)
            r[2] += 1

    def wild_shifts(self) -> list[str]:
        """The viper shift sites whose amount left 0..SHIFT_MAX, as 'function line N: lo..hi'."""
        return [f"{name} line {line}: {lo}..{hi}"
                for (name, line), (lo, hi, _) in sorted(self.shifts.items())
                if lo < 0 or hi > SHIFT_MAX]


def traced(tracer: Tracer):
    """A TracedInt class bound to one tracer."""

    class TracedInt(int):
        def _wrap(self, v):
            if isinstance(v, bool) or not isinstance(v, int):
                return v
            tracer.see(int(v))
            return TracedInt(v)

    def binop(name):
        base = getattr(int, name)
        shift = name in ("__lshift__", "__rshift__")
        rshift = name in ("__rlshift__", "__rrshift__")

        def f(self, other):
            if shift and isinstance(other, int):       # self << other: the amount is other
                tracer.see_shift(int(other), sys._getframe(1))
            elif rshift:                                # other << self
                tracer.see_shift(int(self), sys._getframe(1))
            r = base(int(self), int(other) if isinstance(other, int) else other)
            return self._wrap(r) if r is not NotImplemented else r
        return f

    for n in ("__add__", "__radd__", "__sub__", "__rsub__", "__mul__", "__rmul__",
              "__floordiv__", "__rfloordiv__", "__mod__", "__rmod__", "__lshift__",
              "__rlshift__", "__rshift__", "__rrshift__", "__and__", "__rand__", "__or__", "__ror__"):
        setattr(TracedInt, n, binop(n))
    TracedInt.__neg__ = lambda self: self._wrap(-int(self))
    TracedInt.__abs__ = lambda self: self._wrap(abs(int(self)))
    return TracedInt


class TracedArray(list):
    """A list standing for an int32 array (viper's ptr32 on a board): what is stored is traced."""

    def __init__(self, T, n):
        super().__init__(T(0) for _ in range(n))
        self.T = T

    def __setitem__(self, i, v):
        super().__setitem__(i, self.T(v))


def traced_optimiser(T, n, alphas=None):
    """The paper profile's Optimiser for n points with its int32 arrays as TracedArrays, so that
    its viper functions' values are traced too: run it inside `with viper_casts():`."""
    from acal.paper.optimiser import Optimiser
    o = Optimiser(n)
    for name in ("u", "f", "pa", "alpha", "cache"):
        setattr(o, name, TracedArray(T, len(getattr(o, name))))
    o.set_rates(*(alphas or (fixed.ALPHA_SCALE, fixed.ALPHA_MISALIGN, fixed.ALPHA_OFFSET)))
    return o


# the device modules whose viper functions cast with int() (acal/core/emit.py)
VIPER_MODULES = ("paper.objective", "core.normal_sums", "core.gaussnewton", "core.model",
                 "core.effects", "core.solve", "core.calibration")


class viper_casts:
    """Viper's int() cast as the identity in the device's viper modules, so that a traced int
    passes it."""

    def __enter__(self):
        import importlib
        for m in VIPER_MODULES:
            importlib.import_module("acal." + m).int = lambda v: v

    def __exit__(self, *exc):
        import importlib
        for m in VIPER_MODULES:
            del importlib.import_module("acal." + m).int


class Int32s(list):
    """A list of traced ints handed over where the device passes an int32 array (the fits copy
    a plain list into an array, which would drop the tracing)."""


# GaussNewton's int32 arrays (viper's ptr32 on a board), all traced by traced_gauss_newton
GAUSS_NEWTON_ARRAYS = ("aux", "d", "a", "b", "bl", "u", "p", "pt", "sh", "grown", "r", "rt", "srt",
                       "rhs", "w", "z", "q")


def traced_gauss_newton(T, n, kinds=()):
    """The default profile's GaussNewton for n points with its int32 arrays as traced lists:
    run it inside `with viper_casts():` on Int32s of traced points (and conditions)."""
    from acal.core.gaussnewton import GaussNewton
    gn = GaussNewton(n, kinds)
    for name in GAUSS_NEWTON_ARRAYS:
        setattr(gn, name, [T(0)] * len(getattr(gn, name)))
    gn.ts = T(0)
    return gn
