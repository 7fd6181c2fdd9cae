"""`make bench`, files part: measured in one run on this machine.

* throughput of the vectorised path, one core: floats in g -> the device's Q10 samples, the rest
  detector's twin, the apply twin (samples per second, best of 3 over 20 M samples);
* a 14-day 100 Hz simulated wrist recording (CSV, simulated once and kept in a cache outside the
  checkout, cache_root(), by its arguments and the simulator's code version; --no-cache: into a
  temporary folder, deleted after; or --csv FILE) calibrated end to end by `accelcal calibrate` in its own process: wall
  time, CPU time and peak RSS (the kernel's count for that process, os.wait4); then the same
  samples as an Axivity AX3 .cwa (accelcal.simulate.cwa; at an AX3 rate only);
* the same file through scikit-digital-health's CalibrateAccelerometer and actipy's
  calibrate_gravity (each in its own process in .venv-bench, their defaults), scored on the same
  still windows (accelcal.studies.bench_others).

    python -m accelcal.studies.bench_files [--days 14] [--rate 100] [--csv FILE] [--no-cwa] [--no-cache]
                                           [--others PYTHON] [--json]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from accelcal.bridge import twin
from accelcal.locations import checkout

ROOT = checkout() or Path.cwd()   # .venv-bench and build/pycache live in the checkout


def throughput(n: int = 20_000_000) -> dict:
    rng = np.random.default_rng(5)
    x, y = rng.normal(0, 0.3, n), rng.normal(0, 0.3, n)
    z = rng.normal(1, 0.01, n)
    chunk = 1 << 20

    def best(f):
        b = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            f()
            b = min(b, time.perf_counter() - t0)
        return n / b

    planar = twin.samples_planar(x, y, z)

    def convert():
        for a in range(0, n, chunk):
            twin.samples_planar(x[a:a + chunk], y[a:a + chunk], z[a:a + chunk], a)

    def rest():
        rs = twin.RestStream(100)
        for a in range(0, n, chunk):
            rs.feed_planar(planar[:, a:a + chunk])

    q = np.ascontiguousarray(planar.T[: n // 4], dtype=np.int64)
    p = [int(v * (1 << 24)) for v in (1.01, 0.99, 1.02, 0.01, -0.01, 0.02, 0.01, -0.02, 0.03)]

    def apply():
        for a in range(0, len(q), chunk):
            twin.apply_params(p, q[a:a + chunk])
    conv, det = best(convert), best(rest)
    return {"convert_samples_per_s": conv, "rest_samples_per_s": det,
            "convert_and_rest_samples_per_s": 1.0 / (1.0 / conv + 1.0 / det),
            "apply_samples_per_s": best(apply) * len(q) / n}


def measured(cmd: list[str], env=None) -> tuple[float, float, str, str, float]:
    """(wall s, peak RSS MB, stdout, stderr, CPU s) of a command, its RSS and CPU time (user +
    system, all its threads) from the kernel (wait4): on a machine others share, the CPU time
    is the figure their load does not inflate much."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    out, err = proc.communicate()
    wall = time.perf_counter() - t0
    # communicate() reaped it; ru_maxrss of all children is the largest child's peak so far,
    # so each measured command runs before any larger one (ours first).
    import resource
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 2):
        raise RuntimeError(f"{cmd[:3]} failed ({proc.returncode}): {err[-2000:]}")
    return wall, use.ru_maxrss / 1024.0, out, err, use.ru_utime + use.ru_stime


def measured_alone(cmd: list[str], env=None) -> tuple[float, float, str, str, float]:
    """As measured, in a fresh helper process so that RUSAGE_CHILDREN holds this command only."""
    helper = ("import json,sys;from accelcal.studies.bench_files import measured;"
              "print(json.dumps(measured(json.loads(sys.argv[1]))))")
    r = subprocess.run([sys.executable, "-c", helper, json.dumps(cmd)], capture_output=True, text=True,
                       env=env)
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-2000:])
    return tuple(json.loads(r.stdout))


def compiled_env() -> dict:
    """The environment for our command with its bytecode compiled once, as an installed package's
    is at install (the peers' are, in .venv-bench's site-packages): a checkout run with
    PYTHONDONTWRITEBYTECODE would compile every module on each start (0.1-1 s here).  The cache
    goes under build/pycache, outside the source tree."""
    import os
    env = dict(os.environ, PYTHONPYCACHEPREFIX=str(ROOT / "build" / "pycache"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    import accelcal
    import acal
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(Path(accelcal.__file__).parent),
                    str(Path(acal.__file__).parent)], env=env, check=False, capture_output=True)
    return env


