#!/usr/bin/env python3
"""Tune one algorithm's parameters once on the BROAD development trials (never per trial).

Usage: .venv/bin/python benchmarks/tune_orientation.py ALGORITHM [--maxfev 40] [--step 0.3]
           [--window SECONDS] [--max-seconds S] [--write]

Optimiser: scipy.optimize.minimize(method="Nelder-Mead") in log-space of the parameters listed in
SEARCH (a leading "-" marks a negative parameter, searched as log(−value)), started from the class's
DEFAULTS (the untuned ones; constructor keywords such as ``mag_reject_norm`` start from the
constructor's default), initial simplex edge ``--step`` in log-space (scipy's default 5 % otherwise),
box-bounded in log-space (BOUNDS, else ``start`` ÷/× 10³), stopped by ``maxfev`` (and, if given,
``--max-seconds``: the best point evaluated so far is kept). Cost: mean total RMSE (degrees) over
the development trials (benchmarks/orientation.py DEV_TRIALS), each scored on its movement samples.
``--window W`` (for the slow Kalman filters): every dev trial is cut W seconds after its first
movement sample; the filter still runs on every sample from the trial start (start-up rest, bias
convergence) up to the cut, and the movement samples before the cut are scored. ``--write`` stores the
result in config/orientation_filters.yaml. Not run by tests.
"""

from __future__ import annotations

import argparse
import inspect
import time

import numpy as np
import yaml
from orientation import DEV_TRIALS, ROOT, broad_errors, load_trials, run_ours
from scipy.optimize import minimize

from gait_biofeedback.batch import ALGORITHMS, TUNED_PATH

SEARCH = {
    "inertial_cf": ["tau_acc", "tau_mag", "tau_rest", "rest_gyr", "rest_acc", "mag_norm_th", "mag_dip_th",
                    "mag_new_time", "mag_max_reject", "tau_mag_fast", "fast_time", "mag_accept_time"],
    "madgwick": ["beta1", "beta2", "beta3", "s_acc1", "s_acc2", "s_mag1", "s_mag2"],
    "mahony": ["kp1", "kp2", "kp3", "s_acc1", "s_acc2", "s_mag1", "s_mag2"],
    # k = A(Δ_mag + α Δ_acc − C) + B: C is redundant with B (kept 0), A < 0 (k falls with disturbance)
    "yi_cf": ["B", "-A", "alpha"],
    # only ratios of σ_G, σ_A, σ_M and the adaptive c_a‖a⁺‖² term matter; the gating of Eq 26
    # (ε_M, ε_dip: constructor keywords) decides how often the yaw KF runs gyro-only
    "zihajehzadeh_ckf": ["sigma_g", "sigma_a", "sigma_m", "mag_reject_norm", "mag_reject_dip"],
    # σ_G2 (not σ_G1): ‖ω‖ > s_g = 0.5 rad/s on most movement samples
    "nazarahari_rekf": ["sigma_g2", "sigma_a1", "sigma_a2", "sigma_m1", "sigma_m2"],
    # μ: gradient step of the pseudo-measurement (R ∝ μ²); the σ's set the gain against P⁻
    "nazarahari_lkf": ["mu", "sigma_g2", "sigma_a2", "sigma_m1", "sigma_m2"],
}
# log-space box bounds where ÷/× 10³ around the start would leave the parameter's meaningful range
BOUNDS = {
    "yi_cf": {"B": (1e-5, 1.0), "alpha": (0.01, 100.0)},
    "zihajehzadeh_ckf": {"mag_reject_norm": (1e-3, 10.0), "mag_reject_dip": (1e-3, 3.0)},
    "nazarahari_lkf": {"mu": (1e-4, 2.0)},
}


def start_value(cls: type, name: str) -> float:
    """Start of a searched parameter: DEFAULTS, else the constructor's keyword default."""
    if name in cls.DEFAULTS:
        return float(cls.DEFAULTS[name])
    for klass in cls.__mro__:
        if "__init__" in vars(klass):
            par = inspect.signature(klass.__init__).parameters.get(name)
            if par is not None and par.default is not inspect.Parameter.empty:
                return float(par.default)
    raise KeyError(f"{cls.__name__}: no start value for {name!r}")


def cut_trial(t: dict[str, np.ndarray], window_s: float) -> dict[str, np.ndarray]:
    """The trial up to ``window_s`` seconds after its first movement sample (scoring window)."""
    end = int(np.argmax(t["movement"])) + round(window_s * t["rate"])
    return {k: (v[:end] if isinstance(v, np.ndarray) and v.ndim >= 1 else v) for k, v in t.items()}


