"""Farago 2024 Table 2: the simulation of section III-A through the device's bins and optimiser,
beside the paper's numbers, `lsq` on the same selected points, and the Cramer-Rao bound of those
points (the best any unbiased method could do on them)."""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from acal.core import fixed
from acal.paper import optimiser
from accelcal import methods, simulate
from accelcal.bridge import runtime
from accelcal.fixedpoint import params_to_float

NAMES = fixed.PARAM_NAMES
# Table 2 of the paper: mean and SD of |estimated - true| at 1 mg and 5 mg noise.
PAPER_MEAN = {
    1: [2.98e-4, 3.18e-4, 2.47e-4, 1.49e-3, 1.42e-3, 1.45e-3, 2.39e-4, 2.54e-4, 2.04e-4],
    5: [1.39e-3, 1.64e-3, 1.07e-3, 2.61e-3, 2.67e-3, 3.3e-3, 1.05e-3, 1.18e-3, 1.08e-3],
}
PAPER_SD = {
    1: [2.37e-4, 2.27e-4, 1.68e-4, 1.22e-3, 1.23e-3, 1.26e-3, 1.88e-4, 1.91e-4, 1.5e-4],
    5: [1.07e-3, 1.22e-3, 8.98e-4, 2.24e-3, 2.07e-3, 2.53e-3, 9.2e-4, 8.35e-4, 7.76e-4],
}


@dataclass
class Table2Result:
    noise_mg: int
    policy: str
    device_err: np.ndarray   # (scenarios, 9) absolute errors of the device optimiser
    lsq_err: np.ndarray      # lsq on the same selected points
    bound: np.ndarray        # Cramer-Rao mean-absolute-error bound per scenario
    failed: int

    def mean(self, which="device"):
        return getattr(self, f"{which}_err" if which != "bound" else "bound").mean(axis=0)

    def sd(self, which="device"):
        return getattr(self, f"{which}_err" if which != "bound" else "bound").std(axis=0, ddof=1)


def run_table2(scenarios=500, noise_mg=1, seed=2024, candidates=300, policy="centre",
               dist="normal", runtime_name="cpython", progress=None,
               profile: str = "paper") -> Table2Result:
    """Run the scenarios at one noise level.  `candidates` random rest means per scenario are
    offered to the bins (the paper does not say how many it generated).  profile: the paper's
    (Table 2 itself), or wear (72 points, Gauss-Newton: beside lsq on the same points)."""
    rng = np.random.default_rng([seed, noise_mg])
    truths, groups = [], []
    for s in range(scenarios):
        p, v = simulate.paper_scenario(rng, candidates, noise_mg * 1e-3, dist)
        truths.append(p)
        groups.append(runtime.PointsGroup(f"s{s:04d}", points=v))
    cfg = runtime.Config.for_profile(profile, policy=policy)
    results = []
    step = 50
    for i in range(0, scenarios, step):  # chunks, so long runs show progress
        results += runtime.run(groups[i:i + step], cfg, runtime_name)
        if progress:
            progress(min(i + step, scenarios), scenarios)
    dev, ref, bnd = [], [], []
    failed = 0
    from accelcal.pipeline.calibrate import fill_reason
    for p, r in zip(truths, results):
        if r.status != optimiser.OK or fill_reason(r, cfg):
            failed += 1
            continue
        sel = r.fit_points_g
        dev.append(np.abs(params_to_float(r.params_int) - p))
        ref.append(np.abs(methods.lsq(sel) - p))
        bnd.append(methods.fisher_bound(p, sel, noise_mg * 1e-3 * (1 if dist == "normal" else 3 ** -0.5)))
    return Table2Result(noise_mg, policy, np.array(dev), np.array(ref), np.array(bnd), failed)


def format_table2(res: dict[tuple[int, str], Table2Result]) -> str:
    out = []
    for noise in (1, 5):
        c = res[(noise, "centre")]
        f = res.get((noise, "first"))
        out.append(f"\nNoise {noise} mg, {len(c.device_err)} scenarios"
                   f" ({c.failed} failed to fill or fit)")
        hdr = (f"{'param':<6}{'paper mean':>12}{'device':>11}{'lsq':>11}{'CR bound':>11}"
               f"{'first-come':>12} | {'paper SD':>10}{'device SD':>11}")
        out.append(hdr)
        out.append("-" * len(hdr))
        for i, n in enumerate(NAMES):
            fc = f"{f.mean()[i]:12.3e}" if f is not None else f"{'':>12}"
            out.append(f"{n:<6}{PAPER_MEAN[noise][i]:12.3e}{c.mean()[i]:11.3e}"
                       f"{c.mean('lsq')[i]:11.3e}{c.mean('bound')[i]:11.3e}{fc} | "
                       f"{PAPER_SD[noise][i]:10.3e}{c.sd()[i]:11.3e}")
        ratio = c.mean().sum() / c.mean("lsq").sum()
        out.append(f"device / lsq (sum of mean errors): {ratio:.3f}")
    return "\n".join(out)


def table2_main(*, scenarios: int, candidates: int, noise_dist: str, runtime_name: str,
                no_first: bool, profile: str, seed: int, as_json: bool = False) -> int:
    def progress(done, total):
        print(f"\r  {done}/{total} scenarios", end="", file=sys.stderr, flush=True)
        if done == total:
            print(file=sys.stderr)

    res = {}
    policies = ["centre"] if no_first else ["centre", "first"]
    for noise in (1, 5):
        for pol in policies:
            print(f"noise {noise} mg, {pol} selection:", file=sys.stderr)
            res[(noise, pol)] = run_table2(scenarios, noise, seed, candidates, pol,
                                           noise_dist, runtime_name, progress, profile)
    if as_json:
        import json
        print(json.dumps({f"{n}mg_{p}": {"device_mean": r.mean().tolist(),
                                           "device_sd": r.sd().tolist(),
                                           "lsq_mean": r.mean("lsq").tolist(),
                                           "bound_mean": r.mean("bound").tolist(),
                                           "paper_mean": PAPER_MEAN[n], "paper_sd": PAPER_SD[n],
                                           "failed": r.failed}
                          for (n, p), r in res.items()}))
    else:
        print("Farago 2024 Table 2: mean |estimated - true| over scenarios "
              f"(noise: {noise_dist}; {candidates} candidate rest means per scenario; "
              f"device = the {profile} profile, CENTRE point selection)")
        print(format_table2(res))
    return 0
