"""`make demo`: a day of wrist wear on the virtual board, through the real mpremote.

1. simulate a day of wear (10 Hz) and the LIS3DH that sees it (9-parameter errors, noise);
2. start the virtual board (MicroPython unix port on a pty, simulated LIS3DH, virtual time);
3. `accelcal deploy`, `accelcal acquire --hours 24` (capture on), `accelcal pull`;
4. show the calibration the board computed beside the host's replay of the same samples through
   the same device modules under CPython (bit for bit), and beside the simulated truth;
5. walk the model-discovery loop on three days with a hidden effect chosen at random: the base
   fit, diagnose names the effect, and the board's own discovery (the device modules with
   `--discover`) names it too; add it, the held-out error falls to near the noise floor."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from accelcal.bridge import boardlog
from accelcal import methods
from accelcal.board import virtual
from acal.core.fixed import PARAM_NAMES, PARAM_ONE, POINT_ONE_G
from acal.logger import log
from acal.paper import optimiser

DAYS = 1
RATE = 10
SEED = 4


def cli(*args: str, quiet: bool = False, ok=(0, 1)) -> subprocess.CompletedProcess:
    t = time.perf_counter()
    print(f"$ accelcal {' '.join(args)}", flush=True)
    p = subprocess.run([sys.executable, "-m", "accelcal.cli", *args], text=True,
                       stdout=subprocess.PIPE, stderr=subprocess.DEVNULL if quiet else None)
    if p.stdout.strip() and not quiet:
        print("  " + p.stdout.strip().replace("\n", "\n  "))
    print(f"  ({time.perf_counter() - t:.0f} s)", flush=True)
    if p.returncode not in ok:
        raise SystemExit(f"demo: `accelcal {args[0]}` failed")
    return p


def main() -> int:
    work = Path("demo-out").resolve()
    work.mkdir(exist_ok=True)
    for f in ("flash", "pulled"):
        d = work / f
        if d.exists():
            for p in sorted(d.rglob("*"), reverse=True):
                p.unlink() if p.is_file() else p.rmdir()
    print(f"accelcal demo: {DAYS} day of wrist wear at {RATE} Hz on the virtual board (in {work})\n")
    cli("simulate", "wrist", "--days", str(DAYS), "--rate", str(RATE), "--seed", str(SEED),
        "-o", str(work / "wrist.csv"), "--stimulus", str(work / "wrist.bin"),
        "--force")   # the demo's own folder: its last run's files are replaced
    truth = json.loads((work / "wrist.truth.json").read_text())
    # MicroPython's own RPI_PICO firmware has a 245 888 B heap (measured on the emulated RP2040);
    # the virtual board compiles the deployed sources on its heap, which 160 kB no longer held
    with virtual.Running(work / "flash", work / "wrist.bin", "--heap", "240k") as board:
        print(f"virtual board on {board.port} (240 kB heap, an RP2040's MicroPython heap)\n")
        common = ["--port", board.port, "--rate", str(RATE), "--capture-kb", "8192"]
        cli("deploy", *common)
        cli("acquire", "--hours", str(24 * DAYS), *common)
        cli("pull", "--port", board.port, "-o", str(work / "pulled"))
    rep = cli("replay", str(work / "pulled"))
    cli("report", str(work / "pulled"), "--html", str(work / "board.html"), "--force", quiet=True)
    print(f"the board's calibrations over the day: {work / 'board.html'}")

    lg = boardlog.decode(work / "pulled" / "log.bin")
    cals = [c for c in lg.dicts(log.CAL) if optimiser.usable(c["status"])]
    if not cals:
        print("\nthe board did not calibrate in this day (bins not full): see pulled/summary.json")
        return 1
    board_p = np.array([cals[-1][n] for n in PARAM_NAMES]) / PARAM_ONE
    ours = _replayed_params(work / "pulled")
    true_p = np.array([truth["params"][n] for n in PARAM_NAMES])
    rests = np.array([[r["x"], r["y"], r["z"]] for r in lg.dicts(log.REST)]) / POINT_ONE_G
    print(f"\nCalibration {cals[-1]['number']} (sample {cals[-1]['index']}, "
          f"{cals[-1]['index'] / RATE / 3600:.1f} h into the wear), board vs host replay vs truth:\n")
    print(f"{'param':<6}{'board':>11}{'host replay':>13}{'truth':>11}{'board-truth':>13}")
    for i, n in enumerate(PARAM_NAMES):
        print(f"{n:<6}{board_p[i]:11.5f}{ours[i]:13.5f}{true_p[i]:11.5f}{board_p[i] - true_p[i]:13.5f}")
    same = np.array_equal(board_p, ours)
    print(f"\nboard and host replay: {'IDENTICAL, bit for bit' if same else 'DIFFERENT'}")
    print(f"calibration error over the board's {len(rests)} logged rest points (mean | |a| - 1 g |): "
          f"{methods.calibration_error_mg(None, rests):.1f} mg before, "
          f"{methods.calibration_error_mg(board_p, rests):.1f} mg after "
          f"(the truth's own: {methods.calibration_error_mg(true_p, rests):.1f} mg)")
    found = discovery_loop(work)
    print("\nMore: `accelcal board virtual`, `accelcal diagnose --help`, `accelcal --help`, README.")
    return 0 if same and rep.returncode == 0 and found else 1


def _replayed_params(d: Path) -> np.ndarray:
    """The calibration the host's replay of the capture ends with."""
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        proc = boardlog.run_capture(d, Path(tmp) / "log.bin")
    return np.array(proc.params) / PARAM_ONE



