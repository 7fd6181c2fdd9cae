"""CSV rows of fixed-decimal numbers, formatted by numpy: the bytes np.savetxt writes with
fmt="%.<d>f" per column, delimiter "," and newline "\\n", without a Python call per value.

np.savetxt formats each row with Python's %-operator (correctly rounded: the exact binary value,
ties to even): on the 14-day 100 Hz simulated recording (121 M rows) that was ~19 min.  Here each
value is scaled by 10^d and rounded in floats; where that rounding could differ from the exact
one (the scaled value within its own rounding error of a half, or too large for the float's 53
bits, or not finite) the row is formatted by Python as np.savetxt does.  So every byte is
np.savetxt's (tests/files/test_csvtext.py)."""
from __future__ import annotations

import numpy as np

BLOCK_ROWS = 1 << 20        # rows formatted at once: a few tens of MB of characters
EXACT = float(2 ** 50)      # beyond: the float product's error may reach a whole unit


def _hard(scaled: np.ndarray) -> np.ndarray:
    """Where rounding the float product may differ from rounding the exact value: within the
    product's own error (relative 2^-53, taken as 2^-50) of a half, too large, or not finite."""
    with np.errstate(invalid="ignore", over="ignore"):
        return ~np.isfinite(scaled) | (scaled >= EXACT) | \
            (np.abs(scaled - np.floor(scaled) - 0.5) <= scaled * 2.0 ** -50 + 2.0 ** -60)


def _field(v: np.ndarray, d: int) -> np.ndarray:
    """The values' text right-aligned in (n, width) uint8, 0 where nothing is written."""
    scaled = np.abs(v) * float(10 ** d)
    k = np.rint(scaled).astype(np.int64)
    top = int(k.max()) if len(k) else 0
    n_digits = max(len(str(top)), d + 1)
    point = 1 if d else 0
    width = 1 + n_digits + point                   # sign, digits, point
    out = np.zeros((len(v), width), dtype=np.uint8)
    shown = np.full(len(v), d + 1)                 # digits written: the fraction's and the units'
    rest = k.copy()
    for j in range(n_digits):
        col = width - 1 - j - (point if j >= d else 0)
        digit = (rest % 10).astype(np.uint8) + ord("0")
        if j <= d:
            out[:, col] = digit
        else:
            on = k >= 10 ** j
            shown += on
            out[:, col] = np.where(on, digit, 0)
        rest //= 10
    if d:
        out[:, width - 1 - d] = ord(".")
    neg = np.flatnonzero(np.signbit(v))
    out[neg, width - 1 - shown[neg] - point] = ord("-")
    return out


def _bulk(columns, decimals) -> np.ndarray:
    """The rows (no hard value among them) as one uint8 array of characters."""
    parts = []
    for i, (v, d) in enumerate(zip(columns, decimals)):
        parts.append(_field(v, d))
        sep = np.full((len(v), 1), ord("," if i < len(columns) - 1 else "\n"), dtype=np.uint8)
        parts.append(sep)
    m = np.hstack(parts).ravel()
    return m[m != 0]


def fixed_rows(columns, decimals) -> bytes:
    """The rows of columns (equal-length float arrays) as np.savetxt(fh, np.column_stack(columns),
    delimiter=",", fmt=["%.{d}f" for d in decimals]) writes them, as bytes."""
    columns = [np.asarray(c, dtype=np.float64) for c in columns]
    n = len(columns[0]) if columns else 0
    fmt = ",".join(f"%.{d}f" for d in decimals) + "\n"
    out = []
    for a in range(0, n, BLOCK_ROWS):
        block = [c[a:a + BLOCK_ROWS] for c in columns]
        hard = np.zeros(len(block[0]), dtype=bool)
        for v, d in zip(block, decimals):
            with np.errstate(over="ignore"):
                hard |= _hard(np.abs(v) * float(10 ** d))
        prev = 0
        for i in np.flatnonzero(hard):
            if i > prev:
                out.append(_bulk([c[prev:i] for c in block], decimals).tobytes())
            out.append((fmt % tuple(c[i] for c in block)).encode())
            prev = i + 1
        if prev < len(block[0]):
            out.append(_bulk([c[prev:] for c in block], decimals).tobytes())
    return b"".join(out)