def cache_root() -> Path:
    """Where simulated bench recordings are kept between runs, outside the checkout:
    $ACCELCAL_BENCH_CACHE, else $XDG_CACHE_HOME/accelcal/bench (~/.cache/accelcal/bench)."""
    import os
    if os.environ.get("ACCELCAL_BENCH_CACHE"):
        return Path(os.environ["ACCELCAL_BENCH_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "accelcal" / "bench"


def code_version(pkg: Path | None = None) -> str:
    """What the simulated files depend on: the simulator's, the effects' and the writers'
    sources (accelcal/simulate, accelcal/model, files/csvtext.py, files/outputs.py) and numpy's
    version (its random streams); 12 hex digits of their SHA-256."""
    import hashlib
    import accelcal
    pkg = pkg or Path(accelcal.__file__).parent
    h = hashlib.sha256(np.__version__.encode())
    files = sorted([*pkg.glob("simulate/**/*.py"), *pkg.glob("model/*.py"),
                    pkg / "files" / "csvtext.py", pkg / "files" / "outputs.py"])
    for f in files:
        h.update(str(f.relative_to(pkg)).encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:12]


def cached(root: Path, days: float, rate: int, seed: int = 14, cwa: bool = True) -> tuple[Path, Path | None]:
    """(the simulated CSV, its .cwa or None) from the cache at root, simulated into it first when
    missing.  An entry is a folder named by the simulation's arguments and code_version(), made
    under a temporary name and renamed whole into place (a killed run leaves no entry that looks
    complete); entries of another code version, and temporary folders of runs no longer
    running, are removed."""
    import os
    import shutil
    version = code_version()
    name = f"wrist-{days:g}d-{rate}hz-s{seed}"
    entry = root / f"{name}-{version}"
    root.mkdir(parents=True, exist_ok=True)
    for old in root.iterdir():
        stale = old.name.startswith("wrist-") and old != entry and not old.name.endswith(version)
        if old.name.startswith(".partial-"):     # .partial-PID-NAME: a run that never finished
            pid = old.name.split("-")[1]
            stale = pid.isdigit() and not _running(int(pid))
        if stale:
            print(f"removing stale cache entry {old}", file=sys.stderr, flush=True)
            shutil.rmtree(old, ignore_errors=True)
    csv = entry / f"{name}.csv"
    if not csv.exists():
        tmp = root / f".partial-{os.getpid()}-{entry.name}"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        try:
            simulated(tmp, days, rate, seed)
            as_cwa(tmp / csv.name, tmp)     # None (nothing written) at a rate no AX3 has
            try:
                os.rename(tmp, entry)
            except OSError:
                if not csv.exists():
                    raise
                shutil.rmtree(tmp)          # another run put the same entry in place first
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    else:
        print(f"simulated recording from the cache: {csv}", file=sys.stderr, flush=True)
    c = csv.with_suffix(".cwa")
    return csv, (c if cwa and c.exists() else None)


def _running(pid: int) -> bool:
    import os
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def simulated(folder: Path, days: float, rate: int, seed: int = 14) -> Path:
    """A simulated wrist recording CSV in folder (`accelcal simulate wrist`, its truth beside)."""
    f = folder / f"wrist-{days:g}d-{rate}hz-s{seed}.csv"
    print(f"simulating {days:g} days at {rate} Hz into {f} ...", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "accelcal.cli", "simulate", "wrist", "--days", str(days),
                    "--rate", str(rate), "--seed", str(seed), "-o", str(f), "--force"], check=True,
                   stdout=subprocess.DEVNULL)
    print(f"  ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    return f


def as_cwa(csv: Path, folder: Path) -> Path | None:
    """The recording as an Axivity AX3 .cwa in folder (accelcal.simulate.cwa), None when its
    rate is no AX3 rate (3200 / 2^k Hz: not 10 Hz)."""
    from accelcal.files.recordings import open_recording
    from accelcal.simulate.cwa import CwaWriter, rate_code
    rec = open_recording(csv)
    out = folder / (csv.stem + ".cwa")
    writer = None
    with open(out, "wb") as fh:
        for ch in rec.chunks():
            if writer is None:
                rate = int(round(1.0 / float(np.median(np.diff(ch.t[:1 << 16])))))
                try:
                    rate_code(rate)
                except ValueError:
                    break
                writer = CwaWriter(fh, rate)
            writer.write(ch.t, ch.xyz, ch.temp)
        if writer is not None:
            writer.close()
    if writer is None:
        out.unlink()
        return None
    return out


def calibrated(f: Path, n: int, days: float, rate: int) -> dict:
    """`accelcal calibrate` on f in its own process: wall, CPU, peak RSS, what it found."""
    wall, rss, out, err, cpu = measured_alone([sys.executable, "-m", "accelcal.cli", "calibrate",
                                               str(f), "--json", "--quiet"], compiled_env())
    rec = json.loads(out)
    kind = "CSV" if f.suffix == ".csv" else f.suffix.lstrip(".").upper()
    print(f"{days:g} days at {rate} Hz ({n / 1e6:.0f} M samples, {f.stat().st_size / 1e9:.2f} GB of "
          f"{kind}), end to end: accelcal {wall:.1f} s ({n / wall / 1e6:.1f} M samples/s; CPU "
          f"{cpu:.1f} s), peak RSS {rss:.0f} MB, {rec['status']}, calibration error "
          f"{rec['error_before_mg']:.2f} -> {rec.get('error_after_mg', float('nan')):.2f} mg on "
          f"{rec['still_windows']} still windows", flush=True)
    return {"wall_s": wall, "cpu_s": cpu, "peak_rss_mb": rss, "status": rec["status"],
            "error_before_mg": rec["error_before_mg"], "error_after_mg": rec.get("error_after_mg"),
            "still_windows": rec["still_windows"], "samples_per_s": n / wall,
            "file_gb": f.stat().st_size / 1e9}


def still_windows(path: Path, folder: Path) -> Path:
    """accelcal's kept still windows of the file (first sample, length), for scoring the others."""
    from accelcal.files.recordings import open_recording
    from accelcal.pipeline.scan import scan
    sc = scan(open_recording(path), 5, 123, 0)
    kept = sc.masks()["kept"]
    out = folder / (path.stem + ".windows.npz")
    np.savez(out, starts=sc.segments.end[kept] - sc.length + 1, length=sc.length)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(allow_abbrev=False, prog="python -m accelcal.studies.bench_files", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--days", type=float, default=14)
    ap.add_argument("--rate", type=int, default=100)
    ap.add_argument("--others", metavar="PYTHON", help="interpreter with scikit-digital-health and "
                                                        "actipy (default: .venv-bench/bin/python)")
    ap.add_argument("--no-throughput", action="store_true", help="only the end-to-end runs")
    ap.add_argument("--csv", metavar="FILE", help="an existing recording CSV of that length "
                                                  "(default: simulated into a temporary folder, "
                                                  "deleted after)")
    ap.add_argument("--no-cwa", action="store_true", help="not the .cwa of the same samples")
    ap.add_argument("--no-cache", action="store_true",
                    help="simulate into a temporary folder, deleted after (default: kept in "
                         "$ACCELCAL_BENCH_CACHE or ~/.cache/accelcal/bench, by arguments and "
                         "code version)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    res: dict = {}
    if not a.no_throughput:
        res["throughput"] = tp = throughput()
        print(f"vectorised path, one core: g -> Q10 {tp['convert_samples_per_s'] / 1e6:.0f} M samples/s, "
              f"rest twin {tp['rest_samples_per_s'] / 1e6:.0f} M/s, both {tp['convert_and_rest_samples_per_s'] / 1e6:.0f} M/s, "
              f"apply {tp['apply_samples_per_s'] / 1e6:.0f} M/s", flush=True)
    with tempfile.TemporaryDirectory(prefix="accelcal-bench-") as tmp:
        cwa = None
        if a.csv:
            f = Path(a.csv)
        elif a.no_cache:
            f = simulated(Path(tmp), a.days, a.rate)
        else:
            f, cwa = cached(cache_root(), a.days, a.rate, cwa=not a.no_cwa)
        n = int(a.days * 86400 * a.rate)
        res["accelcal"] = calibrated(f, n, a.days, a.rate)
        if cwa is None and not a.no_cwa and (a.csv or a.no_cache):
            cwa = as_cwa(f, Path(tmp))
        if cwa is not None:
            res["accelcal_cwa"] = calibrated(cwa, n, a.days, a.rate)
            if cwa.parent == Path(tmp):
                cwa.unlink()    # the peers read the CSV: room on the disk for their copies
        elif not a.no_cwa:
            print(f"  (no .cwa: {a.rate} Hz is no Axivity rate)", flush=True)
        others(a, f, Path(tmp), res)
    if a.json:
        print(json.dumps(res))
    return 0


def others(a, f: Path, tmp: Path, res: dict) -> None:
    """The same file through scikit-digital-health and actipy (each in its own process)."""
    wall = res["accelcal"]["wall_s"]
    cpu = res["accelcal"]["cpu_s"]
    py = a.others or str(ROOT / ".venv-bench" / "bin" / "python")
    if Path(py).exists():
        win = still_windows(f, tmp)
        for tool in ("skdh", "actipy"):
            try:
                wall_o, rss_o, out_o, _, cpu_o = measured_alone(
                    [py, "-m", "accelcal.studies.bench_others", tool, str(f), str(win)])
                o = json.loads(out_o.strip().splitlines()[-1])
                o.update(wall_s=wall_o, cpu_s=cpu_o, peak_rss_mb=rss_o,
                         accelcal_share_wall=wall / wall_o, accelcal_share_cpu=cpu / cpu_o)
            except (RuntimeError, ValueError, IndexError) as e:
                o = {"tool": tool, "error": " ".join(str(e).split())[-300:]}
            res[tool] = o
            if "error" in o:
                print(f"  {tool}: FAILED {o['error']}", flush=True)
            else:
                print(f"  {tool}: {o['wall_s']:.1f} s, CPU {cpu_o:.1f} s (accelcal takes "
                      f"{wall / wall_o:.2f}x its wall time, {cpu / cpu_o:.2f}x its CPU; read {o['read_s']:.1f} s, "
                      f"calibrate {o['calibrate_s']:.1f} s), peak RSS {o['peak_rss_mb']:.0f} MB, "
                      f"calibration error {o['error_before_mg']:.2f} -> {o['error_after_mg']:.2f} mg "
                      "on the same windows", flush=True)
    else:
        print(f"  (skdh/actipy skipped: {py} not found; `make bench` creates it)")


if __name__ == "__main__":
    sys.exit(main())
