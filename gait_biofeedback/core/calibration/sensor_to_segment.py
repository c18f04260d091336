"""Sensor-to-segment calibration (thesis ch. 3, Eq 14–17; gait.md §1.3–1.7).

Result per segment: the constant rotation ``r`` (segment → sensor) with ``q_segment = q_sensor ⊗ r``;
``as_matrix(r)`` has the anatomical axes (x anterior, y superior, z right, both legs) as columns in
sensor coordinates, i.e. it is ``(AF→SF)`` = the transpose of the thesis' ``({}^{AF}_{SF}R)`` (Eq 16).

Steps (per segment, independently):

1. Vertical (thesis Eq 14, READING gait.md §1.4 "rows"): ``y_AF`` = mean accelerometer during quiet
   standing, normalised (specific force points up). No axis pre-permutation: READING for arbitrary
   mountings, the provisional VF x is the horizontal projection of the sensor axis most
   perpendicular to ``y_AF`` (never degenerate), ``z_VF = x_VF × y_VF``.
2. Heading (thesis Eq 15, convention-free recipe of gait.md §1.5): the first principal axis ``u`` of
   the angular velocity's horizontal components (VF x–z plane, mean removed) during the motion is the
   mediolateral axis; ``z_AF = ±u``, ``x_AF = y_AF × z_AF``. READING (EXT): the motion gyro is first
   low-passed (2nd-order Butterworth, ``MOTION_LOWPASS_HZ`` = 6 Hz, zero phase; gait and hip flexion
   have their sagittal content below it). Real thigh sensors vibrate on the soft tissue at each heel
   strike: on the qmt walk 52–63 % of the thigh gyro's x/y power is above 10 Hz (spikes of ±15 rad/s),
   which made the raw PCA pick that vibration axis instead of the mediolateral one.
3. Sign of ``z_AF`` (= the 180° x anterior/posterior ambiguity; the thesis' atan restriction needs
   pre-permuted axes, READING here): ``z_AF`` must point right, so forward (sagittal) rotation is
   positive about +z on both legs. Each rule is a physical property of the movement that holds for any
   walker (simulated and real), evaluated on the low-passed rate ``ω·z``:

   * hip flexion protocol, thigh: hip flexion exceeds extension, so the thigh's inclination relative
     to standing has a positive mean, read from the accelerometer (:func:`inclination_sign`; the
     integrated ``∫ ω·z dt`` of before drifted with the filter's bias estimate and put 5 of 50 random
     mountings 180° off); shank and foot swing with the thigh, so their ``ω·z`` correlates positively
     with the thigh's (simulated: +1.0);
   * walking protocol, shank: it rotates forward slowly over the planted foot in stance and fast in
     swing, so its largest rate peak is the forward swing (positive skewness of ``ω·z``; simulated
     +1.6, qmt ±0.8);
   * walking protocol, thigh (:func:`knee_shape_sign`, reference = the calibrated shank of the same
     leg): the knee angle ``∫(ω_thigh − ω_shank)`` flexes far more (≈ 60° in swing) than it
     hyperextends, so its excursion about its 2 s moving mean is positive-dominant
     (``p99 + p1 > 0``); with the wrong thigh sign the curve is the sum of the two segment angles,
     nearly symmetric (simulated +20° vs 0°, qmt +19° vs −3°). The former rule (mean of ``∫ ω·z``
     over the walk) drifts on a long real walk (qmt right thigh: +21° mean from drift alone, the wrong
     sign on both thighs); without a shank the thigh falls back to its mean inclination;
   * walking protocol, foot (:func:`foot_pitch_sign`, no reference needed, also used by the batch
     gait-event calibration): the foot's toes-down minimum at push-off (≈ −37°) is deeper than its
     toes-up maximum at initial contact (≈ +12°) [T §6.4.2], so the sign whose detrended pitch has the
     larger negative excursion (``|p1| > p99``) is kept. The skewness of a real foot's rate is ≈ 0
     (qmt ±0.16: the push-off and swing peaks are equally fast, the largest can be negative), which
     put every gait event ~300 ms off. ``details["reference_agreement"]`` records whether the foot's
     rate correlates positively with the shank's (qmt +0.95, simulated +0.92).

   Without the reference, a segment falls back to its own rule (mean inclination in hip flexion and
   for a walking thigh, the integrated mean angle when no accelerometer is given, skewness for a
   walking shank), noted in ``details["sign_rule"]``.
4. Pelvis and chest (gait.md §1.7, issue 14): vertical from standing; in walking, x along the sensor's
   own anteroposterior acceleration axis (:func:`~gait_biofeedback.core.calibration.trunk.walking_axis`),
   its sign from what follows; heading from option (b), the
   thighs' mean anatomical x during the motion seen in the pelvis sensor through each hip's kinematic
   relative heading (:mod:`~gait_biofeedback.core.calibration.trunk`), the chest through the pelvis.
   Only when that gives nothing (a still pelvis, as in hip flexion) and the sensors share a
   magnetometer heading, option (a): the thighs' mean world heading in standing. Otherwise the trunk
   segment alone is refused, with what to do.

Before any of it, the motion is checked against the protocol (:mod:`~.protocol`: the other
protocol's sign rules would put segments 180° off, and a sitting "standing" wrong verticals). Then each
segment is accepted or refused on its own; the session succeeds when one segment is accepted.

Quality: ``explained_variance`` of the first principal axis (λ1/(λ1+λ2), 0.5 = no preferred axis,
1 = single-axis motion); trunk: ``thigh_heading_agreement`` (1 − |Δheading| / 90°).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.calibration.cycles import MIN_CYCLES, count_cycles, lowpass_motion
from gait_biofeedback.core.calibration.protocol import MAX_UPRIGHT_TILT, WORDS, check_protocol, upright_tilt
from gait_biofeedback.core.calibration.trunk import forward_in_proximal, walking_axis
from gait_biofeedback.core.calibration.windows import rms_about_mean
from gait_biofeedback.core.segments import GRAVITY, SIDES, ImuSeries

NOT_IN_KIT = "not in this kit"
"""Said of a segment whose calibration needs sensors the kit does not have (a pelvis without thighs):
the summaries show it as what the kit lacks, not as a refusal."""

PROTOCOLS: tuple[str, ...] = ("hip_flexion", "walking")
AUTO = "auto"  # a request's protocol: the one the movement shows (:mod:`.protocol`)
REQUESTS: tuple[str, ...] = (AUTO, *PROTOCOLS)
LEG_PARTS: tuple[str, ...] = ("thigh", "shank", "foot")
TRUNK_SEGMENTS: tuple[str, ...] = ("pelvis", "chest")
CYCLE_WORD: dict[str, str] = {"hip_flexion": "flexion", "walking": "swing"}
MIN_EXPLAINED_VARIANCE = 0.6
MAX_STANDING_GYRO_RMS = 0.08  # rad/s (4.6 °/s): more is not quiet standing
MIN_STANDING_SAMPLES = 10  # fewer is no standing recorded
MAX_STANDING_ACC_RMS = 0.5  # m/s²
MAX_THIGH_HEADING_DISAGREEMENT = np.radians(30.0)
MAX_AXIS_DISAGREEMENT = np.radians(45.0)  # trunk walking axis vs the nearest joint direction
DETREND_WINDOW_S = 2.0  # moving-mean window removed from integrated angles (about one stride)


@dataclass
class SegmentCalibrationResult:
    """One segment's calibration; ``rotation`` = r (segment → sensor), ``q_segment = q_sensor ⊗ r``."""

    segment: str
    rotation: np.ndarray
    valid: bool
    quality: float
    quality_metric: str
    standing_motion: float
    message: str = ""
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"segment": self.segment, "rotation": [float(v) for v in self.rotation], "valid": self.valid,
                "quality": float(self.quality), "quality_metric": self.quality_metric,
                "standing_motion": float(self.standing_motion), "message": self.message,
                "details": _plain(self.details)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SegmentCalibrationResult:
        return cls(segment=str(d["segment"]), rotation=quat.normalize(np.asarray(d["rotation"], dtype=float)),
                   valid=bool(d["valid"]), quality=float(d["quality"]),
                   quality_metric=str(d["quality_metric"]),
                   standing_motion=float(d["standing_motion"]), message=str(d.get("message", "")),
                   details=dict(d.get("details", {})))


