"""files/csvtext.py: the simulator's CSV rows formatted by numpy are np.savetxt's bytes (what
`accelcal simulate wrist` wrote with np.savetxt before), on a simulated recording's own values
and on values chosen to be hard: ties, -0, values that round to zero, large, not finite."""
import io

import numpy as np
from hypothesis import given, settings, strategies as st

from accelcal.files import csvtext
from accelcal.simulate import wearer


def savetxt(columns, decimals) -> bytes:
    fh = io.BytesIO()
    np.savetxt(fh, np.column_stack(columns), delimiter=",", fmt=[f"%.{d}f" for d in decimals])
    return fh.getvalue()


def test_simulated_recording_rows_are_savetxts(tmp_path, monkeypatch):
    # every block the simulator formats (with a supply column: %.0f), checked against np.savetxt
    seen = []

    def both(columns, decimals):
        got = csvtext.fixed_rows(columns, decimals)
        seen.append((len(columns[0]), got == savetxt(columns, decimals)))
        return got
    monkeypatch.setattr(wearer, "fixed_rows", both)
    wearer.simulate_wrist(tmp_path / "w.csv", 0.05, 100, 7, effect=("supply_offset",), range_g=4)
    assert seen and all(same for _, same in seen) and sum(n for n, _ in seen) == 432_000
    head = (tmp_path / "w.csv").read_bytes()[:60].split(b"\n")
    assert head[0] == b"t,x,y,z,temp,supply_mv" and head[1].startswith(b"0.0000,")


def test_hard_values():
    ties = np.array([0.125, 0.375, 2.5, 0.5, 1.5, -0.125, 0.005, 0.015, 1e-300, 5e-324])
    odd = np.array([-0.0, 0.0, -0.0004, -0.0005, 1e15, 1e17, 2.0 ** 60, -1e300, np.nan, np.inf,
                    -np.inf, 999.9995, 9.9999999])
    v = np.concatenate([ties, odd, -ties])
    for d in (0, 1, 2, 3, 4, 6):
        assert csvtext.fixed_rows([v, v[::-1]], [d, 3]) == savetxt([v, v[::-1]], [d, 3]), d


def test_blocks_and_random_values(monkeypatch):
    monkeypatch.setattr(csvtext, "BLOCK_ROWS", 1000)
    rng = np.random.default_rng(3)
    cols = [np.arange(5000) / 100.0, rng.normal(0, 3, 5000), np.rint(rng.normal(0, 1, 5000) * 1e3) / 1e3,
            rng.uniform(-50, 150, 5000)]
    cols[1][::7] = np.rint(cols[1][::7] * 2000) / 2000    # halves of the last digit: ties
    assert csvtext.fixed_rows(cols, [4, 3, 3, 2]) == savetxt(cols, [4, 3, 3, 2])
    assert csvtext.fixed_rows([np.zeros(0)], [3]) == b""


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1, max_size=40),
       st.integers(0, 8))
def test_any_float(values, d):
    v = np.array(values)
    assert csvtext.fixed_rows([v], [d]) == savetxt([v], [d])
