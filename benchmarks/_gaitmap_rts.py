"""Run gaitmap's RtsKalman (PyPI ``gaitmap``) on arrays; executed by ``benchmarks/spatial.py`` inside
its own venv (gaitmap is not a project dependency). ``python _gaitmap_rts.py IN.npz OUT.npz``: IN has
``gyr`` (rad/s), ``acc`` (m/s²), ``rate``; OUT gets ``position`` (N, 3), gaitmap's default parameters,
initial orientation from the first second's gravity."""

import sys

import numpy as np
import pandas as pd
from gaitmap.trajectory_reconstruction import RtsKalman
from gaitmap.utils.rotations import get_gravity_rotation

data = np.load(sys.argv[1])
gyr, acc, rate = data["gyr"], data["acc"], float(data["rate"])
frame = pd.DataFrame(np.hstack([acc, np.degrees(gyr)]),
                     columns=["acc_x", "acc_y", "acc_z", "gyr_x", "gyr_y", "gyr_z"])
start = get_gravity_rotation(acc[: max(1, int(rate))].mean(axis=0))
result = RtsKalman(initial_orientation=start).estimate(frame, sampling_rate_hz=rate)
position = np.asarray(result.position_)[1:]  # gaitmap adds the initial sample
np.savez(sys.argv[2], position=position)
