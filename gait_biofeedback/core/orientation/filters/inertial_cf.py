"""Inertial-frame complementary filter: split inclination / heading corrections, rest and motion bias.

A complementary filter built from the thesis' design checklist (orientation.md §2.7) and published
ideas, written from the papers' descriptions (no code of any implementation was read or copied):

* strap-down of the bias-corrected gyro into an almost-inertial frame I, exact exponential
  (checklist block 3; orientation.md §2.2): q_g ← q_g ⊗ exp(½ (y_G − b) dt);
* accelerometer correction low-pass filtered *in frame I*, where gravity is constant and the segment
  accelerations of bounded-velocity motion average out (Laidig & Seel, "VQF: Highly accurate IMU
  orientation estimation with bias estimation and magnetic disturbance rejection", Information
  Fusion 91:187–204, 2023, §3.2): a_I = R(q_g) a / ‖y_A,stat‖, a_lp ← a_lp + k (a_I − a_lp) with
  k = dt/(τ_acc + dt); the inclination correction q_a (I → 6D earth frame) is then rotated by the
  shortest rotation that makes R(q_a) a_lp vertical (the low-pass sets the time constant);
* heading-only magnetometer correction (checklist block 6; Seel & Ruppin, "Eliminating the effect of
  magnetic disturbances on the inclination estimates of inertial sensors", IFAC-PapersOnLine
  50(1):8798–8803, 2017): the field in the 6D earth frame m_E = R(q_a ⊗ q_g) m gives the heading
  offset ψ = atan2(m_E,x, m_E,y) (horizontal field → +y, north); δ ← δ + dt/(τ_mag + dt)·wrap(ψ − δ);
  the output is q = R_z(δ) ⊗ q_a ⊗ q_g, so the magnetometer can never tilt the estimate;
* magnetic disturbance detection and rejection on field norm and dip angle (checklist block 7,
  thesis Eq 49 signal; Laidig & Seel 2023 §3.4): rejected while |‖m‖ − n_ref| > mag_norm_th·n_ref or
  |dip − dip_ref| > mag_dip_th; a field that stays at a new (norm, dip) for ``mag_new_time`` becomes the
  reference; after ``mag_max_reject`` s of rejection the magnetometer is used again; after a
  rejection of ≥ 1 s or a new reference the heading converges with ``tau_mag_fast`` for ``fast_time``;
* separate inclination and heading gains as time constants (checklist block 9);
* gyro bias: static start-up bias (checklist block 1, thesis §5.2.8) plus an online estimate
  (block 2): at rest (low-passed gyro and accelerometer deviations below ``rest_gyr``, ``rest_acc`` for
  ``rest_time`` s, Laidig & Seel 2023 §3.3) b ← low-pass of the gyro with ``tau_rest``; in motion a
  Mahony-type integral of the inclination correction (Mahony, Hamel & Pflimlin, IEEE TAC
  53(5):1203–1218, 2008): b ← b − R(q6)ᵀ c / τ_bias, c the correction rotation vector of the sample
  (horizontal axes only are observable); ‖b‖ ≤ ``bias_max``.

READINGs / project choices: first-order low-pass filters (dt/(τ + dt), exact for any dt the node
passes) instead of higher-order ones; the inclination step is a full rotation onto the low-passed
vector; the first magnetometer sample (after a 6D start) sets δ directly. Parameters are time
constants in s, angular rates in rad/s, ``rest_acc`` in g, ``mag_norm_th`` relative, ``mag_dip_th``
rad. ``mag_reject_norm`` / ``mag_reject_dip`` of the base class, when given, replace ``mag_norm_th`` /
``mag_dip_th`` (this filter does its own detection). The per-sample arithmetic is in
:mod:`~gait_biofeedback.core.orientation.filters._inertial_kernel` (numba when installed, else pure
Python, same numbers).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.jit import compiled, plain
from gait_biofeedback.core.orientation.filters import _inertial_kernel as ik
from gait_biofeedback.core.orientation.filters.base import OrientationFilter


def _warmup() -> tuple:
    s = np.zeros(ik.N_STATE)
    s[ik.QG] = s[ik.QA] = s[ik.OUT] = s[ik.ACC_NORM] = 1.0
    return (s, np.ones(len(ik.PARAM_NAMES)), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, -1.0, True, 0.01)


def _run_warmup() -> tuple:
    s, p, *sample = _warmup()
    return (s, p, np.array(sample[0:3]), np.array(sample[3:6]), np.array(sample[6:9]), np.array([True]),
            np.array([0.01]), np.empty(7))


class InertialCF(OrientationFilter):
    """Complementary filter: inertial-frame accelerometer low-pass, heading-only magnetometer."""

    name = "inertial_cf"
    # the untuned starting point (time constants as in Laidig & Seel 2023's order of magnitude, thresholds
    # a priori); the tuned values the node and the batch functions use are in
    # config/orientation_filters.yaml (BROAD development trials, Nelder-Mead, see the YAML's record)
    DEFAULTS: ClassVar[dict[str, Any]] = {
        "tau_acc": 3.0,
        "tau_mag": 9.0,
        "tau_bias": 0.0,  # motion bias integral off: it made BROAD worse (see the report); > 0 enables
        "tau_rest": 2.0,
        "rest_gyr": 0.035,
        "rest_acc": 0.05,
        "rest_time": 1.5,
        "bias_max": 0.035,
        "mag_norm_th": 0.1,
        "mag_dip_th": math.radians(10.0),
        "mag_new_time": 20.0,
        "mag_max_reject": 60.0,
        "tau_mag_fast": 1.0,
        "fast_time": 3.0,
        "tau_rest_lp": 0.5,
        "mag_accept_time": 1.0,
        "acc_stages": 2,
        "use_numba": True,
    }

    def __init__(self, rate_hz: float, *, rest_gyr: float | None = None, rest_acc: float | None = None,
                 **params: Any) -> None:
        # rest_gyr / rest_acc are keywords of the base class too: taken here, so that they reach the kernel
        super().__init__(rate_hz, rest_gyr=self.DEFAULTS["rest_gyr"] if rest_gyr is None else rest_gyr,
                         rest_acc=self.DEFAULTS["rest_acc"] if rest_acc is None else rest_acc, **params)

    # ------------------------------------------------------------------ configuration and state
    def _configure(self, params: dict[str, Any]) -> None:
        values = {k: float(params[k]) for k in ik.PARAM_NAMES}
        params["rest_gyr"], params["rest_acc"] = self.rest_gyr, self.rest_acc
        values["rest_gyr"], values["rest_acc"] = float(self.rest_gyr), float(self.rest_acc)
        if self.mag_reject_norm is not None:
            values["mag_norm_th"] = float(self.mag_reject_norm)
        if self.mag_reject_dip is not None:
            values["mag_dip_th"] = float(self.mag_reject_dip)
        for k in ("tau_acc", "tau_mag", "tau_rest", "tau_mag_fast", "tau_rest_lp"):
            if not values[k] >= 0.0:
                raise ValueError(f"{self.name}: {k} must be >= 0, got {values[k]}")
        kernel = compiled(ik, "step", _warmup()) if params["use_numba"] else None
        self.numba = kernel is not None
        if kernel is not None:
            self._kernel = kernel
            self._p = np.array([values[k] for k in ik.PARAM_NAMES])
            self._s = np.zeros(ik.N_STATE)
            self._out = self._out_array
        else:
            self._kernel = plain(ik, "step")
            self._p = [values[k] for k in ik.PARAM_NAMES]
            self._s = [0.0] * ik.N_STATE
            self._out = self._out_list
        self._s[ik.OUT] = 1.0
        self._gating = False  # the base-class gate is folded into mag_norm_th / mag_dip_th

    def _out_array(self) -> np.ndarray:
        return self._s[ik.OUT:ik.OUT + 4].copy()

    def _out_list(self) -> np.ndarray:
        return np.array(self._s[ik.OUT:ik.OUT + 4])

    # the base class keeps q, rest and disturbance flags in attributes: map them onto the flat state
    @property
    def _q(self) -> tuple[float, float, float, float]:  # type: ignore[override]
        s = self._s
        return (float(s[ik.OUT]), float(s[ik.OUT + 1]), float(s[ik.OUT + 2]), float(s[ik.OUT + 3]))

    @_q.setter
    def _q(self, q: tuple[float, float, float, float]) -> None:
        for i in range(4):
            self._s[ik.OUT + i] = float(q[i])

    @property
    def _rest(self) -> bool:  # type: ignore[override]
        return bool(self._s[ik.REST] != 0.0)

    @_rest.setter
    def _rest(self, value: bool) -> None:
        self._s[ik.REST] = 1.0 if value else 0.0

    @property
    def _mag_disturbed(self) -> bool:  # type: ignore[override]
        return bool(self._s[ik.MDIST] != 0.0)

    @_mag_disturbed.setter
    def _mag_disturbed(self, value: bool) -> None:
        self._s[ik.MDIST] = 1.0 if value else 0.0

    def _reset_state(self) -> None:
        s = self._s
        keep = [s[ik.OUT + i] for i in range(4)]
        for i in range(ik.N_STATE):
            s[i] = 0.0
        for i in range(4):
            s[ik.OUT + i] = keep[i]
        s[ik.QG] = s[ik.QA] = 1.0

    def _on_initialize(self) -> None:
        """Attitude set from vectors (or ``reset(q)``): q_g = 1, q_a = q, δ = 0, a_lp = R(q)ᵀ-up."""
        s = self._s
        self._reset_state()
        w, x, y, z = self._q
        s[ik.QA], s[ik.QA + 1], s[ik.QA + 2], s[ik.QA + 3] = w, x, y, z
        s[ik.ALP] = 2.0 * (x * z - w * y)
        s[ik.ALP + 1] = 2.0 * (w * x + y * z)
        s[ik.ALP + 2] = 1.0 - 2.0 * (x * x + y * y)
        s[ik.ACCLP:ik.ACCLP + 3] = [s[ik.ALP], s[ik.ALP + 1], s[ik.ALP + 2]]
        s[ik.ALP1:ik.ALP1 + 3] = [s[ik.ALP], s[ik.ALP + 1], s[ik.ALP + 2]]
        for i in range(3):
            s[ik.SBIAS + i] = float(self.static_bias[i])
        s[ik.ACC_NORM] = float(self.acc_norm) if self.acc_norm else 1.0
        s[ik.MAG_NORM] = float(self.mag_norm) if self.mag_norm else 0.0
        if self._mag_ref is not None:
            north, up = self._mag_ref
            s[ik.MREF_N] = math.hypot(north, up)
            s[ik.MREF_DIP] = math.atan2(up, north)
            s[ik.CAND_N], s[ik.CAND_DIP] = s[ik.MREF_N], s[ik.MREF_DIP]
            s[ik.MREF_SET] = 1.0
            s[ik.UND_T] = float(self.params["mag_accept_time"])  # trusted at start

    def _online_bias(self) -> np.ndarray:
        return np.array([float(self._s[ik.BIAS + i]) for i in range(3)])

    def _extra_state(self) -> dict[str, Any]:
        s = self._s
        return {
            "numba": self.numba,
            "heading_offset": float(s[ik.DELTA]),
            "inclination_q": np.array([float(s[ik.QA + i]) for i in range(4)]),
            "acc_lowpass_inertial": np.array([float(s[ik.ALP + i]) for i in range(3)]),
            "mag_reference": (float(s[ik.MREF_N]), float(s[ik.MREF_DIP])) if s[ik.MREF_SET] else None,
        }

    # ------------------------------------------------------------------ hot path
    def update(self, gyr: Any, acc: Any, mag: Any = None, dt: float | None = None) -> np.ndarray:
        """One sample (see :meth:`OrientationFilter.update`); the arithmetic runs in the kernel."""
        if not self._initialized:
            return super().update(gyr, acc, mag, dt)  # skips invalid samples, initialises from vectors
        self._call(gyr, acc, mag, dt)
        return self._out()

    def update_tuple(self, gyr: Any, acc: Any, mag: Any = None,
                     dt: float | None = None) -> tuple[float, float, float, float]:
        """Like :meth:`update` but returns a plain tuple (w, x, y, z): the cheapest call per sample."""
        if not self._initialized:
            return tuple(super().update(gyr, acc, mag, dt).tolist())
        self._call(gyr, acc, mag, dt)
        s = self._s
        return (s[ik.OUT], s[ik.OUT + 1], s[ik.OUT + 2], s[ik.OUT + 3])

    def _call(self, gyr: Any, acc: Any, mag: Any, dt: float | None) -> None:
        # numpy rows → Python floats via tolist(); other sequences through float() so that numba
        # always sees the one (float64) signature it compiled
        if type(gyr) is np.ndarray:
            gx, gy, gz = gyr.tolist()
        else:
            gx, gy, gz = float(gyr[0]), float(gyr[1]), float(gyr[2])
        if type(acc) is np.ndarray:
            ax, ay, az = acc.tolist()
        else:
            ax, ay, az = float(acc[0]), float(acc[1]), float(acc[2])
        if mag is None:
            mx = my = mz = 0.0
        elif type(mag) is np.ndarray:
            mx, my, mz = mag.tolist()
        else:
            mx, my, mz = float(mag[0]), float(mag[1]), float(mag[2])
        if self._kernel(self._s, self._p, gx, gy, gz, ax, ay, az, mx, my, mz, mag is not None,
                        self.dt if dt is None else float(dt)):
            self._skipped += 1

    def update_batch(self, gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray, has_mag: np.ndarray,
                     dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`OrientationFilter.update_batch` in the kernel's loop
        (:func:`~gait_biofeedback.core.orientation.filters._inertial_kernel.run`, compiled when
        :meth:`update` is): the same numbers as sample by sample."""
        if not self._initialized or not len(dt):
            return super().update_batch(gyr, acc, mag, has_mag, dt)
        n = len(dt)
        runner = compiled(ik, "run", _run_warmup(), ("step",)) if self.numba else None
        if runner is not None:
            out = np.empty(7 * n)
            flat = [np.ascontiguousarray(v, float).ravel() for v in (gyr, acc, mag)]
            skipped = runner(self._s, self._p, *flat, np.ascontiguousarray(has_mag, bool),
                             np.ascontiguousarray(dt, float), out)
        else:  # the pure-Python twin, on lists as :meth:`update` runs it
            flat = [0.0] * (7 * n)
            skipped = plain(ik, "run")(self._s, self._p, gyr.ravel().tolist(), acc.ravel().tolist(),
                                       mag.ravel().tolist(), has_mag.tolist(), dt.tolist(), flat)
            out = np.array(flat)
        self._skipped += skipped
        out = out.reshape(n, 7)
        return out[:, :4].copy(), out[:, 4:].copy()

    def gyro_bias(self) -> np.ndarray:
        """Total gyro bias (static + online, rad/s): the cheap per-sample form of ``state()["gyro_bias"]``."""
        s = self._s
        return np.array([s[ik.SBIAS] + s[ik.BIAS], s[ik.SBIAS + 1] + s[ik.BIAS + 1],
                         s[ik.SBIAS + 2] + s[ik.BIAS + 2]])
