#!/usr/bin/env python3
"""Orientation filters on BROAD: accuracy (total / heading / inclination RMSE) and per-sample cost.

Usage: .venv/bin/python benchmarks/orientation.py [--trials 03,09] [--algorithms mahony,vqf]
                                                   [--no-peers] [--cost-samples 5000]

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
    return estimate_orientation(t["gyr"], t["acc"], t["mag"], t["rate"], name, startup_s=STARTUP_S, **params)


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", help="comma-separated trial numbers (default: all present)")
    ap.add_argument("--algorithms", help="comma-separated names (default: all ours + peers)")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--cost-samples", type=int, default=5000)
    args = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"BROAD not found at {DATA}: nothing to benchmark")
    trials = load_trials(args.trials.split(",") if args.trials else None)
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
