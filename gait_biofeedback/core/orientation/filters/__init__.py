"""Orientation filters (orientation.md): one streaming interface, one batch entry point.

Every filter: ``cls(rate_hz, **params)``, ``reset(q=None)``, ``initialize(acc, mag=None)``,
``calibrate(StartupCalibration)``, ``update(gyr, acc, mag=None, dt=None) -> q`` (w, x, y, z),
sensor → world ENU, ``gyro_bias()`` (cheap per-sample bias estimate) and ``state() -> dict`` for
diagnostics; :class:`InertialCF` also has ``update_tuple`` (same numbers, returns a tuple). Batch:
:func:`estimate_orientation`. ``DEFAULT_ALGORITHM`` is the most accurate one in
``benchmarks/orientation.py`` among those within the per-sample cost budget
(``docs/benchmarks/orientation.md``).
"""

from __future__ import annotations

from gait_biofeedback.core.orientation.filters.base import OrientationFilter
from gait_biofeedback.core.orientation.filters.batch import estimate_orientation
from gait_biofeedback.core.orientation.filters.guo_fkf import GuoFKF
from gait_biofeedback.core.orientation.filters.inertial_cf import InertialCF
from gait_biofeedback.core.orientation.filters.madgwick import MadgwickFilter
from gait_biofeedback.core.orientation.filters.mahony import MahonyFilter
from gait_biofeedback.core.orientation.filters.nazarahari_lkf import NazarahariLKF
from gait_biofeedback.core.orientation.filters.nazarahari_rekf import NazarahariREKF
from gait_biofeedback.core.orientation.filters.roetenberg_ikf import RoetenbergIKF
from gait_biofeedback.core.orientation.filters.startup import (
    StartupCalibration,
    attitude_from_vectors,
    calibrate_from_rest,
    quiet_samples,
)
from gait_biofeedback.core.orientation.filters.yi_cf import YiCF
from gait_biofeedback.core.orientation.filters.zihajehzadeh_ckf import ZihajehzadehCKF

ALGORITHMS: dict[str, type[OrientationFilter]] = {
    "guo_fkf": GuoFKF,
    "inertial_cf": InertialCF,
    "madgwick": MadgwickFilter,
    "mahony": MahonyFilter,
    "nazarahari_rekf": NazarahariREKF,
    "nazarahari_lkf": NazarahariLKF,
    "roetenberg_ikf": RoetenbergIKF,
    "yi_cf": YiCF,
    "zihajehzadeh_ckf": ZihajehzadehCKF,
}
DEFAULT_ALGORITHM = "inertial_cf"  # lowest mean total RMSE of ours on BROAD (benchmarks/orientation.py)

__all__ = [
    "ALGORITHMS",
    "DEFAULT_ALGORITHM",
    "GuoFKF",
    "InertialCF",
    "MadgwickFilter",
    "MahonyFilter",
    "NazarahariLKF",
    "NazarahariREKF",
    "OrientationFilter",
    "RoetenbergIKF",
    "StartupCalibration",
    "YiCF",
    "ZihajehzadehCKF",
    "attitude_from_vectors",
    "calibrate_from_rest",
    "estimate_orientation",
    "quiet_samples",
]
