#!/usr/bin/env python3
"""Orientation filters on BROAD: accuracy (total / heading / inclination RMSE) and per-sample cost.

Usage: .venv/bin/python benchmarks/orientation.py [--trials 03,09] [--algorithms mahony,vqf]
                                                   [--no-peers] [--cost-samples 5000] [--schemes]

``--schemes``: instead, thesis ch. 4's table: every gain-regulated filter (Madgwick, Mahony, Guo,
Roetenberg) × every scheme it has (FOG, VST1, VST2, VST3, IAE), on the development and held-out
trials, and the thesis' Table 6 Madgwick gains (thigh, shank, foot; trained on Xsens MTw at 100 Hz)
run as given; the cost column is per ``update`` call fed tuples, as the node does. Parameters: with
``--params-dir DIR``, the file ``DIR/<filter>_<scheme>.yaml`` written by
``gait-biofeedback tune <filter> --scheme <scheme> --write DIR/<filter>_<scheme>.yaml`` (every scheme
tuned with the same budget: a fair comparison of the schemes); else the shipped tuned ones when they
were tuned for that scheme, else the filter's defaults for the scheme (marked "untuned").

Data: BROAD (Laidig, Caruso, Cereatti, Seel, "BROAD—A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7), 2021, CC BY 4.0) from ../shared/data/broad (never copied into the repo).
Metric (the dataset paper's): error quaternion q_est ⊗ conj(q_opt) in the world frame on the
``movement`` samples (with a finite reference); total angle, heading (rotation about world z) and
inclination (the remainder) RMSE in degrees. 6D results carry meaningful inclination only.
Our filters use the start-up step on the leading quiet samples (≤ 5 s: static gyro bias, reference
norms, initial attitude); the peers get the raw data, as they are meant to be used.
Cost: µs per ``update`` call, fed one sample at a time from numpy rows, as a ROS callback would.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.io

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gait_biofeedback.batch import ALGORITHMS, DEFAULT_ALGORITHM, estimate_orientation, load_tuned  # noqa: E402
from gait_biofeedback.batch import quaternion as quat  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "broad"
STARTUP_S = 5.0
# Development split used by benchmarks/tune_orientation.py (fixed, chosen before any result):
# three undisturbed (slow rotation, fast rotation with breaks, fast translation) and three disturbed
# (vibration, stationary magnet, attached magnet) trials; the other eight are held out.
DEV_TRIALS = ("03", "09", "15", "27", "31", "35")
# ahrs' Madgwick/Mahony reference frame is x = magnetic north, z up (NWU): ENU = R_z(+90°) · NWU.
NWU_TO_ENU = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])


def load_trials(select: list[str] | None = None) -> dict[str, dict[str, np.ndarray]]:
    """BROAD trials by name (``NN_description``), optionally only those whose number is in ``select``."""
    trials = {}
    for path in sorted(DATA.glob("*.mat")):
        if select and path.stem[:2] not in select:
            continue
        d = scipy.io.loadmat(path, squeeze_me=True)
        trials[path.stem] = {
            "gyr": np.ascontiguousarray(d["imu_gyr"], dtype=float),
            "acc": np.ascontiguousarray(d["imu_acc"], dtype=float),
            "mag": np.ascontiguousarray(d["imu_mag"], dtype=float),
            "quat": np.asarray(d["opt_quat"], dtype=float),
            "movement": np.asarray(d["movement"], dtype=bool),
            "rate": float(d["sampling_rate"]),
        }
    return trials


def broad_errors(q: np.ndarray, q_ref: np.ndarray, movement: np.ndarray) -> tuple[float, float, float]:
    """(total, heading, inclination) RMSE in degrees on movement samples (BROAD paper metric)."""
    ok = movement & np.isfinite(q_ref).all(1) & np.isfinite(q).all(1)
    e = quat.canonical(quat.multiply(quat.normalize(q[ok]), quat.conjugate(q_ref[ok])))
    total = 2.0 * np.arccos(np.clip(e[:, 0], -1.0, 1.0))
    heading = 2.0 * np.arctan2(e[:, 3], e[:, 0])
    heading = (heading + np.pi) % (2.0 * np.pi) - np.pi
    incl = 2.0 * np.arccos(np.clip(np.hypot(e[:, 0], e[:, 3]), -1.0, 1.0))
    return tuple(float(np.degrees(np.sqrt(np.mean(x**2)))) for x in (total, heading, incl))


def run_ours(name: str, t: dict[str, np.ndarray], params: dict) -> np.ndarray:
    """``name`` with the class's defaults and ``params`` over them (the tuned set when wanted is passed)."""
    return estimate_orientation(t["gyr"], t["acc"], t["mag"], t["rate"], name, startup_s=STARTUP_S,
                                tuned=False, **params)


