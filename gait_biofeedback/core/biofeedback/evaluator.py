"""Prescriptive biofeedback: measured gait vs the therapist's targets → visual and auditory cues.

Thesis ch. 8 and §9.2.5 (gait.md §5.3): a knowledge base compares the measured with the targeted
pattern, the error is displayed, and "audio cues synchronized with errors, e.g., a beeping sound with a
frequency or amplitude proportional to the error" are generated in real time. The thesis names the fed
back signals (joint angles, IC/TC) but no quantities, bands or curves; the per-stride quantities here are
EXT (gait.md §5.2 "DERIVED-possible"):

* kinematic, per side, from the sagittal joint angles of the stride (IC to next IC of the same foot):
  ``knee_flexion_peak_swing`` (max knee flexion from TC to the closing IC), ``knee_flexion_at_ic`` (knee
  flexion at the opening IC: "knee extension at IC"), ``hip_extension_peak_stance`` (-min hip flexion from
  IC to TC: "hip extension in late stance"), ``ankle_dorsiflexion_at_ic``;
* temporal, from the GaitCycle: ``stance_fraction`` (per side), ``cadence`` and ``step_time_symmetry``
  (bilateral, side "");
* spatial (issue 16), from the GaitCycle's foot trajectory: ``stride_length`` (per side), ``gait_speed``
  (bilateral), and ``step_length`` (per side) with ``step_length_symmetry`` (bilateral, ``(L - R) /
  (0.5 (L + R))`` of the mean step lengths over the last ``symmetry_window`` steps of each side).
  A stride whose ``spatial_flag`` is set gives no spatial cue, nor does a turn (EXT): a stride whose
  foot turned by more than ``TURN_LIMIT`` (20°, as the report leaves turns out) or by an unknown angle
  (a provisional one not yet trusted) is short because it turns, and a cue to lengthen it would be
  wrong; its step length does not enter the symmetry either. Nor does a walk's first stride of each
  foot (the first after a standing, or after a stride that was not plausible: its opening IC is not
  the closing IC of the foot's last stride evaluated): gait initiation is short, as the report's
  :func:`~gait_biofeedback.core.gait.cycles.steady_strides` leaves it out. (A walk's last stride, the
  stop, is only known once no stride follows: live, it gets its cues.)

Step length (EXT, :func:`step_length`): two foot trajectories have no common frame (each filter's
origin and heading drift on their own), so the distance between the feet is taken from the legs'
sagittal angles instead: the ankle of a leg with hip flexion ``h`` and knee flexion ``k`` is
``l_thigh sin h + l_shank sin(h - k)`` ahead of the hip (pelvis level). At each IC the leading ankle
is ``D`` ahead of the trailing one. In a stride of side S (its IC to its next IC) the other foot's
step ends at its IC (``D_O``) and S's own at the closing IC (``D_S``); without sliding the two steps
add up to the stride, so ``step_S = stride_length · D_S / (D_S + D_O)``. Only the ratio of the leg
chain is used, so the segment lengths' scale and the pelvis tilt (common to both legs) hardly
matter; the length comes from the foot trajectory.

Comparison (gait_biofeedback_msgs/BiofeedbackCue): ``error = measured - nearest band edge`` (0 inside),
severity IN_BAND (0), MILD (outside by less than one band width) or SEVERE (one band width or more).

Audio cue rule (thesis ch. 8: pitch follows the error; silent in band), :class:`AudioRule`: with the
signed error in band widths ``e = error / (high - low)``, the tone is ``f = base_frequency · 2^(octaves ·
clip(e, -1, 1))`` (too much → higher, too little → lower pitch) and the beep rate is ``min_rate +
(max_rate - min_rate) · min(|e|, 1)`` beeps/s; inside the band both are 0 (no sound).

Everything is SI (rad, s, Hz, fractions); config/targets.yaml may be written in degrees, percent or
steps/min and is converted on load.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gait_biofeedback.core.biofeedback import normative as normative_gait
from gait_biofeedback.core.body import BodyDimensions, StickFigureDimensions
from gait_biofeedback.core.gait.cycles import TURN_LIMIT, symmetry_index
from gait_biofeedback.core.joints.angles import joint_angle_names, relative_rotation_from_angles
from gait_biofeedback.core.joints.skeleton import stick_figure
from gait_biofeedback.core.params import param
from gait_biofeedback.core.quaternion import multiply
from gait_biofeedback.core.safe_yaml import load_yaml_file
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.resources import config_path

SEVERITY_IN_BAND, SEVERITY_MILD, SEVERITY_SEVERE = 0, 1, 2

# quantity → (joint group for the feedback selection, bilateral?, SI unit on the wire)
QUANTITIES: dict[str, tuple[str, bool, str]] = {
    "knee_flexion_peak_swing": ("knee", False, "rad"),
    "knee_flexion_at_ic": ("knee", False, "rad"),
    "hip_extension_peak_stance": ("hip", False, "rad"),
    "ankle_dorsiflexion_at_ic": ("ankle", False, "rad"),
    "stance_fraction": ("timing", False, "1"),
    "step_time_symmetry": ("timing", True, "1"),
    "cadence": ("timing", True, "Hz"),
    "stride_length": ("spatial", False, "m"),
    "gait_speed": ("spatial", True, "m/s"),
    "step_length": ("spatial", False, "m"),
    "step_length_symmetry": ("spatial", True, "1"),
}
SPATIAL = ("stride_length", "gait_speed", "step_length", "step_length_symmetry")
KINEMATIC = ("knee_flexion_peak_swing", "knee_flexion_at_ic", "hip_extension_peak_stance",
             "ankle_dorsiflexion_at_ic")
JOINT_GROUPS = ("hip", "knee", "ankle", "timing", "spatial")
SAGITTAL = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")
"""The sagittal angles the evaluator keeps per side (JointState name = ``<side>_<name>``)."""

# unit in targets.yaml → (factor to SI, SI unit)
_UNITS: dict[str, tuple[float, str]] = {
    "deg": (math.pi / 180.0, "rad"), "rad": (1.0, "rad"), "percent": (0.01, "1"), "%": (0.01, "1"),
    "1": (1.0, "1"), "Hz": (1.0, "Hz"), "steps/s": (1.0, "Hz"), "steps/min": (1.0 / 60.0, "Hz"),
    "s": (1.0, "s"), "m": (1.0, "m"), "cm": (0.01, "m"), "m/s": (1.0, "m/s"),
}


@dataclass(frozen=True)
class Band:
    """Target band in SI units."""

    low: float
    high: float
    unit: str

    @property
    def width(self) -> float:
        return self.high - self.low


@dataclass(frozen=True)
class AudioRule:
    """Beep tone and rate from the error (module docstring; thesis ch. 8)."""

    base_frequency: float = 660.0
    octaves: float = 1.0
    min_rate: float = 1.0
    max_rate: float = 6.0

    def cue(self, error: float, band: Band) -> tuple[float, float]:
        """(frequency Hz, rate beeps/s) for a signed ``error`` from ``band``; (0, 0) inside it."""
        if error == 0.0 or not math.isfinite(error):
            return 0.0, 0.0
        width = band.width if band.width > 0 else max(abs(band.high), 1e-9)
        e = error / width
        frequency = self.base_frequency * 2.0 ** (self.octaves * max(-1.0, min(1.0, e)))
        rate = self.min_rate + (self.max_rate - self.min_rate) * min(abs(e), 1.0)
        return frequency, rate


@dataclass
class Targets:
    """Bands per (quantity, side) (side "" for bilateral quantities), audio rule, reference curves."""

    bands: dict[tuple[str, str], Band]
    audio: AudioRule = field(default_factory=AudioRule)
    reference_enabled: bool = True
    reference_tolerance: dict[str, float] = field(default_factory=lambda: {
        k: v * normative_gait.DEG for k, v in normative_gait.DEFAULT_TOLERANCE_DEG.items()})

    def band(self, quantity: str, side: str) -> Band | None:
        return self.bands.get((quantity, "" if QUANTITIES[quantity][1] else side))

    def to_json(self) -> dict[str, Any]:
        """Bands and reference curves for the dashboard (SI)."""
        out: dict[str, Any] = {
            "bands": [{"quantity": q, "side": s, "low": b.low, "high": b.high, "unit": b.unit}
                      for (q, s), b in self.bands.items()],
            "audio": {"base_frequency": self.audio.base_frequency, "octaves": self.audio.octaves,
                      "min_rate": self.audio.min_rate, "max_rate": self.audio.max_rate},
            "reference": {},
        }
        if self.reference_enabled:
            pct = normative_gait.percent_grid()
            for name in SAGITTAL:
                mean, low, high = normative_gait.reference_band(name, self.reference_tolerance[name], pct)
                out["reference"][name] = {"percent": pct.tolist(), "mean": mean.tolist(),
                                          "low": low.tolist(), "high": high.tolist()}
            out["reference_sources"] = list(normative_gait.REFERENCE_SOURCES)
        return out


def _to_si(value: Any, unit: str, where: str) -> float:
    if unit not in _UNITS:
        raise ValueError(f"{where}: unknown unit {unit!r}; use one of {sorted(_UNITS)}")
    return float(value) * _UNITS[unit][0]


def targets_from_dict(config: Mapping[str, Any]) -> Targets:
    """Targets from the parsed config/targets.yaml (format documented in that file)."""
    bands: dict[tuple[str, str], Band] = {}
    for quantity, spec in (config.get("quantities") or {}).items():
        if quantity not in QUANTITIES:
            raise ValueError(f"targets: unknown quantity {quantity!r}; known: {sorted(QUANTITIES)}")
        spec = spec or {}
        if not spec.get("enabled", True):
            continue
        unit = str(spec.get("unit", QUANTITIES[quantity][2]))
        si_unit = _UNITS[unit][1] if unit in _UNITS else unit
        if si_unit != QUANTITIES[quantity][2]:
            raise ValueError(f"targets: {quantity} in {unit!r}, expected a unit of {QUANTITIES[quantity][2]}")
        bilateral = QUANTITIES[quantity][1]
        sides = [""] if bilateral else [s for s in spec.get("sides", SIDES)]
        for side in sides:
            own = spec.get(side, {}) if side else {}
            low = _to_si(own.get("low", spec.get("low")), unit, f"targets: {quantity}")
            high = _to_si(own.get("high", spec.get("high")), unit, f"targets: {quantity}")
            if not low <= high:
                raise ValueError(f"targets: {quantity} {side}: low {low} > high {high}")
            bands[(quantity, side)] = Band(low, high, QUANTITIES[quantity][2])
    audio_cfg = config.get("audio") or {}
    audio = AudioRule(**{k: float(v) for k, v in audio_cfg.items() if k in AudioRule.__dataclass_fields__})
    ref = config.get("reference_curves") or {}
    tol = {k: v * normative_gait.DEG for k, v in normative_gait.DEFAULT_TOLERANCE_DEG.items()}
    tol.update({k: float(v) * normative_gait.DEG for k, v in (ref.get("tolerance") or {}).items()
                if k in tol})
    return Targets(bands, audio, bool(ref.get("enabled", True)), tol)


def load_targets(path: str | Path) -> Targets:
    """Targets from a YAML file (config/targets.yaml)."""
    return targets_from_dict(load_yaml_file(path) or {})


def default_targets_path() -> Path:
    """config/targets.yaml of a source checkout, else the installed share/gait_biofeedback/config copy."""
    return config_path("targets.yaml")


def compare(measured: float, band: Band) -> tuple[float, int]:
    """(signed error = measured - nearest band edge (0 inside), severity) of one quantity."""
    if measured < band.low:
        error = measured - band.low
    elif measured > band.high:
        error = measured - band.high
    else:
        return 0.0, SEVERITY_IN_BAND
    return error, (SEVERITY_MILD if abs(error) < band.width else SEVERITY_SEVERE)


@dataclass
class Cue:
    """One comparison (fields of gait_biofeedback_msgs/BiofeedbackCue; ``stamp_ns``: the stride's
    closing IC)."""

    quantity: str
    side: str
    unit: str
    measured: float
    band_low: float
    band_high: float
    error: float
    severity: int
    audio_frequency: float
    audio_rate: float
    stride_index: int
    stamp_ns: int

    @property
    def joint(self) -> str:
        return QUANTITIES[self.quantity][0]


@dataclass
class Stride:
    """Timing of one stride (from a GaitCycle): stamps (int ns) of its opening IC, TC (None: unknown)
    and closing IC; the temporal and spatial parameters as in the GaitCycle."""

    side: str
    index: int
    start_ns: int
    tc_ns: int | None
    end_ns: int
    stance_fraction: float = math.nan
    cadence: float = math.nan
    step_time_symmetry: float = math.nan
    plausible: bool = True
    step_time: float = math.nan
    stride_length: float = math.nan
    gait_speed: float = math.nan
    spatial_flag: str = ""
    max_foot_height: float = math.nan  # m, shown on the dashboard (no cue)
    foot_angle_ic: float = math.nan  # rad, toes up at the strike, shown on the dashboard (no cue)
    turning_angle: float = math.nan  # rad, the foot's heading change (a turn gives no spatial cue)

    @property
    def turning(self) -> bool:
        """Not known to be a straight stride: turned by more than ``TURN_LIMIT``, or by an unknown angle."""
        return not abs(self.turning_angle) <= TURN_LIMIT

    @property
    def t_start(self) -> float:
        return self.start_ns / NS_PER_S

    @property
    def t_tc(self) -> float:
        return math.nan if self.tc_ns is None else self.tc_ns / NS_PER_S

    @property
    def t_end(self) -> float:
        return self.end_ns / NS_PER_S


@dataclass
class StrideResult:
    """Cues of one stride and its time-normalised sagittal curves (rad on ``percent``), if covered."""

    stride: Stride
    cues: list[Cue]
    percent: np.ndarray | None = None
    curves: dict[str, np.ndarray] = field(default_factory=dict)
    kinematics: dict[str, float] = field(default_factory=dict)
    spatial: dict[str, float] = field(default_factory=dict)


class AngleHistory:
    """Bounded history of one side's sagittal angles (rad) with sample times (s), oldest first."""

    def __init__(self, capacity: int = 1500) -> None:
        self.t: deque[float] = deque(maxlen=capacity)
        self.values: deque[tuple[float, float, float]] = deque(maxlen=capacity)

    def add(self, t: float, hip: float, knee: float, ankle: float) -> None:
        if self.t and t <= self.t[-1]:
            return  # out of order / repeated: keep the history monotonic
        self.t.append(t)
        self.values.append((hip, knee, ankle))

    @property
    def latest(self) -> float:
        return self.t[-1] if self.t else -math.inf

    def window(self, t0: float, t1: float, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(t (N,), angles (N, 3)) with t0 - margin <= t <= t1 + margin."""
        times = list(self.t)
        i0 = bisect_left(times, t0 - margin)
        i1 = bisect_left(times, t1 + margin + 1e-9)
        vals = list(self.values)[i0:i1]
        return np.asarray(times[i0:i1], dtype=float), np.asarray(vals, dtype=float).reshape(-1, 3)


def normalise_stride(t: np.ndarray, values: np.ndarray, t_start: float, t_end: float,
                     percent: np.ndarray | None = None) -> np.ndarray:
    """``values`` (N,) at ``t`` resampled at ``percent`` (% of the stride from ``t_start`` to ``t_end``)."""
    pct = normative_gait.percent_grid(2.0) if percent is None else percent
    return np.interp(t_start + pct / 100.0 * (t_end - t_start), t, values)


def stride_kinematics(t: np.ndarray, angles: np.ndarray, stride: Stride) -> dict[str, float]:
    """Kinematic quantities (rad) of one stride from sagittal ``angles`` (N, 3: hip, knee, ankle) at ``t``.

    The IC values are interpolated at the opening IC; peaks are taken over the samples of the phase.
    """
    hip, knee, ankle = angles[:, 0], angles[:, 1], angles[:, 2]
    stance = (t >= stride.t_start) & (t <= stride.t_tc)
    swing = (t >= stride.t_tc) & (t <= stride.t_end)
    out = {"knee_flexion_at_ic": float(np.interp(stride.t_start, t, knee)),
           "ankle_dorsiflexion_at_ic": float(np.interp(stride.t_start, t, ankle))}
    if stance.any():
        out["hip_extension_peak_stance"] = float(-hip[stance].min())
    if swing.any():
        out["knee_flexion_peak_swing"] = float(knee[swing].max())
    return out


def ankle_ahead(hip_flexion: float, knee_flexion: float, lengths: BodyDimensions) -> float:
    """Forward distance (m) of the ankle from the hip in the leg's sagittal plane, pelvis level."""
    return (lengths.thigh_length_m * math.sin(hip_flexion)
            + lengths.shank_length_m * math.sin(hip_flexion - knee_flexion))


def step_length(stride_length: float, own_lead: float, other_lead: float) -> float:
    """The stride's own step (m): ``stride_length · D_S / (D_S + D_O)`` (module docstring), from the
    leading ankle's lead over the trailing one at the closing IC (``own_lead``) and at the other
    foot's IC inside the stride (``other_lead``); NaN unless both leads are positive."""
    if not (own_lead > 0.0 and other_lead > 0.0 and math.isfinite(stride_length)):
        return math.nan
    return stride_length * own_lead / (own_lead + other_lead)


FEEDBACK_SIDES = (*SIDES, "both")
FEEDBACK_JOINTS = (*JOINT_GROUPS, "all")


DASHBOARD_LINK_FILE = "dashboard_url.txt"
"""The file in the session folder holding the dashboard's link with its command token (0600), removed
when the session ends."""


@dataclass(frozen=True)
class BiofeedbackParams(StickFigureDimensions):
    """Parameters of the biofeedback stage and its dashboard (node ``biofeedback``)."""

    targets_file: str = param("", "the therapist's targets ('' = config/targets.yaml)")
    serve_dashboard: bool = param(True, "serve the clinician's dashboard")
    host: str = param("127.0.0.1", "address the dashboard binds (keep 127.0.0.1 unless behind a proxy)")
    allowed_hosts: tuple[str, ...] = param((), "more names the page may be opened under (host or host:port, "
                                           "e.g. this machine's LAN name, or a proxy's); needed when host is "
                                           "not 127.0.0.1")
    port: int = param(8080, "dashboard port (0 = any free port)", low=0, high=65535)
    session_dir: str = param("", "folder where the link with the command token is written "
                             "(dashboard_url.txt, readable by its owner only); '' = the recording's "
                             "folder when the graph records, else none (the link is printed on the terminal)")
    frame_rate_hz: float = param(30.0, "dashboard frames per second", "Hz", low=1.0, high=120.0)
    stride_wait_s: float = param(0.5, "longest wait for a stride's joint angles before it is evaluated "
                                 "without them", "s", low=0.0, high=10.0)
    curve_strides: int = param(5, "strides per side a newly opened page receives", "strides", low=0, high=100)
    feedback_side: str = param("both", "side whose errors are sounded", choices=FEEDBACK_SIDES)
    feedback_joint: str = param("all", "joint (or timing) whose errors are sounded", choices=FEEDBACK_JOINTS)
    diagnostics_period_s: float = param(1.0, "period of the /diagnostics status", "s", low=0.1, high=60.0)


class BiofeedbackEvaluator:
    """Per-stride comparison with the targets (module docstring). Feed it joint angles with
    :meth:`add_angles` and strides with :meth:`evaluate` once :meth:`covers` says the angles are in."""

    def __init__(self, targets: Targets, max_gap_s: float = 0.1, history_s: float = 15.0,
                 rate_hz: float = 100.0, lengths: BodyDimensions | None = None,
                 symmetry_window: int = 10) -> None:
        self.targets = targets
        self.max_gap_s = max_gap_s
        self.history = {side: AngleHistory(int(history_s * rate_hz)) for side in SIDES}
        self.percent = normative_gait.percent_grid(2.0)
        self.lengths = lengths or BodyDimensions()
        self.steps: dict[str, deque[float]] = {side: deque(maxlen=symmetry_window) for side in SIDES}
        self._last_end_ns: dict[str, int] = {}  # closing IC of each foot's last stride evaluated

    def _lead(self, side: str, t: float) -> float:
        """How far ``side``'s ankle is ahead of the other's at ``t`` (m, leg chain; the angles within
        ``max_gap_s / 2`` of ``t``, interpolated, the nearest at an end); NaN without angles."""
        ahead = []
        for s in (side, SIDES[1 - SIDES.index(side)]):
            times, angles = self.history[s].window(t, t, margin=self.max_gap_s / 2)
            if not len(times):
                return math.nan
            hip, knee = (float(np.interp(t, times, angles[:, k])) for k in (0, 1))
            ahead.append(ankle_ahead(hip, knee, self.lengths))
        return ahead[0] - ahead[1]

    def spatial(self, stride: Stride) -> dict[str, float]:
        """The spatial quantities of ``stride`` (none when its spatial values are unknown or doubtful,
        it is not known to be straight: :attr:`Stride.turning`, or it starts a walk (module docstring); a
        stride length of 0, the value of a field nobody filled, is unknown too)."""
        continuous = self._last_end_ns.get(stride.side) == stride.start_ns
        self._last_end_ns[stride.side] = stride.end_ns
        if stride.spatial_flag or not stride.stride_length > 0.0 or stride.turning or not continuous:
            return {}
        other = SIDES[1 - SIDES.index(stride.side)]
        step = step_length(stride.stride_length, self._lead(stride.side, stride.t_end),
                           self._lead(other, stride.t_end - stride.step_time))
        out = {"stride_length": stride.stride_length, "gait_speed": stride.gait_speed, "step_length": step}
        if math.isfinite(step):
            self.steps[stride.side].append(step)
            out["step_length_symmetry"] = symmetry_index(self.steps["left"], self.steps["right"])
        return out

    def add_angles(self, side: str, stamp_ns: int, hip: float, knee: float, ankle: float,
                   doubtful: bool = False) -> None:
        """One instant's sagittal angles (rad) of ``side``. ``doubtful`` ones (computed while a sensor
        recovered from a dropout) are left out of the history: a stride that needs them has a hole
        longer than ``max_gap_s`` and gets no kinematic cue."""
        if not doubtful:
            self.history[side].add(stamp_ns / NS_PER_S, hip, knee, ankle)

    def covers(self, stride: Stride, slack: float = 0.02) -> bool:
        """True when the angle history of the stride's side reaches its closing IC."""
        return self.history[stride.side].latest >= stride.t_end - slack

    def evaluate(self, stride: Stride) -> StrideResult:
        """Cues of every targeted quantity of ``stride`` (kinematic ones only if its angles are complete)."""
        measured: dict[str, float] = {}
        result = StrideResult(stride, [])
        if not stride.plausible:
            return result
        t, angles = self.history[stride.side].window(stride.t_start, stride.t_end, margin=0.02)
        complete = (len(t) >= 3 and t[0] <= stride.t_start + self.max_gap_s / 2
                    and t[-1] >= stride.t_end - self.max_gap_s / 2
                    and float(np.diff(t).max()) <= self.max_gap_s)
        if complete:
            result.kinematics = stride_kinematics(t, angles, stride)
            measured.update(result.kinematics)
            result.percent = self.percent
            result.curves = {name: normalise_stride(t, angles[:, k], stride.t_start, stride.t_end,
                                                    self.percent) for k, name in enumerate(SAGITTAL)}
        measured["stance_fraction"] = stride.stance_fraction
        measured["cadence"] = stride.cadence
        measured["step_time_symmetry"] = stride.step_time_symmetry
        result.spatial = self.spatial(stride)
        measured.update(result.spatial)
        for quantity, value in measured.items():
            band = self.targets.band(quantity, stride.side)
            if band is None or not math.isfinite(value):
                continue
            error, severity = compare(value, band)
            frequency, rate = self.targets.audio.cue(error, band)
            side = "" if QUANTITIES[quantity][1] else stride.side
            result.cues.append(Cue(quantity, side, band.unit, value, band.low, band.high, error, severity,
                                   frequency, rate, stride.index, stride.end_ns))
        return result


def select_audio_cue(cues: Iterable[Cue], side: str = "both", joint: str = "all") -> Cue | None:
    """The cue to sound: the largest error (in band widths) among ``cues`` of the chosen ``side``
    ("left", "right", "both") and ``joint`` group ("hip", "knee", "ankle", "timing", "all"); None when all
    chosen cues are inside their bands (silence)."""
    best, best_e = None, 0.0
    for c in cues:
        if side != "both" and c.side not in ("", side):
            continue
        if joint != "all" and c.joint != joint:
            continue
        width = c.band_high - c.band_low
        e = abs(c.error) / width if width > 0 else abs(c.error)
        if c.severity != SEVERITY_IN_BAND and e > best_e:
            best, best_e = c, e
    return best


_OBLIQUE = (0.35, 0.18)  # screen offset per metre of right-lateral depth (x, y): a slight 3/4 view


def sagittal_stick_figure(angles: Mapping[str, float], lengths: BodyDimensions | None = None
                          ) -> list[tuple[str, float, float, float, float]]:
    """2D stick figure [(segment, x0, y0, x1, y1)] (m) of the pelvis and legs from joint angles (rad,
    JointState names), pelvis upright at the origin, x anterior, y up (EXT: the pelvis orientation is
    not in JointState, so the pelvis is drawn level). Uses
    :func:`~gait_biofeedback.core.joints.skeleton.stick_figure` with
    segment orientations relative to the pelvis and an oblique projection so both legs and the pelvis
    width are visible (the right leg is drawn nearer, lower and to the left)."""
    orientations: dict[str, np.ndarray] = {"pelvis": np.array([1.0, 0.0, 0.0, 0.0])}
    for side in SIDES:
        q = orientations["pelvis"]
        for joint, seg in (("hip", "thigh"), ("knee", "shank"), ("ankle", "foot")):
            names = joint_angle_names(side, joint)
            if names[0] not in angles:
                break
            rel = relative_rotation_from_angles(joint, side, *(float(angles.get(n, 0.0)) for n in names))
            q = multiply(q, rel)
            orientations[f"{side}_{seg}"] = q
    ox, oy = _OBLIQUE
    out = []
    for seg, a, b in stick_figure(orientations, lengths):
        out.append((seg, float(a[0] - ox * a[2]), float(a[1] - oy * a[2]),
                    float(b[0] - ox * b[2]), float(b[1] - oy * b[2])))
    return out
