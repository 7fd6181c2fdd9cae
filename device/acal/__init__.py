# acal: accelerometer self-calibration on the device (integer-only MicroPython / CircuitPython).
# The one version number of the project: the host package's (pyproject.toml reads it) and mip's
# (package.json; tests/test_layout.py holds them equal).
__version__ = "0.5.0"