def run_vqf(t: dict[str, np.ndarray]) -> np.ndarray:
    from vqf import VQF

    return VQF(1.0 / t["rate"]).updateBatch(t["gyr"], t["acc"], t["mag"])["quat9D"]


def _ahrs_filter(kind: str, rate: float):
    from ahrs.filters import Madgwick, Mahony

    return Madgwick(frequency=rate, gain=0.12) if kind == "madgwick" else Mahony(frequency=rate)


def run_ahrs(kind: str, t: dict[str, np.ndarray]) -> np.ndarray:
    from ahrs.filters import TRIAD  # noqa: F401  (import check only)

    f = _ahrs_filter(kind, t["rate"])
    q = np.array([1.0, 0.0, 0.0, 0.0])
    out = np.empty((len(t["gyr"]), 4))
    for i, (g, a, m) in enumerate(zip(t["gyr"], t["acc"], t["mag"], strict=True)):
        q = f.updateMARG(q, g, a, m)
        out[i] = q
    # Madgwick: NWU world (checked on BROAD rest data); Mahony: its heading frame was not matched in
    # the time available, so only its inclination column is meaningful.
    return quat.multiply(NWU_TO_ENU, out) if kind == "madgwick" else out


def cost_us(name: str, t: dict[str, np.ndarray], n: int, params: dict, method: str = "update",
            rows: str = "numpy") -> float:
    """Median-of-3 µs per ``method`` call, one sample per call (numpy rows, as from a message callback;
    ``rows="tuple"``: tuples of floats, as the ROS node passes them)."""
    g, a, m = ([row if rows == "numpy" else tuple(row.tolist()) for row in t[k][:n]]
               for k in ("gyr", "acc", "mag"))
    best = []
    for _ in range(3):
        if name == "vqf":
            from vqf import VQF

            f = VQF(1.0 / t["rate"])
            t0 = time.perf_counter()
            for i in range(n):
                f.update(g[i], a[i], m[i])
                f.getQuat9D()
        elif name.startswith("ahrs_"):
            f = _ahrs_filter(name[5:], t["rate"])
            q = np.array([1.0, 0.0, 0.0, 0.0])
            t0 = time.perf_counter()
            for i in range(n):
                q = f.updateMARG(q, g[i], a[i], m[i])
        else:
            f = ALGORITHMS[name](t["rate"], **params)
            f.update(g[0], a[0], m[0])  # initialise (and compile, for numba) outside the timing
            update = getattr(f, method)
            t0 = time.perf_counter()
            for i in range(n):
                update(g[i], a[i], m[i])
        best.append((time.perf_counter() - t0) / n * 1e6)
    return float(np.median(best))