# The effects the board fits that one diagnose step names and one calibrate removes (the curved
# temperature response shows as temp_offset first, docs/model-discovery.md "More effects"; the
# supply's recording carries the board's supply_mv column).
ONE_STEP = ("temp_offset", "temp_scale", "drift", "nonlinear", "supply_offset")


def discovery_loop(work: Path, seed: int | None = None) -> bool:
    """The model-discovery loop on a 3-day recording with a hidden effect chosen at random."""
    import random
    seed = random.SystemRandom().randrange(1000, 10000) if seed is None else seed
    hidden = ONE_STEP[seed % len(ONE_STEP)]
    rec = work / "hidden.csv"
    hist = work / "steps.jsonl"
    hist.unlink(missing_ok=True)
    print(f"\n--- Model discovery: 3 days at 10 Hz with one hidden effect (seed {seed}) ---\n")
    cli("simulate", "wrist", "--days", "3", "--rate", "10", "--seed", str(seed), "--effect", hidden,
        "-o", str(rec), "--force", quiet=True)
    out = json.loads(cli("diagnose", str(rec), "--json", "--report", str(work / "report-base"),
                         "--history", str(hist), "--force", quiet=True).stdout)
    print(f"base model: held-out error {out['heldout_error_mg']:.2f} mg, noise floor "
          f"{out['noise_floor_mg']:.2f} mg")
    for c in out["candidates"]:
        print(f"  +{c['effect']:<13} {c['heldout_error_mg']:6.2f} mg  ({c['improvement_pct']:+.1f} %, "
              f"better in {c['blocks_improved_pct']:.0f} % of held-out blocks)")
    named = out["missing_effect"]
    print(f"diagnose names: {named}\n  {out['explanation']}")
    board = board_discovers(rec)
    if not named:
        return False
    model = f"base+{named}"
    lsq = json.loads(cli("calibrate", str(rec), "--model", model, "--method", "lsq", "--points",
                         "all", "--json", quiet=True).stdout)
    dev = cli("calibrate", str(rec), "--model", model, "--json", quiet=True, ok=(0, 2))
    dev = json.loads(dev.stdout) if dev.stdout.strip() else {"status": "failed", "reason": "no output"}
    print(f"{model}: float lsq on all {lsq['points']} rest points {lsq['error_before_mg']:.2f} -> "
          f"{lsq['error_after_mg']:.2f} mg; "
          + (f"the device's integer fit ({dev['profile']} profile, {dev['points']} points, "
             f"{dev['iterations']} Gauss-Newton steps) -> {dev['error_after_mg']:.2f} mg"
             if dev["status"] == "calibrated" else f"the device's fit: {dev['reason']}"))
    if dev["status"] == "calibrated":
        ratio = dev["error_after_mg"] / lsq["error_after_mg"]
        if dev.get("note"):
            print(f"  the device kept its base calibration: {dev['note']}")
        print(f"  device / lsq: {ratio:.2f}" + ("" if ratio <= 1.5 else
              "  -- MORE than 1.5x: the device's points do not show the effect as well as all "
              "rest points do (docs/method-and-formats.md \"Profiles\")"))
    after = json.loads(cli("diagnose", str(rec), "--model", model, "--json", "--history", str(hist),
                           "--report", str(work / "report"), "--force", quiet=True).stdout)
    print(f"with {named}: held-out error {after['heldout_error_mg']:.2f} mg "
          f"(noise floor {after['noise_floor_mg']:.2f} mg); names next: {after['missing_effect'] or 'nothing'}\n")
    cli("report", str(hist), "--plot", str(work / "steps.png"))
    print(f"the hidden effect was: {hidden} -> {'FOUND' if named == hidden else 'MISSED'} by diagnose, "
          f"{'FOUND' if board == hidden else 'MISSED'} by the board's own discovery; "
          f"open {work / 'report-base' / 'report.html'} (where the base model fails) and "
          f"{work / 'report' / 'report.html'} (before and after {named}, the steps so far)")
    # the board's own discovery is reported, not required: on three days its held-out blocks
    # sometimes cannot decide (seed 9485: temp_offset better in 12 blocks, not adopted)
    return named == hidden


def board_discovers(rec: Path) -> str | None:
    """The board's own discovery on the same recording (the device modules, base model,
    `--discover`: what a board deployed with `accelcal deploy --discover` does in the field)."""
    r = cli("calibrate", str(rec), "--discover", "--json", quiet=True, ok=(0, 2))
    d = (json.loads(r.stdout) if r.stdout.strip() else {}).get("discovery") or {}
    if d.get("effect"):
        print(f"the board's own discovery (deployed with base and --discover): adopts {d['effect']}, "
              f"held-out {d['heldout_error_before_mg']:.2f} -> {d['heldout_error_after_mg']:.2f} mg, "
              f"better in {d['blocks_better']} of {d['blocks']} held-out blocks")
    else:
        print("the board's own discovery (deployed with base and --discover): adopts nothing"
              + (f" ({d['reason']})" if d.get("reason") else
                 f"; the closest, {d.get('closest')}" if d else ""))
    return d.get("effect")


if __name__ == "__main__":
    sys.exit(main())
