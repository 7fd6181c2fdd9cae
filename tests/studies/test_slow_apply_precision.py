"""What the apply's output format costs a still wrist (accelcal.studies.apply_precision, one seed
at +-2 g, ~1 min): the 9-parameter float fit written through the device's apply (Q13 g) scores
the held-out still windows as the same fit in floats on the same Q10 readings does, to 0.02 mg
(the Q10 output it replaced cost ~0.1 mg there: docs/method-and-formats.md "Output format")."""
import tempfile

import pytest

from accelcal.studies.apply_precision import run_case


@pytest.mark.slow
def test_the_device_output_keeps_the_float_fits_held_out_error():
    with tempfile.TemporaryDirectory() as tmp:
        row = run_case((2, 1), tmp)
    assert row["output_q"] == 13 and row["windows"] > 1000
    assert abs(row["device_mg"] - row["float_mg"]) < 0.02, row