# thesis Table 6 (orientation.md §4.6): Madgwick gains optimised on the thesis' first three participants
TABLE_6 = {
    ("fixed", "thigh"): (0.073, 6e-04), ("fixed", "shank"): (0.004, 6e-06), ("fixed", "foot"): (0.003, 1e-12),
    ("two_level", "thigh"): (0.082, 1e-05, 0.122, 0.051, 1e-12),
    ("two_level", "shank"): (0.050, 1e-05, 0.064, 0.085, 9e-05),
    ("two_level", "foot"): (0.045, 1e-12, 0.019, 0.404, 1e-25),
    ("three_level", "thigh"): (0.089, 0.005, 0.135, 0.052, 1e-18, 0.200, 0.201, 2e-14),
    ("three_level", "shank"): (0.082, 1e-03, 0.067, 0.086, 1e-18, 0.150, 0.128, 1e-04),
    ("three_level", "foot"): (0.050, 0.006, 0.100, 0.200, 1e-18, 0.204, 0.207, 1e-25),
}
TABLE_6_NAMES = {"fixed": ("beta1", "zeta"), "two_level": ("beta1", "beta2", "s_acc1", "s_mag1", "zeta"),
                 "three_level": ("beta1", "beta2", "s_acc1", "s_mag1", "beta3", "s_acc2", "s_mag2", "zeta")}
SCHEME_LABEL = {"fixed": "FOG", "two_level": "VST1", "three_level": "VST2", "fuzzy": "VST3", "iae": "IAE"}


def scheme_runs(params_dir: Path | None = None) -> list[tuple[str, str, str, dict]]:
    """(label, algorithm, parameter source, params) of every filter × scheme, then Table 6."""
    from gait_biofeedback.tuning.space import SPACES

    tuned = load_tuned()
    runs = []
    for name, schemes in SPACES.items():
        own = tuned.get(name, {})
        for scheme in schemes:
            path = params_dir / f"{name}_{scheme}.yaml" if params_dir else None
            if path is not None and path.is_file():
                params, source = {**load_tuned(path)[name], "scheme": scheme}, "tuned (dir)"
            elif own.get("scheme", ALGORITHMS[name].DEFAULTS.get("scheme")) == scheme and own:
                params, source = {**own, "scheme": scheme}, "tuned (shipped)"
            else:
                params, source = {"scheme": scheme}, "untuned"
            runs.append((f"{name} {SCHEME_LABEL[scheme]}", name, source, params))
    for (scheme, location), values in TABLE_6.items():
        params = {"scheme": scheme, **dict(zip(TABLE_6_NAMES[scheme], values, strict=True))}
        runs.append((f"madgwick {SCHEME_LABEL[scheme]} T6 {location}", "madgwick", "thesis Table 6", params))
    return runs


