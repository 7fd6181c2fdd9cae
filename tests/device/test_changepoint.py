"""The step's change-point search (acal/core/changepoint.py) in slices: at every slice size (points
read, sort moves, points scanned a step; one step for a whole pass) it finds the same split with
the same score, and its order is the stable sort of the kept points by time (Python's sorted),
with ties in time and points the fit rejected; the smaller the slices, the more steps."""
import numpy as np
import pytest

from acal.core import changepoint
from acal.core.bins import COND
from acal.core.changepoint import ChangePoint


class _Fit:
    """What the search reads of a finished fit: its kept points, their times (aux), and each
    one's residual and direction (point)."""

    def __init__(self, w, r, t, keep):
        n = len(r)
        self.n_given = n
        self.keep = keep
        self.srt = [0] * n
        self.aux = [0] * (COND * n)
        for i in range(n):
            self.aux[COND * i + 1] = t[i]
        self._w, self._r = w, r

    def point(self, i, w):
        for c in range(3):
            w[c] = self._w[i][c]
        return self._r[i]


WHOLE = 1 << 20   # a slice past every pass: each phase in one step


def _search(monkeypatch, fit, read, moves, scan):
    monkeypatch.setattr(changepoint, "READ_SLICE", read)
    monkeypatch.setattr(changepoint, "SORT_MOVES", moves)
    monkeypatch.setattr(changepoint, "SCAN_POINTS", scan)
    cp = ChangePoint()
    cp.begin(fit)
    steps = 1
    while not cp.step():
        steps += 1
    state = (cp.found, cp.ts, cp.at, cp.best_m, cp.best_e, cp.m, list(cp.order[:cp.m]))
    return state, steps


@pytest.mark.parametrize("n", [5, 40, 72, 128])
def test_every_slice_size_finds_the_same_split(monkeypatch, n):
    rng = np.random.default_rng(n)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    t = [int(x) for x in rng.integers(0, n // 3 + 2, n)]          # unsorted, many ties
    step_at = np.array(t) >= np.median(t)
    res = 2 * (d @ np.array([0.004, -0.003, 0.002])) * step_at + rng.normal(scale=2e-4, size=n)
    keep = [int(x) for x in rng.random(n) > 0.1]                   # some rejected by the fit
    fit = _Fit([tuple(int(c) for c in row) for row in np.round(d * (1 << 24))],
               [int(x) for x in np.round(res * (1 << 22))], t, keep)
    whole, whole_steps = _search(monkeypatch, fit, WHOLE, WHOLE, WHOLE)
    kept = [i for i in range(n) if keep[i]]
    assert whole[6] == sorted(kept, key=lambda i: t[i])             # stable: ties keep order
    if n >= 40:
        assert whole[0], whole                                    # the step is there to find
    for read, moves, scan in ((1, 1, 1), (3, 2, 1), (8, 16, 1), (8, 5, 3), (2, 7, 8)):
        got, steps = _search(monkeypatch, fit, read, moves, scan)
        assert got == whole, (read, moves, scan)
        assert steps > whole_steps or n < 8
