"""The peers' calibrations of real recordings, split as the tests split them (issue 50 part 6):
for `make bench`, and the data tests/pipeline/test_real_halves.py scores.

For each recording given: its rest points (accelcal.pipeline.restpoints.rest_points, those
`calibrate` keeps), each split of compare's (`--split blocks`, `first-half`, `second-half`:
restpoints.split) that both halves cover, and for each split the samples of the training part
(its time half, or its blocks) handed to scikit-digital-health's CalibrateAccelerometer and
actipy's calibrate_gravity, each in its own process in .venv-bench
(accelcal.studies.bench_others fit).  What each peer fitted (its own parameters and its map read
back from its calibrated samples: per axis c0 + c1 v + c2 T + c3 v T) or that it declined and why
is written as JSON, with the peers' versions, the split's cut and its rest-point counts, so that
a test can score the maps on the same held-out rest points as the default without the peers
installed.  Each split's held-out errors (before, the default, float lsq on every training
point, each peer that fitted) are printed and kept in the JSON (held_out_mg) for the record.  Each recording's whole file too (in-sample; for minutes-long files, whose halves
cannot cover, the only question is whether the peers fit at all).  A file accelcal's reader
refuses is recorded as refused, with no peer run (they are handed accelcal's samples).

    python -m accelcal.studies.peers_real FILE... [--others PYTHON] [--out tests/data/real/peers.json]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from accelcal.errors import InputError
from accelcal.files.recordings import read_whole
from accelcal.locations import checkout
from accelcal.pipeline.restpoints import SPLITS, rest_points, split, usable

ROOT = checkout() or Path.cwd()
TOOLS = ("skdh", "skdh_lifted", "actipy")


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def training_mask(p, halves, rule: str, t: np.ndarray) -> tuple[np.ndarray, dict]:
    """The samples (times t) of the split's training part, and how it was cut: a time half is
    every sample on its side of the rest points' middle; blocks are the SPLITS entry (length,
    offset, parity) that gives the training rest points restpoints.block_split chose."""
    t0, span = float(p.t.min()), float(p.t.max() - p.t.min())
    if rule != "blocks":
        cut = t0 + span / 2
        first = rule == "first-half"
        return (t < cut) if first else (t >= cut), {"cut_s_from_first_point": span / 2}
    train_t = set(np.round(halves[0].t, 6))
    for length, offset, parity in SPLITS:
        block = ((p.t - t0 + offset) // length).astype(int)
        if set(np.round(p.t[block % 2 == parity], 6)) == train_t:
            blk = np.floor((t - t0 + offset) / length).astype(int)
            return blk % 2 == parity, {"block_s": length, "offset_s": offset, "parity": parity}
    raise AssertionError("block split not among SPLITS")


def error_mg(a: np.ndarray) -> float:
    return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)) * 1e3)


def peer_on(fit: dict, p) -> np.ndarray:
    """A peer's read-back map (per axis c0 + c1 v + c2 T + c3 v T) on rest points p."""
    c = np.asarray(fit["map"])
    T = (p.temp if p.temp is not None else np.zeros(len(p)))[:, None]
    return c[:, 0] + c[:, 1] * p.v + c[:, 2] * T + c[:, 3] * p.v * T


def default_on(train, test, folder: Path) -> tuple[str, float]:
    """The default calibration (accelcal.calibrate, no model: auto) of the training rest points
    written as a points file, its model and its held-out error (mg) with its own correction."""
    import accelcal
    from accelcal.model.effects import ModelSpec
    path = folder / "train.csv"
    cols = [train.v] + ([train.temp] if train.temp is not None else []) + [train.t]
    head = "x,y,z," + ("temp," if train.temp is not None else "") + "t"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=head, comments="", fmt="%.9g")
    rec = accelcal.calibrate(str(path))
    if not rec.ok:
        return rec["status"], float("nan")
    a = ModelSpec.parse(rec["model"]).correct(np.array(list(rec["params"].values())), test.v,
                                              test.temp, test.t, rec["reference"], test.cols)
    return rec["model"], error_mg(a)


