"""Power cuts on the emulated Pico's real littlefs: the device's log and calibration store
(device/acal/logger/log.py) written by MicroPython's own firmware, the power cut at pseudo-random cycles
(rp2040.mjs's stopAt), the chip powered up again on the flash as the cut left it.

Two workloads, each run once uncut (its length in cycles) and then cut:
  log   - the app's way of logging: records appended to log.bin, each flushed (a littlefs commit),
          each acknowledged on the console once write() has returned;
  store - calibrations saved one after the other into the two-slot CalStore, each acknowledged.
After each cut a second chip boots on the cut flash image; there the files are read before
anything else runs, then the app starts (acal.logger.app.main on boards/pico.py, with the LIS3DH on
its bus: it opens its log, resumes the stored calibration, logs BOOT and COUNTERS) and the files
are read again.  Checked: the chip boots and littlefs holds the files; every acknowledged log record is there, and every record there is the one written
at its place (the records decode to a prefix of the workload's); the store gives the last
acknowledged calibration or the one being saved, whole; the app resumes that calibration and
appends to the log after what the cut left."""
from __future__ import annotations

import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from acal.logger import log
from acal.core.fixed import PARAM_ONE
from accelcal.board import emulated
from accelcal.bridge import rp2040
from accelcal.errors import InterpreterFailed
from accelcal.locations import BOARDS_DIR

LOG_RECORDS = 40
STORE_SAVES = 12
FILES = ("log.bin", "cal_a.bin", "cal_b.bin")


def rest_values(i: int) -> tuple:
    """The log workload's record i (a REST record's fields)."""
    return (100 * i, 640 * i - 30000, -11 * i, 65536 - 7 * i, 25, i % 10 - 1, i)


def cal_values(k: int) -> tuple:
    """The store workload's calibration k (a CAL record's fields; parameters a fit could give)."""
    return (100 * k, k, 0, 50, 18, 1000 + k, 10 + k, PARAM_ONE + 100 * k, PARAM_ONE - 50 * k,
            PARAM_ONE + 7 * k, 10 * k, -10 * k, 3 * k, 1000 * k, -1000 * k, 500 * k)


WORKLOADS = {
    "log": f"""from acal.logger import log
lg = log.Log('log.bin', 1 << 20)
for i in range({LOG_RECORDS}):
    lg.write(log.REST, 100 * i, 640 * i - 30000, -11 * i, 65536 - 7 * i, 25, i % 10 - 1, i)
    print('W', i)
""",
    "store": f"""from acal.logger import log
from acal.core.fixed import PARAM_ONE
st = log.CalStore('cal_a.bin', 'cal_b.bin')
for k in range(1, {STORE_SAVES + 1}):
    st.save((100 * k, k, 0, 50, 18, 1000 + k, 10 + k, PARAM_ONE + 100 * k, PARAM_ONE - 50 * k,
             PARAM_ONE + 7 * k, 10 * k, -10 * k, 3 * k, 1000 * k, -1000 * k, 500 * k), ())
    print('S', k)
""",
}

RESUME = """import acal.logger.app
app = acal.logger.app.main(seconds=0, verbose=False, rate_hz=100, fifo=True, profile=0)
print('ACAL_RESUMED', app.samples, app.proc.calibrations)
"""


def base_image(folder: Path) -> Path:
    """The package image with boards/pico.py deployed as acal_board.py: what each cut starts
    from."""
    img = folder / "base.bin"
    emulated.run([], puts={"acal_board.py": (BOARDS_DIR / "pico.py").read_bytes()}, flash_out=img)
    return img


def _cuts(workload: str, cut_at: list, base: Path, stimulus: Path, folder: Path,
          timeout: float) -> list[dict]:
    (folder / "workload.py").write_text(WORKLOADS[workload])
    (folder / "resume.py").write_text(RESUME)
    report = folder / f"{workload}.jsonl"
    report.unlink(missing_ok=True)
    args = emulated.node_args(stimulus, 0, 1, base) + [
        "cuts", "--cut-at", ",".join(map(str, cut_at)), "--exec", str(folder / "workload.py"),
        "--exec", str(folder / "resume.py"), "--report", str(report)]
    for f in FILES:
        args += ["--get", f]
    p = subprocess.run(args, capture_output=True, timeout=timeout, encoding="latin1")
    if p.returncode != 0:
        raise InterpreterFailed("rp2040", p)
    return [json.loads(line) for line in report.read_text().splitlines()]


