"""The one thing pyproject.toml does not say in a stable form: the CSV reader's fast path, a C
extension (host/accelcal/files/_csvfast.c), optional so that an install without a C compiler still
succeeds and the reader uses Arrow alone (host/accelcal/files/csvpieces.py)."""
from setuptools import Extension, setup

setup(ext_modules=[Extension("accelcal.files._csvfast", ["host/accelcal/files/_csvfast.c"],
                             optional=True)])
