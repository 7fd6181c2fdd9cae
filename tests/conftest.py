import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def run_cli(*args, cwd=None):
    """Run the installed CLI as a user does; returns CompletedProcess."""
    return subprocess.run([sys.executable, "-m", "accelcal.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd)
