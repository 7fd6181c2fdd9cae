"""Simulated data with known truth: the paper's scenarios (scenarios.py, eqs. 17-20), days of wrist
wear with hidden effects (wearer.py), the stimulus file a simulated chip replays (stimulus.py), and
the simulated LIS3DH, clock and I2C bus that run under MicroPython beside the device code (chip/,
package data, never imported by the host).

The paper's scenario functions are the package's own names, `simulate.uncorrect(...)`, as they
are what most tests and studies draw from."""
from accelcal.simulate.scenarios import noise, paper_scenario, random_params, uncorrect, unit_points

__all__ = ["noise", "paper_scenario", "random_params", "uncorrect", "unit_points"]
