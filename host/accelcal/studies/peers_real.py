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
installed.  Each recording's whole file too (in-sample; for minutes-long files, whose halves
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
        rec["splits"][rule] = {"how": halves.how, **how, "points": len(p),
                               "train_points": len(halves[0]), "held_out_points": len(halves[1]),
                               "train_samples": int(sel.sum()),
                               **peers_on(python, t, xyz, temp, sel, folder)}
        print(f"{path.name} {rule}: " + ", ".join(
            f"{k} {'fitted' if rec['splits'][rule][k]['fitted'] else 'declined'}" for k in TOOLS),
              file=sys.stderr)
    rec["whole_file"] = peers_on(python, t, xyz, temp, np.ones(len(t), bool), folder)
    return rec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m accelcal.studies.peers_real")
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--others", metavar="PYTHON", default=str(ROOT / ".venv-bench" / "bin" / "python"),
                    help="interpreter with scikit-digital-health and actipy (make .venv-bench)")
    ap.add_argument("--out", type=Path, default=ROOT / "tests" / "data" / "real" / "peers.json")
    a = ap.parse_args(argv)
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