def scores(halves, fits: dict, folder: Path) -> dict:
    """Held-out errors (mg) on the split's held-out rest points: before, the default, float lsq
    on every training point, and each peer that fitted (tests/pipeline/test_real_halves.py
    computes the same from the shipped points; printed by make bench, kept for the record)."""
    from accelcal import methods
    train, test = halves[0], halves[1]
    model, default = default_on(train, test, folder)
    out = {"before": methods.calibration_error_mg(None, test.v), "default_model": model,
           "lsq_all": methods.calibration_error_mg(methods.METHODS["lsq"](train.v), test.v)}
    if default == default:   # not nan: the default calibrated (else its status is the model)
        out["default"] = default
    out.update({tool: error_mg(peer_on(f, test)) for tool, f in fits.items() if f["fitted"]})
    return out


def run_peer(python: str, tool: str, npz: Path) -> dict:
    r = subprocess.run([python, "-m", "accelcal.studies.bench_others", "fit", tool, str(npz)],
                       capture_output=True, text=True)
    if r.returncode:
        last = (r.stderr.strip().splitlines() or ["?"])[-1]
        return {"tool": tool, "fitted": False, "reason": f"crashed: {last}"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def peers_on(python: str, t, xyz, temp, sel, folder: Path) -> dict:
    npz = folder / "part.npz"
    arrays = {"t": t[sel], "acc": xyz[sel]}
    if temp is not None:
        arrays["temp"] = temp[sel]
    np.savez(npz, **arrays)
    out = {tool: run_peer(python, tool, npz) for tool in TOOLS}
    npz.unlink()
    return out


def one_file(path: Path, python: str, folder: Path) -> dict:
    rec = {"file": path.name, "sha256": sha256(path), "bytes": path.stat().st_size, "splits": {}}
    try:
        p = usable(rest_points(str(path), 5, 0, 3))
    except InputError as e:
        p, rec["rest_points"] = None, str(e)
    try:
        t, xyz, temp, _ = read_whole(path)
    except InputError as e:   # refused by accelcal's reader: the peers get no samples from it
        rec["refused"] = str(e)
        return rec
    rec["hours"] = float((t[-1] - t[0]) / 3600)
    for rule in ("blocks", "first-half", "second-half"):
        if p is None:
            break
        try:
            halves = split(p, rule)
        except InputError as e:
            rec["splits"][rule] = {"no_split": str(e)}
            continue
        sel, how = training_mask(p, halves, rule, t)
        fits = peers_on(python, t, xyz, temp, sel, folder)
        held = scores(halves, fits, folder)
        rec["splits"][rule] = {"how": halves.how, **how, "points": len(p),
                               "train_points": len(halves[0]), "held_out_points": len(halves[1]),
                               "train_samples": int(sel.sum()), **fits, "held_out_mg": held}
        print(f"{path.name} {rule} held out (mg): " + ", ".join(
            f"{k} {held[k]:.2f}" if k in held else f"{k} declined" for k in
            ("before", "default", "lsq_all", *TOOLS)) + f" [default: {held['default_model']}]")
    rec["whole_file"] = peers_on(python, t, xyz, temp, np.ones(len(t), bool), folder)
    return rec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m accelcal.studies.peers_real")
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--others", metavar="PYTHON", default=str(ROOT / ".venv-bench" / "bin" / "python"),
                    help="interpreter with scikit-digital-health and actipy (make .venv-bench)")
    ap.add_argument("--out", type=Path, default=ROOT / "tests" / "data" / "real" / "peers.json")
    a = ap.parse_args(argv)
    bad = [f"{f}: no such file" for f in a.files if not f.is_file()]
    if not Path(a.others).is_file():
        bad.append(f"{a.others}: no such interpreter (make .venv-bench/.installed, or --others)")
    if bad:
        print(f"peers_real: {bad[0]}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        files = [one_file(f, a.others, Path(tmp)) for f in a.files]
    versions = json.loads(subprocess.run([a.others, "-m", "accelcal.studies.bench_others",
                                          "versions"], capture_output=True, text=True,
                                         check=True).stdout)
    data = {"tool": "python -m accelcal.studies.peers_real (make bench)", "versions": versions,
            "files": files}
    tmp_out = a.out.with_suffix(".json.part")
    tmp_out.write_text(json.dumps(data, indent=1) + "\n")
    tmp_out.replace(a.out)
    print(f"wrote {a.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
