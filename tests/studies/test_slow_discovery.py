"""`make bench` (slow): the naming rule over more seeds, every catalogue effect and clean data.
Each recording: 3 days at 10 Hz; diagnose must name exactly the hidden effect (or nothing)."""
import json
import subprocess
import sys

import pytest

from conftest import run_cli

SEEDS = (41, 42, 43, 44)
CASES = (None, "temp_offset", "temp_scale", "drift", "nonlinear")


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_rule_names_exactly_the_hidden_effect(seed, tmp_path):
    procs = {}
    for e in CASES:
        path = tmp_path / f"{e or 'clean'}.csv"
        args = ["simulate", "wrist", "--days", "3", "--rate", "10", "--seed", str(seed), "-o", str(path)]
        if e:
            args += ["--effect", e]
        procs[e] = (path, subprocess.Popen([sys.executable, "-m", "accelcal.cli", *args],
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    named = {}
    for e, (path, pr) in procs.items():
        assert pr.wait() == 0
        r = run_cli("diagnose", path, "--json")
        assert r.returncode == 0, r.stderr
        out = json.loads(r.stdout)
        named[e] = out["missing_effect"]
        print(seed, e, out["missing_effect"], round(out["heldout_error_mg"], 2),
              [(c["effect"], round(c["improvement_pct"], 1)) for c in out["candidates"]])
    assert named == {e: e for e in CASES}