def scheme_table(trials: dict[str, dict[str, np.ndarray]], cost_samples: int,
                 params_dir: Path | None = None) -> None:
    """The ``--schemes`` table (module docstring)."""
    first = next(iter(trials.values()))
    print(f"BROAD, {len(trials)} trials ({sum(k[:2] in DEV_TRIALS for k in trials)} development); total RMSE "
          "in degrees (mean over trials; median in brackets); inclination: mean over all trials")
    print(f"{'filter / scheme':<30}{'parameters':<17}{'dev':>14}{'held-out':>14}{'inclination':>13}"
          f"{'µs/sample':>11}")
    for label, name, source, params in scheme_runs(params_dir):
        res = {k: broad_errors(run_ours(name, t, params), t["quat"], t["movement"])
               for k, t in trials.items()}
        dev = [v[0] for k, v in res.items() if k[:2] in DEV_TRIALS]
        test = [v[0] for k, v in res.items() if k[:2] not in DEV_TRIALS]
        cells = [f"{np.mean(x):.2f} ({np.median(x):.1f})" if x else "n/a" for x in (dev, test)]
        incl = np.mean([v[2] for v in res.values()])
        print(f"{label:<30}{source:<17}{cells[0]:>14}{cells[1]:>14}{incl:>13.2f}"
              f"{cost_us(name, first, cost_samples, params, rows='tuple'):>11.1f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", help="comma-separated trial numbers (default: all present)")
    ap.add_argument("--algorithms", help="comma-separated names (default: all ours + peers)")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--cost-samples", type=int, default=5000)
    ap.add_argument("--schemes", action="store_true", help="thesis ch. 4: every filter × gain scheme")
    ap.add_argument("--params-dir", type=Path, help="with --schemes: <filter>_<scheme>.yaml files from tune")
    args = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"BROAD not found at {DATA}: nothing to benchmark")
    trials = load_trials(args.trials.split(",") if args.trials else None)
    if args.schemes:
        scheme_table(trials, args.cost_samples, args.params_dir)
        return
    names = args.algorithms.split(",") if args.algorithms else list(ALGORITHMS)
    if not args.no_peers and not args.algorithms:
        names += ["vqf", "ahrs_madgwick", "ahrs_mahony"]
    tuned = load_tuned()
    results: dict[str, dict[str, tuple[float, float, float]]] = {n: {} for n in names}
    runtime = {}
    for n in names:
        t0 = time.perf_counter()
        for tname, t in trials.items():
            if n == "vqf":
                q = run_vqf(t)
            elif n.startswith("ahrs_"):
                q = run_ahrs(n[5:], t)
            else:
                q = run_ours(n, t, tuned.get(n, {}))
            results[n][tname] = broad_errors(q, t["quat"], t["movement"])
        runtime[n] = time.perf_counter() - t0
        print(f"# {n}: {runtime[n]:.1f} s for {len(trials)} trials", file=sys.stderr, flush=True)
    first = next(iter(trials.values()))
    cost = {n: cost_us(n, first, args.cost_samples, tuned.get(n, {})) for n in names}

    print(f"BROAD, {len(trials)} trials; cells: total/heading/inclination RMSE in degrees; "
          f"'*' = development trial (used for tuning); default algorithm = {DEFAULT_ALGORITHM}")
    width = 17
    print(f"{'trial':<34}" + "".join(f"{n[:width - 1]:>{width}}" for n in names))
    for tname in trials:
        mark = "*" if tname[:2] in DEV_TRIALS else " "
        row = "".join(f"{'{:.1f}/{:.1f}/{:.1f}'.format(*results[n][tname]):>{width}}" for n in names)
        print(f"{mark}{tname[:33]:<33}{row}")
    for label, sel in (("mean total (all)", None), ("median total (all)", None),
                       ("mean total (held-out)", "test"), ("mean total (dev)", "dev")):
        vals = []
        for n in names:
            tot = [v[0] for k, v in results[n].items()
                   if sel is None or (sel == "dev") == (k[:2] in DEV_TRIALS)]
            vals.append(np.median(tot) if label.startswith("median") else np.mean(tot) if tot else np.nan)
        print(f"{label:<34}" + "".join(f"{v:>{width}.2f}" for v in vals))
    incl = [np.mean([v[2] for v in results[n].values()]) for n in names]
    print(f"{'mean inclination (all)':<34}" + "".join(f"{v:>{width}.2f}" for v in incl))
    print(f"{'update cost, µs/sample':<34}" + "".join(f"{cost[n]:>{width}.1f}" for n in names))
    if "vqf" in cost:
        print(f"{'cost / VQF':<34}" + "".join(f"{cost[n] / cost['vqf']:>{width}.1f}" for n in names))
    if "inertial_cf" in names:
        p = tuned.get("inertial_cf", {})
        extra = {
            "update, numpy rows (as above)": cost["inertial_cf"],
            "update, tuples (ROS node)": cost_us("inertial_cf", first, args.cost_samples, p, rows="tuple"),
            "update_tuple, tuples": cost_us("inertial_cf", first, args.cost_samples, p, "update_tuple",
                                            "tuple"),
            "update, pure Python (no numba)": cost_us("inertial_cf", first, args.cost_samples,
                                                      {**p, "use_numba": False}),
        }
        numba_on = ALGORITHMS["inertial_cf"](first["rate"], **p).numba
        print(f"inertial_cf cost (µs/sample; numba {'on' if numba_on else 'not available'}): "
              + "; ".join(f"{k} {v:.2f}" + (f" ({v / cost['vqf']:.1f}× VQF)" if "vqf" in cost else "")
                          for k, v in extra.items()))


if __name__ == "__main__":
    main()
