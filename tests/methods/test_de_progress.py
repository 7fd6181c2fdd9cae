"""compare's slow method tells its progress with an estimate (issue 51): de says its size, then
after FIRST_ESTIMATE generations the time each took and so the time left at most; the search
itself is the same with or without being watched."""
import numpy as np

from accelcal import methods, simulate
from accelcal.bridge.runtime import Config
from accelcal.methods import global_search as gs
from accelcal.pipeline.compare import fit_method


def test_de_estimates_its_time_and_finds_the_same(monkeypatch, rng):
    monkeypatch.setattr(gs, "MAXITER", 60)           # the search cut short: the same rules
    monkeypatch.setattr(gs, "REPORT_S", 1e9)         # the first estimate only
    v = simulate.unit_points(rng, 30) * 1.02 + 0.01 + rng.normal(0, 0.001, (30, 3))
    said = []
    watched = methods.METHODS["de"](v, progress=said.append)
    assert np.array_equal(watched, methods.METHODS["de"](v))
    assert len(said) == 2 and "30 points, up to 60 generations of 180 members" in said[0]
    head, tail = said[1].split(" ms each): at most ~")
    per_ms = float(head.rsplit("(", 1)[1])
    assert f"generation {gs.FIRST_ESTIMATE} of at most 60" in said[1]
    left_s = float(tail.split()[0])   # printed to the second, from the time printed to 0.1 ms
    assert abs(left_s - per_ms * (60 - gs.FIRST_ESTIMATE) / 1e3) <= 0.5 + 0.05 * 40 / 1e3


def test_compare_hands_its_progress_to_de(monkeypatch, rng):
    monkeypatch.setattr(gs, "MAXITER", 30)
    v = simulate.unit_points(rng, 40)
    said = []
    p, secs, why = fit_method("de", v, Config(), "cpython", said.append)
    assert why is None and secs > 0 and any("de: generation 20 of at most 30" in m for m in said)