class _BudgetError(Exception):
    pass


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("algorithm", choices=sorted(SEARCH))
    ap.add_argument("--maxfev", type=int, default=40)
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--step", type=float, default=None,
                    help="initial simplex edge in log-space (e.g. 0.3 = ×1.35; negative: vertices below "
                         "the start; default: scipy's 5 %%)")
    ap.add_argument("--window", type=float, default=None,
                    help="score each dev trial only up to this many seconds after its first movement")
    ap.add_argument("--max-seconds", type=float, default=None,
                    help="stop after this much wall time, keeping the best point evaluated so far")
    args = ap.parse_args()
    trials = load_trials(list(DEV_TRIALS))
    if args.window is not None:
        trials = {k: cut_trial(t, args.window) for k, t in trials.items()}
    cls = ALGORITHMS[args.algorithm]
    signed = SEARCH[args.algorithm]
    names = [n.lstrip("-") for n in signed]
    sign = np.array([-1.0 if n.startswith("-") else 1.0 for n in signed])
    start_vals = np.array([start_value(cls, n) for n in names])
    x0 = np.log(sign * start_vals)
    bnd = BOUNDS.get(args.algorithm, {})
    bounds = [tuple(np.log(bnd[n])) if n in bnd else (x - np.log(1e3), x + np.log(1e3))
              for n, x in zip(names, x0, strict=True)]
    best_seen = {"cost": np.inf, "x": x0, "n": 0}
    seen: dict[bytes, float] = {}  # Nelder-Mead re-evaluates x0 (and clipped points): don't refilter
    t0 = time.perf_counter()

    def cost(x: np.ndarray) -> float:
        key = np.asarray(x, dtype=float).tobytes()
        if key in seen:
            return seen[key]
        if args.max_seconds is not None and time.perf_counter() - t0 > args.max_seconds:
            raise _BudgetError
        params = dict(zip(names, (sign * np.exp(x)).tolist(), strict=True))
        errs = [
            broad_errors(run_ours(args.algorithm, t, params), t["quat"], t["movement"])[0]
            for t in trials.values()
        ]
        c = float(np.mean(errs))
        c = c if np.isfinite(c) else 1e3
        best_seen["n"] += 1
        seen[key] = c
        if c < best_seen["cost"]:
            best_seen.update(cost=c, x=np.array(x, dtype=float))
        print(f"{c:7.3f}  " + " ".join(f"{n}={v:.4g}" for n, v in params.items()), flush=True)
        return c

    start = cost(x0)
    options = {"maxfev": args.maxfev, "xatol": 0.05, "fatol": 0.01}
    if args.step is not None:
        options["initial_simplex"] = np.vstack([x0, x0 + args.step * np.eye(len(x0))])
    stopped = ""
    try:
        minimize(cost, x0, method="Nelder-Mead", bounds=bounds, options=options)
    except _BudgetError:
        stopped = f" (stopped by --max-seconds {args.max_seconds:g})"
    fun, nfev = best_seen["cost"], best_seen["n"]
    best = dict(zip(names, (sign * np.exp(best_seen["x"])).tolist(), strict=True))
    took = time.perf_counter() - t0
    scope = f" (first {args.window:g} s of movement)" if args.window is not None else ""
    print(
        f"default {start:.3f}° → tuned {fun:.3f}° mean total RMSE on dev trials {DEV_TRIALS}{scope}; "
        f"{nfev} evaluations, {took:.0f} s{stopped}"
    )
    if args.write:
        data = yaml.safe_load(TUNED_PATH.read_text()) if TUNED_PATH.is_file() else {}
        data = data or {}
        algos = data.setdefault("algorithms", {})
        algos[args.algorithm] = {
            "params": {k: float(f"{v:.4g}") for k, v in best.items()},
            "tuning": {
                "dev_trials": list(DEV_TRIALS),
                **({"scoring": f"each dev trial cut {args.window:g} s after its first movement sample "
                               "(filtered from its start, movement samples before the cut scored)"}
                   if args.window is not None else {}),
                "searched": signed,
                "mean_total_rmse_deg": round(float(fun), 3),
                "default_rmse_deg": round(start, 3),
                "evaluations": int(nfev),
                "seconds": round(took),
                "command": f"benchmarks/tune_orientation.py {args.algorithm} --maxfev {args.maxfev}"
                + (f" --step {args.step:g}" if args.step is not None else "")
                + (f" --window {args.window:g}" if args.window is not None else "")
                + (f" --max-seconds {args.max_seconds:g}" if args.max_seconds is not None else "")
                + " --write",
            },
        }
        TUNED_PATH.write_text(
            "# Tuned once on the BROAD development trials (see benchmarks/tune_orientation.py).\n"
            + yaml.safe_dump(data, sort_keys=False)
        )
        print(f"written to {TUNED_PATH.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