def _files(rec: dict, which: str, folder: Path) -> Path:
    d = folder / which
    d.mkdir(exist_ok=True)
    for f in FILES:
        (d / f).unlink(missing_ok=True)
        if f in rec.get(which, {}):
            (d / f).write_bytes(bytes.fromhex(rec[which][f]))
    return d


def judge(workload: str, rec: dict, folder: Path) -> dict:
    """One cut's findings: lost and damaged log records, a mixed calibration, a failed boot."""
    acks = [line.split() for line in rec["out"].replace("\r", "").split("\n") if line.strip()]
    acked = sum(1 for a in acks if a[:1] in (["W"], ["S"]))
    out = {"acked": acked, "lost": 0, "damaged": 0, "mixed": 0, "failed_boot": 0}
    resumed = [ln.split() for ln in rec.get("resume_out", "").splitlines() if ln.startswith("ACAL_RESUMED")]
    if "boot_error" in rec or rec.get("resume_err") or not resumed:
        out["failed_boot"] = 1
        out["why"] = rec.get("boot_error") or rec.get("resume_err") or "the app printed nothing"
        return out
    before = _files(rec, "before", folder)
    after = _files(rec, "after", folder)
    if workload == "log":
        recs, _ = log.scan((before / "log.bin").read_bytes()) if (before / "log.bin").exists() else ([], [])
        vals = [(t, log.unpack(t, p)) for _, t, p in recs]
        expected = [(log.REST, rest_values(i)) for i in range(LOG_RECORDS)]
        out["damaged"] = sum(1 for i, v in enumerate(vals) if i >= len(expected) or v != expected[i])
        out["lost"] = max(0, acked - len(vals))
        later, _ = log.scan((after / "log.bin").read_bytes())
        kept = [(t, log.unpack(t, p)) for _, t, p in later][:len(vals)]
        resumed_log = kept == vals and any(t == log.BOOT for _, t, _ in later[len(vals):])
        if not resumed_log:
            out["failed_boot"] = 1
            out["why"] = "the app's log after the power-up does not continue the cut one"
    else:
        _, got = log.CalStore(str(before / "cal_a.bin"), str(before / "cal_b.bin")).load()
        allowed = {cal_values(k) for k in (acked, acked + 1) if 1 <= k <= STORE_SAVES}
        if got is None:
            out["mixed"] = int(acked > 0)        # the acknowledged calibration is gone
        else:
            out["mixed"] = int(tuple(got) not in allowed)
        number = 0 if got is None else got[1]
        if int(resumed[-1][2]) != number:
            out["failed_boot"] = 1
            out["why"] = f"the app resumed calibration {resumed[-1][2]}, the store holds {number}"
    return out


def run_cuts(n_per_workload: int, seed: int = 1, timeout: float = 7200) -> dict:
    """n_per_workload cuts of each workload at pseudo-random cycles (seeded); the counts."""
    from accelcal.simulate.stimulus import calibration_dance
    rng = np.random.default_rng(seed)
    totals = {"cuts": 0, "records_acked": 0, "records_lost": 0, "records_damaged": 0,
              "mixed_calibrations": 0, "failed_boots": 0, "problems": []}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        stim = folder / "stim.bin"
        calibration_dance(stim, 100, [1, 1, 1, 0, 0, 0, 0, 0, 0], seed, rounds=1)
        base = base_image(folder)
        for workload in WORKLOADS:
            ref = _cuts(workload, ["end"], base, stim, folder, timeout)[0]
            ref_counts = judge(workload, ref, folder)
            if not ref["finished"] or ref_counts["failed_boot"]:
                raise RuntimeError(f"the {workload} workload fails uncut: {ref_counts}")
            totals[f"{workload}_cycles"] = ref["ran"]
            points = sorted(int(c) for c in rng.integers(1, ref["ran"], n_per_workload))
            for rec in _cuts(workload, points, base, stim, folder, timeout):
                c = judge(workload, rec, folder)
                totals["cuts"] += 1
                totals["records_acked"] += c["acked"] if workload == "log" else 0
                totals["records_lost"] += c["lost"]
                totals["records_damaged"] += c["damaged"]
                totals["mixed_calibrations"] += c["mixed"]
                totals["failed_boots"] += c["failed_boot"]
                if c["lost"] or c["damaged"] or c["mixed"] or c["failed_boot"]:
                    totals["problems"].append({"workload": workload, "cut_at": rec["cut_at"], **c})
    return totals
