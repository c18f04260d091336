#!/usr/bin/env python3
"""Tune one algorithm's parameters once on the BROAD development trials (never per trial).

Usage: .venv/bin/python benchmarks/tune_orientation.py ALGORITHM [--maxfev 40] [--step 0.3] [--write]

Optimiser: scipy.optimize.minimize(method="Nelder-Mead") in log-space of the positive parameters
listed in SEARCH, started from the class's TUNING_START (else its DEFAULTS), initial simplex edge
``--step`` in log-space (scipy's default 5 % otherwise), bounded by ``maxfev``. Cost: mean total RMSE
(degrees) over the development trials (benchmarks/orientation.py DEV_TRIALS), each scored on its
movement samples. ``--write`` stores the result in config/orientation_filters.yaml. Not run by tests.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import yaml
from orientation import DEV_TRIALS, ROOT, broad_errors, load_trials, run_ours
from scipy.optimize import minimize

from gait_biofeedback.core.filters import ALGORITHMS
from gait_biofeedback.core.filters.config import TUNED_PATH

SEARCH = {
    "inertial_cf": ["tau_acc", "tau_mag", "tau_rest", "rest_gyr", "rest_acc", "mag_norm_th", "mag_dip_th",
                    "mag_new_time", "mag_max_reject", "tau_mag_fast", "fast_time", "mag_accept_time"],
    "madgwick": ["beta1", "beta2", "beta3", "s_acc1", "s_acc2", "s_mag1", "s_mag2"],
    "mahony": ["kp1", "kp2", "kp3", "s_acc1", "s_acc2", "s_mag1", "s_mag2"],
    "yi_cf": ["B", "alpha"],
    "zihajehzadeh_ckf": ["sigma_g", "sigma_a", "sigma_m"],
    "nazarahari_rekf": ["sigma_g1", "sigma_a1", "sigma_a2", "sigma_m1", "sigma_m2"],
    "nazarahari_lkf": ["sigma_g1", "sigma_a1", "sigma_a2", "sigma_m1", "sigma_m2", "mu"],
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("algorithm", choices=sorted(SEARCH))
    ap.add_argument("--maxfev", type=int, default=40)
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--step", type=float, default=None,
                    help="initial simplex edge in log-space (e.g. 0.3 = ±35 %%; default: scipy's 5 %%)")
    args = ap.parse_args()
    trials = load_trials(list(DEV_TRIALS))
    names = SEARCH[args.algorithm]
    cls = ALGORITHMS[args.algorithm]
    defaults = getattr(cls, "TUNING_START", cls.DEFAULTS)  # hand-set start when DEFAULTS hold the result
    x0 = np.log([float(defaults[n]) for n in names])

    def cost(x: np.ndarray) -> float:
        params = dict(zip(names, np.exp(x).tolist(), strict=True))
        errs = [
            broad_errors(run_ours(args.algorithm, t, params), t["quat"], t["movement"])[0]
            for t in trials.values()
        ]
        c = float(np.mean(errs))
        print(f"{c:7.3f}  " + " ".join(f"{n}={v:.4g}" for n, v in params.items()), flush=True)
        return c if np.isfinite(c) else 1e3

    t0 = time.perf_counter()
    start = cost(x0)
    options = {"maxfev": args.maxfev, "xatol": 0.05, "fatol": 0.01}
    if args.step is not None:
        options["initial_simplex"] = np.vstack([x0, x0 + args.step * np.eye(len(x0))])
    res = minimize(cost, x0, method="Nelder-Mead", options=options)
    best = dict(zip(names, np.exp(res.x).tolist(), strict=True))
    took = time.perf_counter() - t0
    print(
        f"default {start:.3f}° → tuned {res.fun:.3f}° mean total RMSE on dev trials {DEV_TRIALS}; "
        f"{res.nfev} evaluations, {took:.0f} s"
    )
    if args.write:
        data = yaml.safe_load(TUNED_PATH.read_text()) if TUNED_PATH.is_file() else {}
        data = data or {}
        algos = data.setdefault("algorithms", {})
        algos[args.algorithm] = {
            "params": {k: float(f"{v:.4g}") for k, v in best.items()},
            "tuning": {
                "dev_trials": list(DEV_TRIALS),
                "mean_total_rmse_deg": round(float(res.fun), 3),
                "default_rmse_deg": round(start, 3),
                "evaluations": int(res.nfev),
                "seconds": round(took),
                "command": f"benchmarks/tune_orientation.py {args.algorithm} --maxfev {args.maxfev}"
                + (f" --step {args.step:g}" if args.step is not None else "") + " --write",
            },
        }
        TUNED_PATH.write_text(
            "# Tuned once on the BROAD development trials (see benchmarks/tune_orientation.py).\n"
            + yaml.safe_dump(data, sort_keys=False)
        )
        print(f"written to {TUNED_PATH.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
