"""Calibration methods of both papers in float64 (numpy/scipy), one module each, all scored with
the same 9-parameter correction (base.py).  The device method is not here: it is the integer
one in device/acal, run through accelcal.bridge.runtime.

| --method  | module                | source |
|-----------|-----------------------|--------|
| lsq       | nonlinear.py          | float optimum (fminunc's role, Farago Table 3); Levenberg-Marquardt as Lukowicz |
| de        | global_search.py      | differential evolution (LabVIEW's global search, Farago Table 3) |
| linauto   | linautocalibration.py | Gietzelt 2013, non-iterative |
| linminvar | linminvarestimate.py  | Lotters 1998, linear minimum-variance estimator |
| campolo   | lsqnonlinear.py       | Campolo 2006, LsqNonLinear with the eq. 4 initial values |
| merayo    | mgncalibration.py     | Merayo 2000, MgnCalibration: full ellipsoid, Cholesky factor |
| minvol    | minvolellipsoid.py    | Bonnet 2009, minimum-volume enclosing ellipsoid (Khachiyan) |
"""
from accelcal.methods.base import (ONE_HEMISPHERE, P0, REGISTRY, FitError, Method,  # noqa: F401
                                   calibration_error_mg,
                                   check_points, correct, coverage_reason, fisher_bound, k_matrix,
                                   one_side_margin,
                                   upper_factor)
from accelcal.methods.float_device import float_device  # noqa: F401
from accelcal.methods.global_search import de  # noqa: F401
from accelcal.methods.linautocalibration import linauto  # noqa: F401
from accelcal.methods.linminvarestimate import linminvar  # noqa: F401
from accelcal.methods.lsqnonlinear import campolo  # noqa: F401
from accelcal.methods.mgncalibration import merayo  # noqa: F401
from accelcal.methods.minvolellipsoid import minvol  # noqa: F401
from accelcal.methods.nonlinear import lsq  # noqa: F401

ORDER = ["lsq", "de", "linauto", "linminvar", "campolo", "merayo", "minvol"]
METHODS: dict[str, Method] = {n: REGISTRY[n] for n in ORDER}
