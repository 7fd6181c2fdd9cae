# The two profiles of the one device pipeline (docs/method-and-formats.md "Profiles"): named
# settings, not two
# implementations.
#
#   PAPER  Farago 2024 to the letter: rest when max - min of x stays below 0.12 g, 2 points per
#          subset (18), the paper's gradient descent for 50 iterations.  Table 2, Table 3 and
#          the comparisons run it.
#   WEAR   the default, for real wear: rest judged on all three axes against a threshold derived
#          from the sensor's noise measured on the device (rest.NoiseGauge), 8 points per subset
#          (72), a Gauss-Newton fit run to the optimum of its points, integer outlier rejection
#          (gaussnewton.py), and readiness from coverage (bins.py) rather than nine full
#          subsets; a composed model 14 per subset (126).
# Composed models (effects.py) keep their spread rules (bins.py) in both.
from acal.core.rest import ALL_AXES, AUTO, DEFAULT_THRESHOLD

PAPER = 0
WEAR = 1
NAMES = ("paper", "wear")
DEFAULT = WEAR

GRADIENT = 0   # fit: the paper's gradient descent (optimiser.py)
NEWTON = 1     # fit: Gauss-Newton with outlier rejection (gaussnewton.py)

COMPOSED_MAX_COUNT = 4  # paper profile, composed model: 4 per subset (36), spread in T and t
WEAR_MAX_COUNT = 8
WEAR_COMPOSED_MAX_COUNT = 14
# Why 8 per subset (72 points): the outlier test needs enough points that one bad one is a
# minority in its neighbourhood (18 cannot outvote a point); RAM is ~5 kB of list slots at 72
# points; a Gauss-Newton step costs 10 residuals per point, ~0.2 s on an RP2040 at 72 points,
# sliced (docs/method-and-formats.md "Sliced fit").  More points than the bins' 0.1 g spacing lets
# a band hold
# would sit unused.
# Why 14 for a composed model (126 points, the most under gaussnewton.MAX_POINTS = 128, the
# bound its sums are proven for): each effect's points are spread in their condition as well,
# and on the held-out wrist benchmark 72 of them left the fit of a single seed up to 1.34x the
# true model's error where least squares on every rest point was within 1.2x (temperature
# gain and curve on seed 4, drift); 126 bring every effect's seeds 1-6 within 1.25x but one
# (docs/model-discovery.md "Points for a composed model").  Cost on an RP2040: ~7.5 kB more
# heap for the four-effect App, a longer fit (more slices of the same size).
# A board that discovers its effect (acal/discover/search.py) starts with the base model's 8 and takes
# the composed model's 14 when it adopts one (adopted_max_count, Pipeline.adopt).


def settings(profile, composed=False):
    """A profile's pipeline settings: axis, threshold (Q10 g or rest.AUTO), min_count,
    max_count, fit (GRADIENT / NEWTON); composed: for a composed model."""
    if profile == PAPER:
        return {"axis": 0, "threshold": DEFAULT_THRESHOLD, "min_count": 2,
                "max_count": COMPOSED_MAX_COUNT if composed else 2, "fit": GRADIENT}
    if profile == WEAR:
        return {"axis": ALL_AXES, "threshold": AUTO, "min_count": 2,
                "max_count": WEAR_COMPOSED_MAX_COUNT if composed else WEAR_MAX_COUNT,
                "fit": NEWTON}
    raise ValueError("profile must be PAPER or WEAR")


def parse(name):
    """'paper' or 'wear' -> the profile id; ValueError otherwise."""
    for i in range(len(NAMES)):
        if NAMES[i] == name:
            return i
    raise ValueError("a profile is paper or wear: " + name)


def adopted_max_count(fit, max_count):
    """Points per subset a discovering board's bins take once it adopts an effect
    (Pipeline.adopt): with the wear profile's fit (NEWTON) the composed model's,
    WEAR_COMPOSED_MAX_COUNT, as a board booted with that model holds, or max_count when that is
    more; the paper profile's fit (GRADIENT, which never discovers) keeps max_count.  From the
    fit and the count alone, which a BOOT record holds, so that a replay adopts as the board did."""
    if fit == NEWTON and max_count < WEAR_COMPOSED_MAX_COUNT:
        return WEAR_COMPOSED_MAX_COUNT
    return max_count
