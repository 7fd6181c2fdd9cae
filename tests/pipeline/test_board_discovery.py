"""The board's own discovery (`calibrate FILE --discover`, device/acal/discover/search.py) beside the
host's `diagnose` on simulated wear, behind `slow`: every catalogue effect x seeds, the share of
recordings where the board names what diagnose names (goal >= 90 %), the board's false names
on 10 clean seeds, and its held-out error after within 1.5x the true sensor model's on the same
held-out points.  (The default suite's cases: tests/pipeline/test_diagnose.py.)"""
import numpy as np
import pytest

from accelcal.bridge.runtime import Config
from accelcal.pipeline.diagnose import diagnose
from accelcal.pipeline.job import calibrate
from conftest import simulate_wrists, true_corrected

DAYS, RATE = 3, 10
DISCOVER = Config.for_profile("wear", discover=True)


def board_names(path):
    """The board's named effect (None: none) and its discovery record."""
    d = calibrate(str(path), cfg=DISCOVER)["discovery"]
    return d["effect"], d


def true_board_heldout_mg(path, d) -> float:
    """The simulation's true sensor model scored as the board scores a model (score.py): on
    the board's held-out points and their conditions, each point's | |a|^2 - 1 | weighted by
    the rest means it stands for, as mg (heldout_mg's |a|^2 - 1 ~ 2 (|a| - 1))."""
    hs = d["heldout_set"]
    a = true_corrected(path, hs["xyz_g"], np.array(hs["temp"]), np.array(hs["time"]),
                       {"supply_mv": np.array(hs["supply"])})
    r = np.abs(np.sum(a * a, axis=1) - 1) / 2
    return float(np.average(r, weights=hs["weight"]) * 1e3)


EFFECTS = ("temp_offset", "temp_scale", "drift", "nonlinear", "temp_offset2", "step",
           "supply_offset")
SEEDS = (51, 52, 53)
CLEAN_SEEDS = tuple(range(61, 71))


def study_rows(folder, cases) -> list:
    """Per case (name, seed, hidden effects), simulated two at a time and deleted after use (3
    days at 10 Hz are 94 MB each): (name_seed, diagnose's effect, the board's, its closest,
    blocks better, blocks, held-out error before, after, the true model's on the same points),
    printed as they come.  A step's error is its placed time's, leave-one-out
    (acal/discover/stepplace.py): the honest figure for a time the held-out points placed."""
    rows = []
    for k in range(0, len(cases), 2):
        pair = {f"{n}_{s}": (s, eff) for n, s, eff in cases[k:k + 2]}
        paths = simulate_wrists(folder, pair, DAYS, RATE)
        for key, path in paths.items():
            host = diagnose(str(path))["missing_effect"]
            named, d = board_names(path)
            after = d["heldout_error_after_mg"] if named else d["heldout_error_before_mg"]
            rows.append((key, host, named, d.get("closest"), d.get("blocks_better"), d.get("blocks"),
                         d.get("heldout_error_before_mg"), after, true_board_heldout_mg(path, d)))
            print(*rows[-1], d.get("step_time_fitted_s"), d.get("step_time_s"), flush=True)
            path.unlink()
            path.with_suffix(".truth.json").unlink()
    return rows


@pytest.mark.slow
def test_study_agreement_with_diagnose_and_false_names(tmp_path):
    """Each catalogue effect x SEEDS and 10 clean seeds: prints each case and the shares."""
    cases = [(e, s, (e,)) for e in EFFECTS for s in SEEDS] + [("clean", s, ()) for s in CLEAN_SEEDS]
    rows = study_rows(tmp_path, cases)
    hidden = [r for r in rows if not r[0].startswith("clean")]
    agree = sum(r[1] == r[2] for r in rows)
    right = [r for r in hidden if r[2] == r[0].rsplit("_", 1)[0]]
    false = sum(r[2] is not None for r in rows if r[0].startswith("clean"))
    print(f"board names what diagnose names in {agree} of {len(rows)} recordings "
          f"({100 * agree / len(rows):.0f} %); the hidden effect in {len(right)} of {len(hidden)}; "
          f"false names on {false} of {len(CLEAN_SEEDS)} clean seeds")
    assert false == 0
    assert agree >= 0.9 * len(rows)     # the goal (measured: docs/model-discovery.md)
    assert_within_true(right + rows[len(hidden):])


def assert_within_true(rows):
    """The held-out error after beside the true sensor model's on the same points, where the
    board's model is the true one's form (the hidden effect named, or clean): within 1.5x (the
    step too, its time placed among the held-out points of its gap, scored leave-one-out:
    docs/model-discovery.md "Against the true sensor model")."""
    ratio = {r[0]: r[7] / r[8] for r in rows}
    print("after / true:", " ".join(f"{k} {v:.2f}" for k, v in ratio.items()))
    assert max(ratio.values()) <= 1.5, ratio
