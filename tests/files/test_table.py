"""files/table.py's median: np.median's value to the bit, without importing numpy.ma."""
import subprocess
import sys

import numpy as np
from hypothesis import given, settings, strategies as st

from accelcal.files.table import median


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-1e300, 1e300, width=64), min_size=1, max_size=60))
def test_median_is_numpys(values):
    v = np.array(values)
    assert median(v) == float(np.median(v))
    steps = np.diff(np.cumsum(np.abs(v)) / 100.0)       # time steps, as the readers take them
    if len(steps) and np.isfinite(steps).all():
        assert median(steps) == float(np.median(steps))


def test_median_loads_no_numpy_ma():
    code = ("import sys, numpy as np\nfrom accelcal.files.table import median\n"
            "median(np.arange(10.0)); median(np.arange(11.0))\nprint('numpy.ma' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "False", out.stderr
