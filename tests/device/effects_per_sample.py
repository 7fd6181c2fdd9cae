"""The apply's effects one sample at a time: what the block's viper loop
(acal/core/calibration.py _apply_composed) does to each reading, written as plain per-sample
code from the device's own block_terms, for the tests that hold the apply's forms to the float
model and to the real MicroPython (test_effects.py runs this file's text there too).  Tests'
alone: a board applies whole blocks and keeps no copy of it."""
from acal.core.effects import FORM_OFFSET, FORM_SCALE, block_terms


def apply_terms(t, at, w, x, y, z, e=0):
    """One effect's form and terms t[at:at+4] (block_terms) applied to the reading w (list of 3,
    Q(14 - e) g), x y z the sample (Q10 g)."""
    form = t[at]
    for i in range(3):
        a = t[at + 1 + i]
        if form == FORM_OFFSET:
            w[i] -= a
        elif form == FORM_SCALE:
            w[i] -= (a * w[i]) >> 18
        else:
            s = x if i == 0 else (y if i == 1 else z)
            w[i] -= (a * ((s * s) >> (10 + e))) >> 14


def correct_sample(kind, k, m, w, x, y, z, d, ts=0, e=0):
    """Remove effect `kind` (per-sample parameters k[m:m+3]) from the sample x, y, z (Q10 g,
    within the full scale), accumulating into w (list of 3, Q(14 - e) g at the full scale's
    shift e (fixed.py), holding x y z << (4 - e) or an earlier effect's result), at the relative
    conditions d (block_terms); ts: a step's time (as dt).  block_terms then apply_terms."""
    t = [0, 0, 0, 0]
    block_terms(kind, k, m, t, 0, d, ts, e)
    apply_terms(t, 0, w, x, y, z, e)