class SegmentEntry(NamedTuple):
    """One segment's calibration as its consumers receive it: r, whether it is valid, the message."""

    rotation: np.ndarray
    valid: bool
    message: str = ""


@dataclass
class SessionCalibration:
    """All segments' calibration of one calibration trial; ``success`` only when every segment is valid."""

    protocol: str
    segments: dict[str, SegmentCalibrationResult]
    success: bool
    message: str
    standing: tuple[float, float] | None = None
    motion: tuple[float, float] | None = None
    looks_like: str | None = None  # the protocol the movement showed (None: it could not tell)

    def rotations(self) -> dict[str, np.ndarray]:
        """Segment → r of the valid segments."""
        return {s: r.rotation for s, r in self.segments.items() if r.valid}

    def to_dict(self) -> dict[str, Any]:
        return {"protocol": self.protocol, "success": self.success, "message": self.message,
                "standing": None if self.standing is None else [float(v) for v in self.standing],
                "motion": None if self.motion is None else [float(v) for v in self.motion],
                "looks_like": self.looks_like,
                "segments": {s: r.to_dict() for s, r in self.segments.items()}}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SessionCalibration:
        if d.get("protocol") not in PROTOCOLS:
            raise ValueError(f"calibration file: protocol {d.get('protocol')!r} is not one of {PROTOCOLS}")
        return cls(protocol=d["protocol"], success=bool(d["success"]), message=str(d.get("message", "")),
                   standing=None if d.get("standing") is None else tuple(d["standing"]),
                   motion=None if d.get("motion") is None else tuple(d["motion"]),
                   looks_like=d.get("looks_like") if d.get("looks_like") in PROTOCOLS else None,
                   segments={s: SegmentCalibrationResult.from_dict(r) for s, r in d["segments"].items()})


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value)
    if isinstance(value, (np.integer, int)) and not isinstance(value, bool):
        return int(value)
    return value if isinstance(value, (str, bool)) or value is None else str(value)


