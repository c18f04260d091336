"""Importer of the pyshoe foot-mounted INS data set's Vicon trials (Wagstaff et al. 2020).

One trial is one MAT v5 file (``2017-11-22-11-22-03.mat``): ``ts`` (s, about 200 Hz), ``imu`` (N, 6)
= accelerometer (m/s²) then gyroscope (rad/s) of the IMU on top of the right shoe, ``gt`` (N, 3) the
Vicon position of the shoe (m), ``zv_<detector>_opt`` the zero-velocity labels of five detectors,
each at the threshold that was best for that trial, and ``trial_error``/``best_error`` their errors.
The IMU's z axis points down (the accelerometer reads about -9.8 m/s² on z at rest): the graph's foot
calibration takes any mounting, so the axes are imported as they are.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.io.recording import Recording

PYSHOE_SEGMENT = "right_foot"
PYSHOE_VARIABLES = frozenset({"ts", "imu", "gt"})
DETECTORS = ("shoe", "ared", "amvd", "mbgtd", "vicon")


def is_pyshoe(variables: set[str]) -> bool:
    """Whether a .mat file's variable names are those of a pyshoe trial."""
    return variables >= PYSHOE_VARIABLES and any(v.startswith("zv_") for v in variables)


def import_pyshoe(path: str | Path) -> Recording:
    """Read one pyshoe Vicon trial → a :class:`Recording` with ``right_foot`` (no magnetometer).

    ``reference``: ``position`` (N, 3) m, the Vicon shoe position at the IMU's sample times (the
    Vicon frame is left-handed in x-y: mirror y before comparing it with an ENU trajectory, see
    ``benchmarks/spatial.py``); ``zero_velocity`` detector → (N,) bool; ``best_error`` m, the
    data set's best detector error. ValueError naming what is missing for a file of another kind."""
    from scipy.io import loadmat

    path = Path(path)
    data: dict[str, Any] = loadmat(path, squeeze_me=True)
    missing = sorted(PYSHOE_VARIABLES - set(data))
    if missing:
        raise ValueError(f"{path}: not a pyshoe Vicon trial: variables {missing} missing "
                         f"(it holds {sorted(k for k in data if not k.startswith('__'))})")
    t = np.asarray(data["ts"], dtype=float).reshape(-1)
    imu = np.asarray(data["imu"], dtype=float)
    if imu.ndim != 2 or imu.shape != (len(t), 6):
        raise ValueError(f"{path}: 'imu' must be (N, 6) acc then gyro for the {len(t)} samples of 'ts', "
                         f"got {imu.shape}")
    position = np.asarray(data["gt"], dtype=float).reshape(len(t), 3)
    zero_velocity = {name: np.asarray(data[f"zv_{name}_opt"]).reshape(-1).astype(bool)
                     for name in DETECTORS if f"zv_{name}_opt" in data}
    reference = {"position": position, "zero_velocity": zero_velocity,
                 "best_error": float(data.get("best_error", np.nan))}
    series = ImuSeries(PYSHOE_SEGMENT, t - t[0], imu[:, :3], imu[:, 3:])
    return Recording({PYSHOE_SEGMENT: series}, f"pyshoe {path}", reference)
