"""`accelcal calibrate FILES...`: many recordings, a process pool (or an existing Dask cluster),
one record per file, each calibrate_file's (pipeline/job.py); the caller shows the progress
(done(record) as each file ends).  One bad file never stops the batch: whatever goes wrong in a
file becomes that file's status and reason."""
from __future__ import annotations

import time

from accelcal.errors import InputError
from accelcal.pipeline.job import Job, calibrate_file
from accelcal.pipeline.results import CalibrationResult


def batch_record(path: str, job: Job) -> CalibrationResult:
    """One file's record in a batch (calibrate_file's, timed); never raises: bad input or a bug
    becomes the file's status and reason."""
    t0 = time.perf_counter()
    try:
        rec = calibrate_file(path, job)
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


def _child(path: str, job: Job, conn) -> None:
    conn.send(batch_record(path, job))
    conn.close()


def isolated_record(path: str, job: Job, ctx) -> CalibrationResult:
    """batch_record in a process of its own: if a native reader kills it (an abort, a signal,
    memory), that is this file's status, "failed", with the signal named."""
    import signal
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(path, job, send), daemon=True)
    proc.start()
    send.close()
    try:
        rec = recv.recv()
    except EOFError:
        rec = None
    proc.join()
    if rec is not None:
        return rec
    code = proc.exitcode or 0
    how = (f"signal {signal.Signals(-code).name}" if code < 0 and -code in signal.valid_signals()
           else f"exit {code}")
    return CalibrationResult.failed(path, f"the process reading the file died ({how}): a file "
                                    "its reader cannot survive (a damaged file?)")


def run_local(paths: list[str], job: Job, jobs: int, done=lambda rec: None) -> list[CalibrationResult]:
    """The batch on a process pool of `jobs` workers (1: in this process).  Records in the
    order of paths."""
    out: dict[int, dict] = {}
    if jobs <= 1:
        for i, p in enumerate(paths):
            out[i] = batch_record(p, job)
            done(out[i])
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed
        from concurrent.futures.process import BrokenProcessPool
        # forkserver: workers do not inherit Arrow's or BLAS's threads mid-flight
        ctx = mp.get_context("forkserver")
        lost: list[int] = []
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as ex:
            futs = {ex.submit(batch_record, p, job): i for i, p in enumerate(paths)}
            for f in as_completed(futs):
                i = futs[f]
                try:
                    out[i] = f.result()
                except BrokenProcessPool:   # a worker died: every file not done is lost with it
                    lost.append(i)
                    continue
                except Exception as e:  # the worker died (killed, out of memory)
                    out[i] = CalibrationResult.failed(paths[i], f"worker lost: {type(e).__name__}: {e}")
                done(out[i])
        for i in sorted(lost):   # each again in a process of its own: one death, one file's status
            out[i] = isolated_record(paths[i], job, ctx)
            done(out[i])
    return [out[i] for i in range(len(paths))]


def run_dask(paths: list[str], job: Job, address: str, done=lambda rec: None) -> list[CalibrationResult]:
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
    try:
        futs = client.map(batch_record, paths, job=job, pure=False)
        index = {f.key: i for i, f in enumerate(futs)}
        for f in as_completed(futs):
            i = index[f.key]
            try:
                out[i] = f.result()
            except Exception as e:
                out[i] = CalibrationResult.failed(paths[i], f"worker lost: {type(e).__name__}: {e}")
            done(out[i])
    finally:
        client.close()
    return [out[i] for i in range(len(paths))]