def label(segment: str) -> str:
    """'left_shank' → 'left shank' (for messages a clinician reads)."""
    return segment.replace("_", " ")


def vertical_calibration(standing_acc: np.ndarray) -> np.ndarray:
    """Thesis Eq 14, rows READING (gait.md §1.4): ``(SF→VF)`` matrix whose rows are x_VF, y_VF, z_VF.

    ``y_VF`` = mean specific force (up). READING for arbitrary mountings: ``x_VF`` = horizontal
    projection of the sensor axis most perpendicular to ``y_VF`` (instead of the sensor x of the
    pre-permuted thesis set-up), ``z_VF = x_VF × y_VF``. Property: ``R @ mean(acc) = (0, |mean|, 0)``.
    """
    acc = np.asarray(standing_acc, dtype=float).reshape(-1, 3)
    y = acc.mean(axis=0)
    norm = np.linalg.norm(y)
    if not np.isfinite(norm) or norm < 1e-6:
        raise ValueError("vertical calibration: the mean accelerometer reading is zero or not finite")
    y = y / norm
    e = np.eye(3)[int(np.argmin(np.abs(y)))]
    x = e - np.dot(e, y) * y
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    return np.vstack([x, y, z])


def heading_calibration(motion_gyr: np.ndarray, vertical: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Thesis Eq 15 by the convention-free recipe (gait.md §1.5 READING).

    ``vertical``: the ``(SF→VF)`` matrix of :func:`vertical_calibration`. Returns (γ rad, explained
    variance λ1/(λ1+λ2), principal axis in sensor coordinates). ``u = (u_x, u_z)`` is the unit first
    principal vector of the VF horizontal components with ``u_z >= 0``; ``γ = atan2(-u_x, u_z)`` rotates
    VF about y onto AF (``x_AF = (u_z, 0, -u_x)``, ``z_AF = (u_x, 0, u_z)`` in VF). The axis sign is
    resolved by :func:`calibrate_segment`, not here.
    """
    w_vf = np.asarray(motion_gyr, dtype=float).reshape(-1, 3) @ np.asarray(vertical).T
    horizontal = w_vf[:, [0, 2]]
    if horizontal.shape[0] < 3:
        raise ValueError("heading calibration: fewer than 3 motion samples")
    cov = np.cov(horizontal, rowvar=False)
    eigval, eigvec = np.linalg.eigh(cov)
    u = eigvec[:, 1]
    if u[1] < 0:
        u = -u
    total = float(eigval.sum())
    explained = float(eigval[1] / total) if total > 0 else 0.5
    gamma = float(np.arctan2(-u[0], u[1]))
    axis_sf = u[0] * vertical[0] + u[1] * vertical[2]
    return gamma, explained, axis_sf / np.linalg.norm(axis_sf)


def sagittal_angle(rate: np.ndarray, rate_hz: float, window_s: float = DETREND_WINDOW_S) -> np.ndarray:
    """Integrated sagittal rate (rad) minus its ``window_s`` moving mean: a drift-free shape of a
    segment's (or joint's) sagittal angle over a walk, to compare its negative and positive excursions."""
    angle = np.cumsum(np.asarray(rate, dtype=float)) / rate_hz
    window = max(1, min(len(angle), round(window_s * rate_hz)))
    padded = np.pad(angle, (window // 2, window - 1 - window // 2), mode="edge")
    return angle - np.convolve(padded, np.ones(window) / window, "valid")


def foot_pitch_sign(rate: np.ndarray, rate_hz: float) -> tuple[float, float]:
    """(+1 if ``rate`` is about the right-pointing axis, asymmetry) of a walking foot's sagittal rate.

    Rule (module docstring step 3, READING after [T §6.4.2]): the toes-down minimum at push-off is
    deeper than the toes-up maximum at IC. ``asymmetry`` = ``|p1| − p99`` (rad) of the detrended pitch
    for the returned sign (≥ 0)."""
    pitch = sagittal_angle(rate, rate_hz)
    p1, p99 = np.percentile(pitch, [1, 99])
    deeper_down = -p1 - p99
    return (1.0 if deeper_down >= 0 else -1.0), float(abs(deeper_down))


def knee_shape_sign(thigh_rate: np.ndarray, shank_rate: np.ndarray, rate_hz: float) -> tuple[float, float]:
    """(+1 if ``thigh_rate`` is about the right-pointing axis, asymmetry) of a walking thigh, given the
    same leg's shank rate about its (already right-pointing) axis.

    Rule (module docstring step 3): the knee angle ``∫(ω_thigh − ω_shank)`` flexes far more than it
    hyperextends: its detrended excursion has ``p99 + p1 > 0``. Both thigh signs are tried and the one
    with the more positive-dominant knee curve is returned; ``asymmetry`` = the difference (rad)."""
    thigh_rate = np.asarray(thigh_rate, dtype=float)
    shank_rate = np.asarray(shank_rate, dtype=float)
    score = []
    for sign in (1.0, -1.0):
        p1, p99 = np.percentile(sagittal_angle(sign * thigh_rate - shank_rate, rate_hz), [1, 99])
        score.append(p99 + p1)
    return (1.0 if score[0] >= score[1] else -1.0), float(abs(score[0] - score[1]))


def inclination_sign(axis: np.ndarray, up: np.ndarray, motion_acc: np.ndarray) -> tuple[float, float]:
    """(+1 if ``axis`` points right, mean forward inclination rad) of a thigh from its accelerometer:
    a rotation θ about the right-pointing axis z turns the sensor's up vector by −θ about z, so
    ``(up × â)·z = −sin θ``; averaged over the motion (linear accelerations average out), flexion
    exceeding extension makes it negative about the right-pointing axis. No integration, so no drift
    (the integrated angle put 5 of 50 simulated left thighs 180° off in hip flexion: the filters' bias
    estimate moves during the motion, and 30 s of it outweighs a mean flexion of +5°)."""
    acc = np.asarray(motion_acc, dtype=float)
    unit = acc / np.maximum(np.linalg.norm(acc, axis=1, keepdims=True), 1e-9)
    forward = -float(np.mean(np.cross(up, unit) @ axis))
    return (1.0 if forward >= 0 else -1.0), float(np.arcsin(min(1.0, abs(forward))))


def _own_sign(segment: str, rate: np.ndarray, protocol: str, rate_hz: float,
              inclination: tuple[float, float] | None = None) -> tuple[float, str]:
    """(+1 if the segment's own rule says the axis points right, rule name) (module docstring step 3)."""
    if protocol == "walking" and segment.endswith("foot"):
        sign, asym = foot_pitch_sign(rate, rate_hz)
        return sign, f"foot pitch shape (push-off deeper by {np.degrees(asym):.0f} deg)"
    if (protocol == "hip_flexion" or segment.endswith("thigh")) and inclination is not None:
        return inclination[0], f"mean inclination ({np.degrees(inclination[1]):.1f} deg forward)"
    if protocol == "hip_flexion" or segment.endswith("thigh"):
        angle = np.cumsum(rate) / rate_hz
        return (1.0 if np.mean(angle) >= 0 else -1.0), "mean sagittal angle"
    centred = rate - rate.mean()
    return (1.0 if np.mean(centred**3) >= 0 else -1.0), "skewness"


def calibrate_segment(
    segment: str,
    standing_acc: np.ndarray,
    standing_gyr: np.ndarray,
    motion_gyr: np.ndarray,
    rate_hz: float,
    protocol: str,
    standing_orientation: np.ndarray | None = None,
    reference_rate: np.ndarray | None = None,
    motion_acc: np.ndarray | None = None,
    standing_limits: tuple[float, float] = (MAX_STANDING_GYRO_RMS, MAX_STANDING_ACC_RMS),
) -> SegmentCalibrationResult:
    """Calibrate one leg segment (thigh, shank, foot) with thesis Eq 14–16 (see module docstring).
    ``standing_limits``: :func:`standing_check`'s (a foot's stance phases in place of a standing are
    allowed more: :func:`~.foot.foot_calibration`).

    ``motion_acc``: the accelerometer at the motion samples; with it, the own rule of a thigh (hip
    flexion, or walking without its shank) is :func:`inclination_sign`, without it the integrated
    mean sagittal angle (which drifts).

    ``reference_rate``: the sagittal angular rate (about its right-pointing axis, standing bias removed,
    low-passed with :func:`lowpass_motion`) of the same leg's reference segment at the motion samples:
    hip flexion thigh for shank/foot (correlation), walking shank for the thigh (knee shape); None = the
    segment's own rule. A walking foot always uses its own pitch-shape rule. ``standing_orientation`` is
    kept in ``details`` (needed by the trunk heading). Never raises for bad recordings: returns
    ``valid=False`` with a message a clinician can act on.
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r}; expected one of {PROTOCOLS}")
    name = label(segment)
    standing_acc = np.asarray(standing_acc, dtype=float).reshape(-1, 3)
    standing_gyr = np.asarray(standing_gyr, dtype=float).reshape(-1, 3)
    motion_gyr = np.asarray(motion_gyr, dtype=float).reshape(-1, 3)
    stand_motion, problem = standing_check(segment, standing_acc, standing_gyr, standing_limits)
    result = SegmentCalibrationResult(segment, quat.IDENTITY.copy(), False, 0.0, "explained_variance",
                                      stand_motion, problem or "")
    if problem:
        return result
    vertical = vertical_calibration(standing_acc)
    y = vertical[1]
    bias = standing_gyr.mean(axis=0)
    if motion_gyr.shape[0] < 3:
        result.message = f"{name}: no movement recorded after the quiet standing"
        return result
    motion = lowpass_motion(motion_gyr - bias, rate_hz)
    gamma, explained, axis = heading_calibration(motion, vertical)
    rate = motion @ axis
    cycles = count_cycles(rate)
    usable_ref = (reference_rate is not None and len(reference_rate) == len(rate)
                  and np.std(reference_rate) > 0)
    details: dict[str, Any] = {}
    if usable_ref:
        ref = np.asarray(reference_rate, dtype=float)
        corr = float(np.corrcoef(rate, ref)[0, 1])
    if protocol == "walking" and segment.endswith("foot"):
        sign, rule = _own_sign(segment, rate, protocol, rate_hz)
        if usable_ref:
            details["reference_agreement"] = float(sign * corr)
    elif protocol == "walking" and segment.endswith("thigh") and usable_ref:
        sign, asym = knee_shape_sign(rate, ref, rate_hz)
        rule = f"knee shape with the shank (flexion-dominant by {np.degrees(asym):.0f} deg)"
    elif usable_ref:
        sign, rule = (1.0 if corr >= 0 else -1.0), f"correlation with reference ({corr:+.2f})"
    else:
        acc_ok = motion_acc is not None and len(motion_acc) == len(rate)
        sign, rule = _own_sign(segment, rate, protocol, rate_hz,
                               inclination_sign(axis, y, motion_acc) if acc_ok else None)
    z = sign * axis
    x = np.cross(y, z)
    rotation = quat.from_matrix(np.column_stack([x, y, z]))
    result.rotation, result.quality = rotation, explained
    result.details = {"gamma": gamma, "cycles": cycles, "sign_rule": rule, **details}
    if standing_orientation is not None:
        result.details["standing_orientation"] = [float(v) for v in standing_orientation]
    need = MIN_CYCLES[protocol]
    if cycles < need:
        what = "flexion cycles" if protocol == "hip_flexion" else "swings (steps of this leg)"
        result.message = f"{name}: only {cycles} {what} detected, need {need}"
    elif explained < MIN_EXPLAINED_VARIANCE:
        result.message = (f"{name}: movement not in one plane (explained variance {explained:.2f} < "
                          f"{MIN_EXPLAINED_VARIANCE}); repeat with clear forward-backward movements")
    else:
        result.valid = True
    return result


def standing_check(segment: str, acc: np.ndarray, gyr: np.ndarray,
                   limits: tuple[float, float] = (MAX_STANDING_GYRO_RMS, MAX_STANDING_ACC_RMS)
                   ) -> tuple[float, str | None]:
    """(RMS angular rate about its mean in rad/s, problem message or None) of a quiet-standing window;
    ``limits``: the largest RMS of the gyro (rad/s) and of the accelerometer (m/s²) about their means."""
    name = label(segment)
    if acc.shape[0] < MIN_STANDING_SAMPLES:
        return float("nan"), f"{name}: no quiet standing recorded (need 3–5 s standing still)"
    gyro_rms, acc_rms = rms_about_mean(gyr), rms_about_mean(acc)
    if gyro_rms > limits[0]:
        return gyro_rms, (f"subject moved during quiet standing ({name}: {np.degrees(gyro_rms):.1f} °/s, "
                          f"limit {np.degrees(limits[0]):.1f} °/s); stand still 5 s and repeat")
    if acc_rms > limits[1]:
        return gyro_rms, (f"subject moved during quiet standing ({name}: accelerometer varies by "
                          f"{acc_rms:.2f} m/s², limit {limits[1]:g} m/s²); stand still 5 s and repeat")
    g = float(np.linalg.norm(acc.mean(axis=0)))
    if abs(g - GRAVITY) > 1.5:
        return gyro_rms, f"{name}: accelerometer reads {g:.1f} m/s² at rest, not ~9.8: check the sensor"
    return gyro_rms, None


def mean_orientation(q: np.ndarray) -> np.ndarray:
    """Normalised sign-aligned mean of nearby unit quaternions (N, 4) (a standing period's attitude)."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    signs = np.where(q @ q[0] < 0, -1.0, 1.0)
    return quat.normalize((q * signs[:, None]).mean(axis=0))


def calibrate_trunk(segment: str, standing_acc: np.ndarray, standing_gyr: np.ndarray,
                    standing_orientation: np.ndarray | None,
                    thighs: list[SegmentCalibrationResult],
                    forward: list[np.ndarray] | None = None,
                    common_heading: bool = True, why_no_forward: list[str] | None = None,
                    walking: tuple[ImuSeries, np.ndarray, tuple[float, float]] | None = None
                    ) -> SegmentCalibrationResult:
    """Pelvis/chest: vertical from standing (Eq 14); heading from ``forward`` (sensor-coordinate
    directions from the joints' kinematic heading, :mod:`~gait_biofeedback.core.calibration.trunk`,
    gait.md §1.7 option (b)) where they exist, else, only with a ``common_heading`` (every sensor
    magnetometer-aided), the mean world heading of the calibrated thighs' x axes during standing
    (option (a)); ``why_no_forward``: why the joints gave none (for the refusal).

    ``walking`` (the segment's series, orientations and the motion window): when the motion is rhythmic
    walking, x is the sensor's own anteroposterior acceleration axis
    (:func:`~gait_biofeedback.core.calibration.trunk.walking_axis`) and the directions above only give
    its sign; it is refused when none of them lies within ``MAX_AXIS_DISAGREEMENT`` of it. (On the qmt
    walk the two hips' kinematic headings put the pelvis forward 69° apart, while the acceleration axis
    lies 13° from one of them; simulated: axis 1.6° from the truth, thigh directions 6–9°, the
    thighs' functional flexion axes.) Quality: 1 − angle / 90° between x and the directions' mean
    (without ``walking``: between the directions averaged)."""
    name = label(segment)
    standing_acc = np.asarray(standing_acc, dtype=float).reshape(-1, 3)
    motion, problem = standing_check(segment, standing_acc, np.asarray(standing_gyr, float).reshape(-1, 3))
    result = SegmentCalibrationResult(segment, quat.IDENTITY.copy(), False, 0.0, "thigh_heading_agreement",
                                      motion, problem or "")
    if problem:
        return result
    y = vertical_calibration(standing_acc)[1]
    directions = [f - np.dot(f, y) * y for f in forward or []]
    directions = [d / np.linalg.norm(d) for d in directions if np.linalg.norm(d) > 0.1]
    source = "kinematic heading (joint accelerations)"
    if not directions:
        usable = [t for t in thighs if t.valid and "standing_orientation" in t.details]
        if not common_heading or standing_orientation is None or not usable:
            via = "the thighs" if segment == "pelvis" else "a calibrated pelvis"
            why = "; ".join(why_no_forward or [])
            if any(w in ("no thigh sensors", "no pelvis sensor") for w in why_no_forward or []):
                advice = (f": its forward direction comes from {via}, {NOT_IN_KIT} (its joints need them: "
                          "wear those sensors and calibrate again; the other segments do not need it)")
            else:
                advice = (": a still pelvis, as in hip flexion, does not show it"
                          + (", and the sensors have no shared magnetometer heading" if not common_heading
                             else "") + "; calibrate with the walking protocol (8 straight steps)")
            result.message = f"{name}: no heading from {via}" + (f" ({why})" if why else "") + advice
            return result
        source = "magnetometer heading of the thighs in standing"
        for t in usable:
            x_world = quat.rotate(np.asarray(t.details["standing_orientation"]),
                                  quat.rotate(t.rotation, [1.0, 0.0, 0.0]))
            x_sensor = quat.rotate_inverse(standing_orientation, x_world * [1.0, 1.0, 0.0])
            x_sensor = x_sensor - np.dot(x_sensor, y) * y
            if np.linalg.norm(x_sensor) < 0.3:
                result.message = f"{name}: sensor orientation and accelerometer disagree on the vertical"
                return result
            directions.append(x_sensor / np.linalg.norm(x_sensor))
    x = np.sum(directions, axis=0)
    if np.linalg.norm(x) < 0.3:
        result.message = f"{name}: the directions it would average point apart; repeat the calibration"
        return result
    x /= np.linalg.norm(x)
    spread = float(np.arccos(np.clip(np.dot(directions[0], directions[-1]), -1.0, 1.0)))
    axis, clarity, step_hz = walking_axis(*walking, y) if walking is not None else (None, 0.0, 0.0)
    details: dict[str, Any] = {"heading_source": source, "thigh_heading_spread": spread}
    if axis is not None:
        axis = axis - np.dot(axis, y) * y
        axis = (1.0 if np.dot(axis, x) >= 0 else -1.0) * axis / np.linalg.norm(axis)
        nearest = float(np.arccos(np.clip(max(np.dot(d, axis) for d in directions), -1.0, 1.0)))
        details.update(heading_source=f"walking acceleration axis (step {step_hz:.2f} Hz, clarity "
                       f"{clarity:.1f}), its sign from the {source}", axis_to_nearest_direction=nearest)
        spread = float(np.arccos(np.clip(np.dot(axis, x), -1.0, 1.0)))
        x = axis
        if nearest > MAX_AXIS_DISAGREEMENT:
            problem = (f"{name}: its walking direction and the {source} disagree by "
                       f"{np.degrees(nearest):.0f}°: check the thigh sensors, then repeat")
    elif spread > MAX_THIGH_HEADING_DISAGREEMENT:
        problem = (f"{name}: the left and right thighs put its forward direction "
                   f"{np.degrees(spread):.0f}° apart: check the thigh sensors, then repeat")
    result.rotation = quat.from_matrix(np.column_stack([x, y, np.cross(x, y)]))
    result.quality = max(0.0, 1.0 - spread / (np.pi / 2))
    result.details = details
    if standing_orientation is not None:
        result.details["standing_orientation"] = [float(v) for v in standing_orientation]
    result.message = problem or ""
    result.valid = problem is None
    return result


def _trunk_forward(segment: str, data: dict[str, ImuSeries], orientations: dict[str, np.ndarray],
                   results: dict[str, SegmentCalibrationResult], motion: tuple[float, float]
                   ) -> tuple[list[np.ndarray], list[str]]:
    """(forward directions of a trunk sensor from the kinematic heading, why the others gave none)
    (module docstring step 4)."""
    if "pelvis" not in data:
        return [], ["no pelvis sensor"]
    if "pelvis" not in orientations:
        return [], ["no pelvis orientation"]
    pelvis, q_pelvis = data["pelvis"], orientations["pelvis"]
    found = []
    if segment == "pelvis":
        for t in (f"{side}_thigh" for side in SIDES):
            if t in results and results[t].valid and t in orientations:
                x_thigh = quat.rotate(results[t].rotation, [1.0, 0.0, 0.0])
                direction, how = forward_in_proximal(pelvis, q_pelvis, data[t], orientations[t], x_thigh,
                                                     motion)
                found.append((direction, f"{label(t)}: {how}"))
        if not found:
            worn = any(f"{side}_thigh" in data for side in SIDES)
            return [], ["no calibrated thigh" if worn else "no thigh sensors"]
    elif segment in orientations and results.get("pelvis") is not None and results["pelvis"].valid:
        x_pelvis = quat.rotate(results["pelvis"].rotation, [1.0, 0.0, 0.0])
        direction, how = forward_in_proximal(pelvis, q_pelvis, data[segment], orientations[segment], x_pelvis,
                                             motion, toward_distal=True)
        found.append((direction, f"pelvis: {how}"))
    else:
        return [], ["no calibrated pelvis"]
    return [d for d, _ in found if d is not None], [how for d, how in found if d is None]


def _window(series_t: np.ndarray, window: tuple[float, float]) -> np.ndarray:
    return (series_t >= window[0]) & (series_t <= window[1])


def calibrate_session(
    data: dict[str, ImuSeries],
    standing: tuple[float, float],
    motion: tuple[float, float],
    protocol: str,
    rate_hz: float | None = None,
    orientations: dict[str, np.ndarray] | None = None,
    common_heading: bool = True,
) -> SessionCalibration:
    """Calibrate every segment of ``data`` (legs, then pelvis/chest) from the ``standing`` and
    ``motion`` time windows (s). ``orientations``: segment → (N, 4) sensor→world per sample of
    ``data`` (needed for the trunk heading); ``common_heading``: they share a magnetometer heading.

    First the motion is checked against ``protocol``
    (:func:`~gait_biofeedback.core.calibration.protocol.check_protocol`): when it looks like the other
    protocol, nothing is calibrated and the message names the protocol it looks like (the other
    protocol's sign rules would put segments 180° off); ``protocol="auto"`` takes the one it looks
    like and refuses when it cannot tell; when it cannot tell, a named protocol is used and the message
    says it was not confirmed. Then each segment is valid or refused on its own (also when its standing
    attitude is far from its attitude during the motion, :func:`~.protocol.upright_tilt`: not a
    standing): ``success`` when at least one is valid (the others' messages stay in ``message`` and in
    their entries)."""
    if protocol not in REQUESTS:
        raise ValueError(f"unknown protocol {protocol!r}; expected one of {REQUESTS}")
    check = check_protocol(data, motion)
    seen = check.looks_like
    if (protocol == AUTO and seen is None) or (seen is not None and protocol not in (AUTO, seen)):
        if seen is None:
            why = (f"the movement does not show which protocol was done ({check.evidence()}): choose "
                   "hip flexion or walking and repeat the protocol")
        else:
            why = (f"the movement looks like {WORDS[seen]} ({check.evidence()}), not {WORDS[protocol]}: "
                   f"calibrate with the {WORDS[seen]} protocol")
        return SessionCalibration(protocol if protocol != AUTO else (seen or PROTOCOLS[0]), {}, False,
                                  f"calibration refused, previous calibration stays in force: {why}",
                                  tuple(standing), tuple(motion), seen)
    unconfirmed = seen is None
    protocol = seen if protocol == AUTO else protocol
    orientations = orientations or {}
    results: dict[str, SegmentCalibrationResult] = {}
    tilts = upright_tilt(data, standing, motion)
    ref_part = "thigh" if protocol == "hip_flexion" else "shank"
    for side in SIDES:
        ref = f"{side}_{ref_part}"
        order = [ref] + [f"{side}_{p}" for p in LEG_PARTS if p != ref_part]
        ref_rate = None
        for seg in order:
            if seg not in data:
                continue
            s = data[seg]
            st, mo = _window(s.t, standing), _window(s.t, motion)
            rate_ref = None
            if ref_rate is not None and (protocol == "walking" or not seg.endswith("thigh")):
                rate_ref = np.interp(s.t[mo], *ref_rate)
            q_stand = mean_orientation(orientations[seg][st]) if seg in orientations and st.any() else None
            res = calibrate_segment(seg, s.acc[st], s.gyr[st], s.gyr[mo], rate_hz or s.rate_hz, protocol,
                                    q_stand, rate_ref, s.acc[mo])
            results[seg] = _refuse_if_not_upright(res, tilts)
            if seg == ref and res.valid:
                z = quat.rotate(res.rotation, [0.0, 0.0, 1.0])
                ref_motion = lowpass_motion(s.gyr[mo] - s.gyr[st].mean(axis=0), rate_hz or s.rate_hz)
                ref_rate = (s.t[mo], ref_motion @ z)
    thighs = [results[f"{side}_thigh"] for side in SIDES if f"{side}_thigh" in results]
    for seg in TRUNK_SEGMENTS:
        if seg in data:
            s = data[seg]
            st = _window(s.t, standing)
            q_stand = mean_orientation(orientations[seg][st]) if seg in orientations and st.any() else None
            forward, why_not = _trunk_forward(seg, data, orientations, results, motion)
            walks = protocol == "walking" and seg in orientations
            walking = (s, orientations[seg], motion) if walks else None
            results[seg] = _refuse_if_not_upright(
                calibrate_trunk(seg, s.acc[st], s.gyr[st], q_stand, thighs, forward, common_heading, why_not,
                                walking), tilts)
    problems = [r.message for r in results.values() if not r.valid]
    valid = [label(s) for s, r in results.items() if r.valid]
    success = bool(valid)
    if not results:
        problems = ["no sensor data to calibrate"]
    if not success:
        message = "calibration refused, previous calibration stays in force: " + "; ".join(problems)
    else:
        message = "calibrated " + ", ".join(valid)
        lacking = [p for p in problems if NOT_IN_KIT in p]  # information: the kit has no such sensors
        problems = [p for p in problems if NOT_IN_KIT not in p]
        if problems:
            message += "; NOT calibrated (their joints are not published): " + "; ".join(problems)
        if lacking:
            message += "; not calibrated, for want of sensors: " + "; ".join(lacking)
    if unconfirmed:
        message += (f" (the movement did not confirm the {WORDS[protocol]} protocol: {check.evidence()}; "
                    "check that it was done as instructed)")
    return SessionCalibration(protocol, results, success, message, tuple(standing), tuple(motion), seen)


def _refuse_if_not_upright(result: SegmentCalibrationResult, tilts: dict[str, float]
                           ) -> SegmentCalibrationResult:
    """``result`` refused when its segment's standing attitude is more than ``MAX_UPRIGHT_TILT`` from
    its attitude during the motion (:func:`~.protocol.upright_tilt`), before another segment uses it."""
    tilt = tilts.get(result.segment, 0.0)
    if result.valid and tilt > MAX_UPRIGHT_TILT:
        result.valid = False
        result.message = (f"{label(result.segment)}: not upright in the quiet standing "
                          f"({np.degrees(tilt):.0f}° from its attitude during the movement: sitting?); "
                          "stand still 5 s and repeat")
    return result


def helical_angle(r_estimate: np.ndarray, r_reference: np.ndarray) -> np.ndarray:
    """Calibration error θ of thesis Eq 19 (rad): rotation angle between two segment→sensor rotations."""
    return quat.angle_between(r_estimate, r_reference)
