"""`accelcal calibrate FILES...`: many recordings, a process pool (or an existing Dask cluster),
a progress bar, one summary row per file.  One bad file never stops the batch: whatever goes
wrong in a file becomes that file's status and reason."""
from __future__ import annotations

import csv
import os
import sys
import time
from dataclasses import dataclass

from accelcal import runtime
from accelcal.io import InputError
from accelcal.outputs import atomic

SUMMARY_COLUMNS = ("file", "status", "calibration", "reason", "profile", "format", "rate_hz", "hours",
                   "hours_used", "gaps", "still_windows", "nonwear_excluded", "imputed_excluded",
                   "clipped_excluded", "bins_filled", "temp_min_c", "temp_max_c", "clipped_pct",
                   "error_before_mg", "error_after_mg", "iterations", "seconds",
                   "kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz")


@dataclass
class Job:
    """What every file gets: the pipeline settings and the calibrate options (picklable, for
    the pool and for Dask)."""
    cfg: runtime.Config
    method: str = "device"
    runtime_name: str = "cpython"
    model: str = "base"
    engine: str = "vector"
    fallback: str | None = None
    points: str = "bins"


def calibrate_file(path: str, job: Job) -> dict:
    """One file's record; never raises."""
    from copy import deepcopy

    from accelcal.calibrate import calibrate_groups, calibrate_recording, use_fallback
    from accelcal.effects import ModelSpec
    from accelcal.io import read_table
    from accelcal.recording import is_recording
    t0 = time.perf_counter()
    cfg = deepcopy(job.cfg)
    try:
        spec = ModelSpec.parse(job.model)
        if is_recording(path):
            rec = calibrate_recording(path, cfg, job.method, job.runtime_name, spec, job.engine,
                                      fallback=job.fallback, points=job.points)
        else:
            rec = {"file": path, "format": "points",
                   **calibrate_groups(read_table(path), None, cfg, job.method, job.runtime_name, spec,
                                        job.points)[0]}
            rec["calibration"] = "new" if rec["status"] == "calibrated" else "none"
            if rec["status"] != "calibrated" and job.fallback:
                import numpy as np
                use_fallback(rec, job.fallback, np.zeros((0, 3)))
    except (InputError, ValueError) as e:
        rec = {"file": path, "status": "failed", "calibration": "none", "reason": str(e)}
    except MemoryError:
        rec = {"file": path, "status": "failed", "calibration": "none",
               "reason": "out of memory reading the file"}
    except Exception as e:  # a bug must not stop the batch: say what it was
        rec = {"file": path, "status": "failed", "calibration": "none",
               "reason": f"internal error: {type(e).__name__}: {' '.join(str(e).split())[:200]}"}
    rec.setdefault("profile", job.cfg.profile)
    rec["seconds"] = round(time.perf_counter() - t0, 3)
    return rec


def _progress(total: int, quiet: bool):
    from tqdm import tqdm
    return tqdm(total=total, unit="file", file=sys.stderr, disable=quiet, dynamic_ncols=True,
                bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} files [{elapsed}<{remaining}]{postfix}")


def run_local(paths: list[str], job: Job, jobs: int, quiet: bool = False) -> list[dict]:
    """The batch on a process pool of `jobs` workers (1: in this process).  Records in the
    order of paths."""
    out: dict[int, dict] = {}
    bar = _progress(len(paths), quiet)
    if jobs <= 1:
        for i, p in enumerate(paths):
            out[i] = calibrate_file(p, job)
            _tick(bar, out[i])
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed
        # forkserver: workers do not inherit Arrow's or BLAS's threads mid-flight
        with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("forkserver")) as ex:
            futs = {ex.submit(calibrate_file, p, job): i for i, p in enumerate(paths)}
            for f in as_completed(futs):
                i = futs[f]
                try:
                    out[i] = f.result()
                except Exception as e:  # the worker died (killed, out of memory)
                    out[i] = {"file": paths[i], "status": "failed", "calibration": "none",
                              "reason": f"worker lost: {type(e).__name__}: {e}"}
                _tick(bar, out[i])
    bar.close()
    return [out[i] for i in range(len(paths))]


def run_dask(paths: list[str], job: Job, address: str, quiet: bool = False) -> list[dict]:
    """The same batch on an existing Dask cluster (scheduler address).  The workers need
    accelcal installed, and the files at the same paths."""
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--dask needs the distributed package (pip install distributed)") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as e:
        raise InputError(f"--dask {address}: cannot reach the scheduler "
                         f"({' '.join(str(e).split())[:200]})") from None
    out: dict[int, dict] = {}
    bar = _progress(len(paths), quiet)
    try:
        futs = client.map(calibrate_file, paths, job=job, pure=False)
        index = {f.key: i for i, f in enumerate(futs)}
        for f in as_completed(futs):
            i = index[f.key]
            try:
                out[i] = f.result()
            except Exception as e:
                out[i] = {"file": paths[i], "status": "failed", "calibration": "none",
                          "reason": f"worker lost: {type(e).__name__}: {e}"}
            _tick(bar, out[i])
    finally:
        bar.close()
        client.close()
    return [out[i] for i in range(len(paths))]


def _tick(bar, rec):
    bar.set_postfix_str(f"{os.path.basename(rec['file'])}: {rec['status']}", refresh=False)
    bar.update(1)


def summary_row(rec: dict) -> dict:
    ex = rec.get("excluded") or {}
    tr = rec.get("temp_range_c") or [None, None]
    row = {k: rec.get(k) for k in SUMMARY_COLUMNS}
    row.update(nonwear_excluded=ex.get("nonwear"), imputed_excluded=ex.get("imputed"),
               clipped_excluded=ex.get("clipped"), temp_min_c=tr[0], temp_max_c=tr[1])
    for k, v in (rec.get("params") or {}).items():
        if k in row:
            row[k] = v
    return row


def write_summary(path: str, recs: list[dict]) -> None:
    with atomic(path, newline="") as fh:
        w = csv.DictWriter(fh, SUMMARY_COLUMNS)
        w.writeheader()
        for r in recs:
            w.writerow({k: ("" if v is None else v) for k, v in summary_row(r).items()})


def print_summary(recs: list[dict], out=sys.stdout) -> None:
    name_w = max(12, *(len(os.path.basename(r["file"])) for r in recs))
    print(f"{'file':<{name_w}}  {'status':<15} {'hours':>7} {'still':>6} {'bins':>4} "
          f"{'before mg':>9} {'after mg':>8}  reason", file=out)
    for r in recs:
        def num(k, fmt):
            v = r.get(k)
            width = int(fmt.split(".")[0].rstrip("dfg"))
            return format(v, fmt) if isinstance(v, (int, float)) else "-".rjust(width)
        status = r["status"] + ("*" if r.get("calibration") == "fallback" else "")
        bins = f"{r['bins_filled']}/9" if "bins_filled" in r else "-"
        print(f"{os.path.basename(r['file']):<{name_w}}  {status:<15} {num('hours', '7.1f')} "
              f"{num('still_windows', '6d')} {bins:>4} {num('error_before_mg', '9.2f')} "
              f"{num('error_after_mg', '8.2f')}  {r.get('reason') or ''}", file=out)
    n_ok = sum(r["status"] == "calibrated" for r in recs)
    n_fb = sum(r.get("calibration") == "fallback" for r in recs)
    print(f"{n_ok} of {len(recs)} files calibrated" + (f"; {n_fb} use their fallback calibration (*)"
                                                       if n_fb else ""), file=out)
