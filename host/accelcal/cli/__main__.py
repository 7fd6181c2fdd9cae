"""`python -m accelcal.cli ARGS`: the same as the `accelcal` command."""
import sys

from accelcal.cli import main

sys.exit(main())
