"""`accelcal calibrate FILES...`: many recordings, a process pool (or an existing Dask cluster),
a progress bar, one summary row per file.  One bad file never stops the batch: whatever goes
wrong in a file becomes that file's status and reason."""
from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass

from accelcal.bridge import runtime
from accelcal.errors import InputError
from accelcal.pipeline.results import CalibrationResult

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
    effects: str | None = None     # a user's effects file, registered in each worker


def calibrate_file(path: str, job: Job) -> CalibrationResult:
    """One file's record; never raises."""
    from accelcal.pipeline.calibrate import calibrate_groups, calibrate_recording, use_fallback
    from accelcal.model.effects import ModelSpec
    from accelcal.files.table import read_table
    from accelcal.files.readers import is_recording
    from accelcal.model.declared import register
    t0 = time.perf_counter()
    cfg = job.cfg   # immutable: each step makes its own (dataclasses.replace)
    try:
        register(job.effects)   # a worker process starts with the built-in catalogue
        spec = ModelSpec.parse(job.model)
        if is_recording(path):
            rec = calibrate_recording(path, cfg, job.method, job.runtime_name, spec, job.engine,
                                      fallback=job.fallback, points=job.points)
        else:
            rec = CalibrationResult(file=path, format="points", **calibrate_groups(
                read_table(path), None, cfg, job.method, job.runtime_name, spec, job.points)[0])
            rec["calibration"] = "new" if rec["status"] == "calibrated" else "none"
            if rec["status"] != "calibrated" and job.fallback:
                import numpy as np
                use_fallback(rec, job.fallback, np.zeros((0, 3)))
    except (InputError, ValueError) as e:
        rec = CalibrationResult.failed(path, str(e))
    except MemoryError:
        rec = CalibrationResult.failed(path, "out of memory reading the file")
    except Exception as e:  # a bug must not stop the batch: say what it was
        rec = CalibrationResult.failed(
            path, f"internal error: {type(e).__name__}: {' '.join(str(e).split())[:200]}")
    rec.setdefault("profile", job.cfg.profile)
    rec["seconds"] = round(time.perf_counter() - t0, 3)
    return rec


def _progress(total: int, quiet: bool):
    from tqdm import tqdm
    return tqdm(total=total, unit="file", file=sys.stderr, disable=quiet, dynamic_ncols=True,
                bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} files [{elapsed}<{remaining}]{postfix}")


def run_local(paths: list[str], job: Job, jobs: int, quiet: bool = False) -> list[CalibrationResult]:
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
                    out[i] = CalibrationResult.failed(paths[i], f"worker lost: {type(e).__name__}: {e}")
                _tick(bar, out[i])
    bar.close()
    return [out[i] for i in range(len(paths))]


def run_dask(paths: list[str], job: Job, address: str, quiet: bool = False) -> list[CalibrationResult]:
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
                out[i] = CalibrationResult.failed(paths[i], f"worker lost: {type(e).__name__}: {e}")
            _tick(bar, out[i])
    finally:
        bar.close()
        client.close()
    return [out[i] for i in range(len(paths))]


def _tick(bar, rec):
    bar.set_postfix_str(f"{os.path.basename(rec['file'])}: {rec['status']}", refresh=False)
    bar.update(1)
