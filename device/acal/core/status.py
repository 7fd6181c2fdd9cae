# The fits' status codes, shared by the paper's gradient descent (acal/paper/optimiser.py), the default
# profile's Gauss-Newton (acal/core/gaussnewton.py), the pipeline and the app's log.  Failure is
# reported, never returned as parameters.
OK = 0
DIVERGED = 1        # a parameter left the fit region, or the objective ended above its start
#                     (or a point lay past +-16 g, outside the exact objective's domain)
TOO_FEW = 2         # fewer points than parameters
OUT_OF_BOUNDS = 3   # converged outside the calibration bounds (fixed.py): not a sensor we trust
UNDETERMINED = 4    # the points do not pin every parameter (acal/core/gaussnewton.py)
# A composed model's fit that failed, or ended worse than the base fit of the same points (by
# mean squared residual over the points each kept): the base calibration is kept, with the
# effects at zero (acal/core/pipeline.py, the wear profile).
BASE_KEPT_FAILED = 5
BASE_KEPT_WORSE = 6
STATUS_NAMES = ("ok", "diverged", "too few points", "out of calibration bounds",
                "parameters not determined by the points",
                "composed fit failed: base calibration kept",
                "composed fit worse than the base fit: base calibration kept")


def usable(status):
    """True when the fit's parameters may be applied (OK, or a base calibration kept)."""
    return status == OK or status == BASE_KEPT_FAILED or status == BASE_KEPT_WORSE
