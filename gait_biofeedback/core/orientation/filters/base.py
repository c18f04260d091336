"""Shared streaming-filter machinery: input checks, start-up state, normalisation, magnetic gating.

Every algorithm subclasses :class:`OrientationFilter` and implements ``_step`` on plain floats.
``update`` does, per sample (orientation.md §1.2, §2.7):
1. skip the sample and keep the last good state if gyro or accelerometer holds NaN/inf (a NaN
   magnetometer only drops the magnetometer for that sample);
2. on the first valid sample, if not initialised yet, set the attitude from the vectors and return;
3. subtract the static gyro bias of the start-up step;
4. divide the accelerometer by ‖y_A,stat‖ (gravity = 1, thesis §5.2.1.2) and the magnetometer by
   ‖y_M,stat‖ (any unit becomes dimensionless); the first valid sample sets a missing reference;
5. magnetic-disturbance gating (thesis §2.7 block 7, field strength and dip angle): the magnetometer
   is ignored for the sample when |‖m‖/‖m_stat‖ − 1| > ``mag_reject_norm`` or when the dip, measured
   against the estimated up vector, is off its reference by more than ``mag_reject_dip`` (rad);
6. call ``_step`` with the deviations Δ_A, Δ_M used by gain regulation (thesis Eq 23).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from gait_biofeedback.core.orientation.filters import _scalar as sq
from gait_biofeedback.core.orientation.filters.startup import StartupCalibration, attitude_from_vectors


class OrientationFilter:
    """Streaming orientation filter: ``update(gyr, acc, mag=None, dt=None) -> q`` (w, x, y, z)."""

    name = "base"
    DEFAULTS: ClassVar[dict[str, Any]] = {}

    def __init__(self, rate_hz: float, *, gyro_bias: Any = (0.0, 0.0, 0.0),
                 acc_norm: float | None = None, mag_norm: float | None = None,
                 mag_reject_norm: float | None = None,
                 mag_reject_dip: float | None = None, rest_gyr: float = 0.05, rest_acc: float = 0.02,
                 **params: Any) -> None:
        if not (rate_hz > 0.0 and math.isfinite(rate_hz)):
            raise ValueError(f"rate_hz must be positive, got {rate_hz}")
        unknown = set(params) - set(self.DEFAULTS)
        if unknown:
            raise TypeError(f"{self.name}: unknown parameters {sorted(unknown)}; "
                            f"known: {sorted(self.DEFAULTS)}")
        self.rate_hz = float(rate_hz)
        self.dt = 1.0 / self.rate_hz
        self.params = {**self.DEFAULTS, **params}
        self.static_bias = tuple(float(b) for b in gyro_bias)
        self.acc_norm = acc_norm
        self.mag_norm = mag_norm
        self.mag_reject_norm = mag_reject_norm
        self.mag_reject_dip = mag_reject_dip
        self.rest_gyr = rest_gyr
        self.rest_acc = rest_acc
        self._mag_ref: tuple[float, float] | None = None  # world field (north, up), normalised
        self._configure(self.params)
        self.reset()

    # ----------------------------------------------------------------- public API
    def reset(self, q: Any = None) -> None:
        """Forget the estimate; ``q`` given → start from it (initialised), else wait for a sample.

        The reference norms and the world magnetic reference (environment, not state) are kept;
        :meth:`initialize` / :meth:`calibrate` set them anew.
        """
        self._initialized = q is not None
        self._q: sq.Quat = (1.0, 0.0, 0.0, 0.0) if q is None else sq.normalized(tuple(float(v) for v in q))
        self._skipped = 0
        self._rest = False
        self._mag_disturbed = False
        self._reset_state()
        if q is not None:
            self._on_initialize()

    def calibrate(self, cal: StartupCalibration) -> np.ndarray:
        """Apply a start-up calibration: static bias, reference norms and initial attitude."""
        self.static_bias = tuple(float(b) for b in cal.gyro_bias)
        self.acc_norm = cal.acc_norm
        self.mag_norm = cal.mag_norm
        return self.initialize(cal.acc_mean, cal.mag_mean)

    def initialize(self, acc: Any, mag: Any = None) -> np.ndarray:
        """Attitude from one accelerometer (+ magnetometer) vector (TRIAD, thesis Eq 9); returns q."""
        acc = np.asarray(acc, dtype=float)
        if self.acc_norm is None:
            self.acc_norm = float(np.linalg.norm(acc))
        if mag is not None:
            mag = np.asarray(mag, dtype=float)
            if not np.isfinite(mag).all():
                mag = None
            elif self.mag_norm is None:
                self.mag_norm = float(np.linalg.norm(mag))
        q = attitude_from_vectors(acc, mag)
        self._q = tuple(float(v) for v in q)
        self._initialized = True
        if mag is not None:
            self._set_mag_ref(tuple(float(v) / self.mag_norm for v in mag))
        self._on_initialize()
        return np.array(self._q)

    def update(self, gyr: Any, acc: Any, mag: Any = None, dt: float | None = None) -> np.ndarray:
        """One sample: gyro (rad/s), accelerometer (m/s²), magnetometer (any unit) → q (w, x, y, z)."""
        gx, gy, gz = gyr.tolist() if hasattr(gyr, "tolist") else gyr
        ax, ay, az = acc.tolist() if hasattr(acc, "tolist") else acc
        s = gx + gy + gz + ax + ay + az
        if s - s != 0.0 or (dt is not None and not dt > 0.0):
            self._skipped += 1
            return np.array(self._q)
        m = None
        if mag is not None:
            mx, my, mz = mag.tolist() if hasattr(mag, "tolist") else mag
            sm = mx + my + mz
            if sm - sm == 0.0 and (mx != 0.0 or my != 0.0 or mz != 0.0):
                m = (mx, my, mz)
        if not self._initialized:
            self.initialize((ax, ay, az), m)
            return np.array(self._q)
        bx, by, bz = self.static_bias
        gx -= bx
        gy -= by
        gz -= bz
        ka = 1.0 / self.acc_norm
        ax *= ka
        ay *= ka
        az *= ka
        na = math.sqrt(ax * ax + ay * ay + az * az)
        dev_acc = abs(na - 1.0)
        self._rest = dev_acc < self.rest_acc and gx * gx + gy * gy + gz * gz < self.rest_gyr * self.rest_gyr
        dev_mag = None
        if m is not None:
            if self.mag_norm is None:
                self.mag_norm = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
            km = 1.0 / self.mag_norm
            m = (m[0] * km, m[1] * km, m[2] * km)
            nm = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
            dev_mag = abs(nm - 1.0)
            if self._mag_ref is None:
                self._set_mag_ref(m)
            m = self._gate_mag(m, nm, dev_mag)
        q = self._step(gx, gy, gz, ax, ay, az, m, dt or self.dt, dev_acc, dev_mag)
        if q[0] - q[0] != 0.0:  # numerical failure: keep the last good state
            self._skipped += 1
            return np.array(self._q)
        self._q = q
        return np.array(q)

    def update_batch(self, gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray, has_mag: np.ndarray,
                     dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """n samples (rows of ``gyr``, ``acc``, ``mag`` (n, 3); ``has_mag`` (n,): the row of ``mag`` is a
        sample, else none; ``dt`` (n,) s) → (q (n, 4), total gyro bias (n, 3)) after each: what :meth:`update`
        and :meth:`gyro_bias` give sample by sample (as vqf's ``updateBatch``). Here that loop; a filter
        with a compiled kernel overrides it."""
        n = len(dt)
        q, bias = np.empty((n, 4)), np.empty((n, 3))
        g_rows, a_rows, m_rows = gyr.tolist(), acc.tolist(), mag.tolist()
        for i, (d, m) in enumerate(zip(dt.tolist(), has_mag.tolist(), strict=True)):
            q[i] = self.update(g_rows[i], a_rows[i], m_rows[i] if m else None, d)
            bias[i] = self.gyro_bias()
        return q, bias

    @property
    def initialized(self) -> bool:
        """True once an attitude was set (first valid sample, ``initialize`` or ``reset(q)``)."""
        return self._initialized

    @property
    def q(self) -> np.ndarray:
        """Current orientation (w, x, y, z), sensor → world ENU."""
        return np.array(self._q)

    def gyro_bias(self) -> np.ndarray:
        """Total gyro bias estimate (static + online, rad/s): the cheap per-sample form of
        ``state()["gyro_bias"]`` (no diagnostics dict)."""
        return np.array(self.static_bias) + self._online_bias()

    def state(self) -> dict[str, Any]:
        """Read-only diagnostics: attitude, bias estimate, rest and magnetic-disturbance flags."""
        return {
            "algorithm": self.name,
            "q": np.array(self._q),
            "initialized": self._initialized,
            "gyro_bias": self.gyro_bias(),
            "rest": self._rest,
            "mag_disturbed": self._mag_disturbed,
            "skipped_samples": self._skipped,
            **self._extra_state(),
        }

    # ----------------------------------------------------------------- helpers
    def _set_mag_ref(self, m: sq.Vec) -> None:
        """World reference field (horizontal north component, vertical component), normalised units."""
        hx, hy, hz = sq.to_world(self._q, *m)
        self._mag_ref = (math.hypot(hx, hy), hz)

    def _gate_mag(self, m: sq.Vec, nm: float, dev_mag: float) -> sq.Vec | None:
        disturbed = False
        if self.mag_reject_norm is not None and dev_mag > self.mag_reject_norm:
            disturbed = True
        elif self.mag_reject_dip is not None and self._mag_ref is not None:
            ux, uy, uz = sq.up_in_sensor(self._q)
            sin_dip = (ux * m[0] + uy * m[1] + uz * m[2]) / nm
            ref_n, ref_u = self._mag_ref
            ref = ref_u / math.hypot(ref_n, ref_u)
            disturbed = abs(math.asin(max(-1.0, min(1.0, sin_dip))) - math.asin(max(-1.0, min(1.0, ref)))) \
                > self.mag_reject_dip
        self._mag_disturbed = disturbed
        return None if disturbed else m

    # ----------------------------------------------------------------- subclass hooks
    def _configure(self, params: dict[str, Any]) -> None:
        """Validate and store algorithm parameters (called once from ``__init__``)."""

    def _reset_state(self) -> None:
        """Reset algorithm-specific state (bias estimate, covariance, …)."""

    def _on_initialize(self) -> None:
        """Called after the attitude was set from vectors."""

    def _online_bias(self) -> np.ndarray:
        return np.zeros(3)

    def _extra_state(self) -> dict[str, Any]:
        return {}

    def _step(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float, m: sq.Vec | None,
              dt: float, dev_acc: float, dev_mag: float | None) -> sq.Quat:
        """One filter step on bias-corrected gyro and normalised acc/mag; returns the new q."""
        raise NotImplementedError
