"""Synthetic multi-IMU gait sessions with exact ground truth (kinematic body model + IMU model).

Body: pelvis, chest and per leg thigh, shank, foot with ISB anatomical frames (x anterior, y superior, z
right). Orientations (segment→world, ENU) are built from the pelvis heading/attitude and clinical joint
angles through the simulator's own JCS (:mod:`gait_biofeedback.sim.joints`, gait.md §1.8, written with
SciPy apart from the code it tests; it also gives the true joint angles); positions by forward
kinematics from the pelvis (origin at the mid-hip point). Loaded feet do not slide: the pelvis position
is the weighted mean of ``pin_c - r_c(t)`` over contacts c (left foot, right foot, "free" =
bed/support), where ``r_c`` is the vector from the pelvis to the contact point (heel while the foot is
toe-up, toe while toe-down: a rolling heel → flat → toe foot), weights are C² and sum to 1, and each pin
is fixed in the world when its weight becomes positive (feet pinned at ground height z = 0). READING:
during double support the two legs' geometries disagree by a few cm; the weight blend absorbs it as a
small slide of the unloading foot.

Walking bouts (contiguous walk/turn phases): the pose blends from standing to the walking pattern frozen
at mid double support (weights 0.5/0.5, so no weight jump), the cadence ramps up (C²), steps, ramps down to
the same frozen phase a whole number of strides later and the pose blends back to standing (the feet slide
together/apart during these 1 s blends). Truth IC/TC = gait phase crossing 0 / the stance fraction, also
during the cadence ramps; each IC is a step. The hip flexion range is scaled (secant search) so the steady
pelvis speed equals ``speed``. During turns a foot keeps its heading through stance and turns in swing.
Transition instants in the truth are the midpoints of the transition phases (gait.md: PT = mean of start
and end).

Stairs ("stairs_up"/"stairs_down" phases, part of a walking bout): the sagittal hip/knee/foot curves blend
(C², 0.8 s around the phase bounds) to stair gait (gait_kinematics.stairs_angles) with more pelvis tilt and
trunk lean going up, and every IC raises (lowers) the ground under the new contact by ``stair_height``
times the stair blend at that IC, so the pelvis climbs (descends) one step per step. On a flight the trunk
(pelvis and chest, not the legs) then gets a height correction so that its motion at step frequency is one
sinusoid of the amplitude real trunks show (``_STAIRS_TRUNK_LIFT``, measured on hapt_waist and UCI chest
data) instead of the legs' smoother rise with double-support kinks. READING: the treads are heights only
(no nosing, any depth); the first and last steps of a flight are partial while the blend ramps; the hip
joint parts from the thigh by that correction (up to ~2 cm) on stairs.

IMU signals are analytic-consistent: every quantity is a smooth (C²) function of time, evaluated at
``t`` and ``t ± h`` (h = 0.5 ms); gyro = rotation vector of ``q(t-h)* ⊗ q(t+h)`` / 2h (sensor frame,
thesis Eq 7-8 kinematics), acc = specific force ``Rᵀ (p̈ + [0, 0, g])`` with p̈ the central second
difference, mag = constant ENU field in the sensor frame. A sensor's orientation is
``q_sensor = q_segment ⊗ conj(r)`` for the mounting rotation r (``q_segment = q_sensor ⊗ r``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.segments import GRAVITY, SEGMENTS, SIDES, ImuSeries
from gait_biofeedback.sim.joints import joint_rotation, true_joint_angles
from gait_biofeedback.sim.kinematics import (
    DEG,
    MAX_STANCE,
    MIN_STANCE,
    PATHOLOGIES,
    GaitPattern,
    contact_weight,
    leg_angles,
    pelvis_angles,
    smootherstep,
    stairs_angles,
    window,
)

PHASE_KINDS = ("stand", "walk", "turn", "hip_flexion", "sit", "lie", "sit_to_stand", "stand_to_sit",
               "sit_to_lie", "lie_to_sit", "stairs_up", "stairs_down")
TRANSITIONS = {"sit_to_stand": ("sitting", "standing"), "stand_to_sit": ("standing", "sitting"),
               "sit_to_lie": ("sitting", "lying"), "lie_to_sit": ("lying", "sitting")}
_POSTURE_OF = {"stand": "standing", "walk": "standing", "turn": "standing", "hip_flexion": "standing",
               "sit": "sitting", "lie": "lying", "stairs_up": "standing", "stairs_down": "standing"}
_WALKING = ("walk", "turn", "stairs_up", "stairs_down")
_STAIRS = {"stairs_up": ("up", "upstairs"), "stairs_down": ("down", "downstairs")}
_STAIRS_RAMP = 1.6  # s, blend level ↔ stair gait, centred on the phase bound
_GAIT_RAMP = 1.0  # s, angle blend standing ↔ walking pose (frozen mid double support) at the bout ends
_CADENCE_RAMP = 0.8  # s, cadence 0 ↔ nominal once the walking pose is reached / before it is left
_H = 5e-4  # s, half-step of the central differences
# The trunk's vertical motion at step frequency on stairs (amplitude of its step-frequency sinusoid, m). The
# legs of the model lift the pelvis smoothly (fundamental 2.1 cm up, 2.7 cm down at the pelvis, 1.6 / 3.2
# cm at the chest) with kinks at double support whose harmonics carry as much acceleration as the
# fundamental (effective ω = √(σ_a/σ_d) 16-18 rad/s at 11.3 rad/s steps). Real trunks rise step by step with
# the step frequency dominant: hapt_waist users 16-22 (benchmarks/activity.py data, the monitor's band:
# signal.vertical_displacement_sections over 6 s), σ_d median 2.2 cm upstairs and 2.6 cm downstairs at ω
# 10.9 and 11.7 rad/s (level 1.4 cm at 12.9); UCI chest subjects 1-7 stairs 2.1 cm at 10.4 rad/s. A
# sinusoid of amplitude σ·√2 gives these σ.
_STAIRS_TRUNK_LIFT = {"up": 0.031, "down": 0.036}
_STAIRS_LIFT_HARMONICS = 12  # the legs' harmonics 2..12 of the step frequency are removed from the trunk
_CONTACTS = ("left", "right", "free")

# Default sensor lever arms (m, in the segment frame): lateral on thigh/shank, dorsum of the foot,
# sacrum, sternum.
_LEVER_ARMS = {
    "pelvis": (-0.10, 0.05, 0.0), "chest": (0.10, 0.20, 0.0),
    "left_thigh": (0.0, -0.20, -0.08), "right_thigh": (0.0, -0.20, 0.08),
    "left_shank": (0.02, -0.15, -0.05), "right_shank": (0.02, -0.15, 0.05),
    "left_foot": (0.06, -0.02, 0.0), "right_foot": (0.06, -0.02, 0.0),
}


@dataclass
class Phase:
    """One part of a session. ``params``: walk/turn {"angle": rad (turn, + = left)}, hip_flexion
    {"side": "left"|"right"|"both", "frequency": Hz, "amplitude": rad}; stairs_up/stairs_down: none (one
    step of ``SimulationConfig.stair_height`` per IC)."""

    kind: str
    duration: float
    params: dict = field(default_factory=dict)


@dataclass
class SimulationConfig:
    """Everything a session depends on; ``simulate`` is a pure function of it (bit-identical repeats)."""

    rate_hz: float = 100.0
    seed: int = 0
    phases: list[Phase] = field(default_factory=lambda: [Phase("stand", 5.0), Phase("walk", 20.0),
                                                           Phase("stand", 5.0)])
    speed: float = 1.2  # m/s; reached by scaling the hip flexion range (see _hip_range_for_speed)
    cadence: float = 1.8  # steps/s
    stance_fraction: float = 0.6
    pathology: str | None = None  # None or a key of gait_kinematics.PATHOLOGIES ("slow")
    heading: float = 0.0  # rad, initial facing direction (0 = east, counter-clockwise)
    # IMU errors (SI). Noise std per axis per sample; bias: constant gyro bias drawn N(0, std) per axis.
    acc_noise_std: float = 0.02
    gyr_noise_std: float = 0.004
    mag_noise_std: float = 0.2e-6
    gyr_bias_std: float = 0.5 * DEG
    gyr_bias_random_walk: float = 0.0  # rad/s/√s
    mag_field: float = 50e-6  # T
    mag_inclination: float = 60.0 * DEG  # field dips below the horizon (northern hemisphere)
    # [(t0, t1, segment or None = all, (3,) world field added in T)]
    mag_disturbances: list[tuple[float, float, str | None, tuple[float, float, float]]] = field(
        default_factory=list)
    with_magnetometer: bool = True
    mounting: str | dict[str, np.ndarray] = "random"  # "random" | "aligned" | {segment: quat}
    lever_arms: dict[str, tuple[float, float, float]] | None = None
    segments: tuple[str, ...] = SEGMENTS
    # Body (adult ~1.75 m), m.
    thigh_length: float = 0.43
    shank_length: float = 0.43
    hip_width: float = 0.18
    ankle_height: float = 0.08
    heel_length: float = 0.06  # ankle → heel, backwards
    toe_length: float = 0.14  # ankle → metatarsal heads, forwards
    trunk_length: float = 0.15  # pelvis origin → chest segment origin (lumbar joint)
    stair_height: float = 0.17  # m, riser of the stairs_up / stairs_down phases
    # Hemiparetic gait (kinematics module docstring): the paretic leg's curves on this side (None: both
    # legs alike), its own stance fraction and hip flexion range (times the other side's).
    paretic_side: str | None = None
    paretic_stance_fraction: float = 0.6
    paretic_hip_range: float = 0.75
    paretic_hip_offset: float = 0.0  # rad added to the paretic hip flexion (-: more extended)
    nonparetic_hip_offset: float = 0.0  # rad, the other leg's hip flexion offset (+: flexed, shorter trail)

    def without_errors(self) -> SimulationConfig:
        """Copy with no noise, no bias and no magnetic disturbance (for consistency tests)."""
        return replace(self, acc_noise_std=0.0, gyr_noise_std=0.0, mag_noise_std=0.0, gyr_bias_std=0.0,
                       gyr_bias_random_walk=0.0, mag_disturbances=[])


@dataclass
class GroundTruth:
    """Exact truth at the sample times ``t`` (N,). Orientations (N, 4) map segment/sensor → world."""

    t: np.ndarray
    segment_orientation: dict[str, np.ndarray]
    sensor_orientation: dict[str, np.ndarray]
    segment_position: dict[str, np.ndarray]  # (N, 3) origin of each segment (pelvis: mid-hip), m
    sensor_position: dict[str, np.ndarray]
    mounting: dict[str, np.ndarray]  # r with q_segment = q_sensor ⊗ r (segment → sensor frame)
    lever_arm: dict[str, np.ndarray]  # sensor position in the segment frame, m
    gyr_bias: dict[str, np.ndarray]  # (N, 3) rad/s actually added
    joint_angles: dict[str, np.ndarray]  # JOINT_NAMES, rad
    initial_contacts: dict[str, np.ndarray]  # side → IC times, s
    terminal_contacts: dict[str, np.ndarray]
    steps: np.ndarray  # all IC times, sorted
    posture: np.ndarray  # (N,) "standing" | "sitting" | "lying"
    locomotion: np.ndarray  # (N,) "none" | "level" | "upstairs" | "downstairs"
    transitions: list[tuple[float, str]]  # (mid-time of the transition, kind)
    phases: list[tuple[float, float, str]]


@dataclass
class SimulatedSession:
    config: SimulationConfig
    imu: dict[str, ImuSeries]
    truth: GroundTruth


# ----------------------------------------------------------------------------------------------------
# Poses


def _static_pose(posture: str) -> dict[str, float]:
    """Channel values of a still posture (angles rad; free = support under the pelvis)."""
    pose = {"w_left": 0.5, "w_right": 0.5, "w_free": 0.0}
    for side in SIDES:
        pose[f"{side}_ground"] = 1.0
    if posture == "sitting":
        for side in SIDES:
            pose[f"{side}_hip_flexion"] = 90 * DEG
            pose[f"{side}_knee_flexion"] = 90 * DEG
    elif posture == "lying":
        pose.update(w_left=0.0, w_right=0.0, w_free=1.0, pelvis_tilt=90 * DEG)
        for side in SIDES:
            pose[f"{side}_ground"] = 0.0
            pose[f"{side}_ankle_dorsiflexion"] = -20 * DEG
    return pose


def _blend(a: dict, b: dict, f: np.ndarray) -> dict[str, np.ndarray]:
    keys = set(a) | set(b)
    return {k: a.get(k, 0.0) + (b.get(k, 0.0) - a.get(k, 0.0)) * f for k in keys}


def _transition(kind: str, u: np.ndarray) -> dict[str, np.ndarray]:
    """Channels of sit↔stand / sit↔lie at normalised time u in [0, 1] (reverse kinds run time backwards)."""
    if kind in ("stand_to_sit", "lie_to_sit"):
        u = 1.0 - u
    if kind in ("sit_to_stand", "stand_to_sit"):
        # forward trunk lean (bump, 40°), then thighs and knees extend; feet stay pinned
        lean = 40 * DEG * np.sin(np.pi * np.clip(u, 0, 1)) ** 2
        rise = 1.0 - smootherstep((u - 0.3) / 0.7)  # 1 = seated geometry
        ch = _blend(_static_pose("standing"), {}, np.zeros_like(u))
        ch["pelvis_tilt"] = -lean
        ch["chest_flexion"] = 0.3 * lean
        for side in SIDES:
            ch[f"{side}_hip_flexion"] = 90 * DEG * rise + lean
            ch[f"{side}_knee_flexion"] = 90 * DEG * rise
        return ch
    # sit → lie: the pelvis is supported first, the trunk goes back while the hips open, legs lift
    sit, lie = _static_pose("sitting"), _static_pose("lying")
    ch = _blend(sit, lie, smootherstep(u / 0.25))
    for key in ("w_left", "w_right", "w_free"):
        ch[key] = sit[key] + (lie[key] - sit[key]) * smootherstep(u / 0.25)
    back = smootherstep((u - 0.1) / 0.6)
    legs = smootherstep((u - 0.4) / 0.6)
    ch["pelvis_tilt"] = 90 * DEG * back
    for side in SIDES:
        ch[f"{side}_hip_flexion"] = 90 * DEG * (1.0 - back)
        ch[f"{side}_knee_flexion"] = 90 * DEG * (1.0 - legs)
        ch[f"{side}_ground"] = 1.0 - smootherstep((u - 0.3) / 0.4)
        ch[f"{side}_ankle_dorsiflexion"] = -20 * DEG * legs
    return ch


def _hip_flexion_moves(t: np.ndarray, duration: float, side: str, params: dict) -> dict[str, np.ndarray]:
    """Standing on one leg, the other swings at the hip (knee nearly straight), thesis §3.3 protocol."""
    freq = float(params.get("frequency", 1.0))
    amp = float(params.get("amplitude", 25 * DEG))
    ch = _blend(_static_pose("standing"), {}, np.zeros_like(t))
    load = smootherstep(t / 0.5) * smootherstep((duration - t) / 0.5)
    env = window(t - 0.5, duration - 1.0, 0.7)
    swing = np.sin(2 * np.pi * freq * (t - 0.5))
    other = "left" if side == "right" else "right"
    ch[f"w_{side}"] = 0.5 * (1.0 - load)
    ch[f"w_{other}"] = 0.5 * (1.0 + load)
    ch[f"{side}_hip_flexion"] = env * (10 * DEG + amp * swing)
    ch[f"{side}_knee_flexion"] = env * (12 * DEG + 8 * DEG * (1 + swing) / 2)
    ch[f"{side}_ankle_dorsiflexion"] = env * 5 * DEG
    ch[f"{side}_ground"] = 1.0 - env
    return ch


class _Plan:
    """The phase list as channel functions of continuous time."""

    def __init__(self, cfg: SimulationConfig, pattern: GaitPattern) -> None:
        self.cfg = cfg
        self.pattern = pattern
        self.patterns = _side_patterns(cfg, pattern)
        self.bounds = np.concatenate([[0.0], np.cumsum([p.duration for p in cfg.phases])])
        self.duration = float(self.bounds[-1])
        self.turns = [(self.bounds[i], p.duration, float(p.params.get("angle", 0.0)))
                      for i, p in enumerate(cfg.phases) if p.kind == "turn"]
        self.stairs = [(self.bounds[i], self.bounds[i + 1], _STAIRS[p.kind][0])
                       for i, p in enumerate(cfg.phases) if p.kind in _STAIRS]
        self.bouts: list[tuple[float, float]] = []  # contiguous walking phases
        for i, p in enumerate(cfg.phases):
            if p.kind in _WALKING:
                if self.bouts and self.bouts[-1][1] == self.bounds[i]:
                    self.bouts[-1] = (self.bouts[-1][0], self.bounds[i + 1])
                else:
                    self.bouts.append((self.bounds[i], self.bounds[i + 1]))
        self.stride_freq = cfg.cadence / 2.0
        # per bout: (t0, t1, ts, tf): stepping accelerates from ts, decelerates from tf, frozen at a phase
        # of mid double support (both feet loaded half-half, so standing weights need no ramp)
        self.freeze_phase = (self.patterns["right"].stance_fraction - 0.5) / 2.0
        self.stepping: list[tuple[float, float, float, float]] = []
        for t0, t1 in self.bouts:
            ts = t0 + 0.6 * _GAIT_RAMP
            strides = np.floor((t1 - _GAIT_RAMP - _CADENCE_RAMP - ts) * self.stride_freq + 1e-9)
            if strides < 1:
                raise ValueError(f"walking from {t0:.1f} s to {t1:.1f} s is too short for one stride; give "
                                 f"at least {_GAIT_RAMP * 1.6 + _CADENCE_RAMP + 1 / self.stride_freq:.1f} s")
            self.stepping.append((t0, t1, ts, ts + strides / self.stride_freq))
        rng = np.random.default_rng([cfg.seed, 7])
        self.sway = rng.uniform(0, 2 * np.pi, 6)

    def heading(self, t: np.ndarray) -> np.ndarray:
        psi = np.full_like(t, self.cfg.heading)
        for t0, dur, angle in self.turns:
            psi = psi + angle * smootherstep((t - t0) / dur)
        return psi

    def stairs_blend(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Blend (0..1) of stair ascent and of stair descent at ``t``: C² ramps of ``_STAIRS_RAMP`` s
        centred on the bounds of the stairs phases."""
        t = np.asarray(t, dtype=float)
        out = {"up": np.zeros_like(t), "down": np.zeros_like(t)}
        for a, b, direction in self.stairs:
            out[direction] = out[direction] + (smootherstep((t - a) / _STAIRS_RAMP + 0.5)
                                               * smootherstep((b - t) / _STAIRS_RAMP + 0.5))
        return out["up"], out["down"]

    def ground(self, t: np.ndarray) -> np.ndarray:
        """Ground height (m) under a contact that starts at ``t``: ``stair_height`` × (stair blend) summed
        over the ICs of both feet up to ``t`` (+ up, - down); 0 without stairs."""
        t = np.asarray(t, dtype=float)
        if not self.stairs:
            return np.zeros_like(t)
        ics, _ = _events(self, self.duration)
        ic = np.sort(np.concatenate([ics[s] for s in SIDES]))
        up, down = self.stairs_blend(ic)
        levels = np.concatenate([[0.0], np.cumsum(self.cfg.stair_height * (up - down))])
        return levels[np.searchsorted(ic, t, side="right")]

    def step_phase(self, t: np.ndarray) -> np.ndarray:
        """Phase of the current step (0 at each IC of either foot, 1 at the next) inside the walking bouts;
        0 outside them."""
        t = np.asarray(t, dtype=float)
        out = np.zeros_like(t)
        for t0, t1, ts, tf in self.stepping:
            sel = (t >= t0) & (t < t1)
            out[sel] = np.mod(2.0 * self.gait_phase(t[sel], ts, tf), 1.0)
        return out

    def trunk_lift(self, t: np.ndarray, chest_z: np.ndarray) -> list[tuple[float, float, np.ndarray]]:
        """Per stairs flight (start, end, coefficients): what to add to the trunk's height so that its
        step-frequency motion is one sinusoid of ``_STAIRS_TRUNK_LIFT`` (phase of the legs' own
        fundamental) instead of the legs' (see there). Fitted on the samples ``t`` (the chest heights
        ``chest_z`` the legs give) where the flight's blend is full: height = a + b·t + Σₙ cₙ cos 2πnψ +
        sₙ sin 2πnψ (ψ: step phase, n up to ``_STAIRS_LIFT_HARMONICS`` below 0.45 × the sample rate)."""
        lifts = []
        harmonics = min(_STAIRS_LIFT_HARMONICS, int(0.45 * self.cfg.rate_hz / self.cfg.cadence))
        for a, b, direction in self.stairs:
            sel = (t >= a + 0.5 * _STAIRS_RAMP) & (t <= b - 0.5 * _STAIRS_RAMP)
            if harmonics < 1 or np.count_nonzero(sel) < 2 * harmonics + 3:
                continue
            basis = self._lift_basis(t[sel], harmonics)
            design = np.column_stack([np.ones(np.count_nonzero(sel)), t[sel], basis])
            coef = np.linalg.lstsq(design, chest_z[sel], rcond=None)[0][2:]
            fundamental = np.hypot(coef[0], coef[1])
            target = np.zeros_like(coef)
            if fundamental > 0:
                target[:2] = coef[:2] * _STAIRS_TRUNK_LIFT[direction] / fundamental
            lifts.append((a, b, target - coef))
        return lifts

    def _lift_basis(self, t: np.ndarray, harmonics: int) -> np.ndarray:
        psi = 2.0 * np.pi * self.step_phase(t)
        return np.column_stack([f(n * psi) for n in range(1, harmonics + 1) for f in (np.cos, np.sin)])

    def lift_height(self, t: np.ndarray, lifts: list[tuple[float, float, np.ndarray]]) -> np.ndarray:
        """Height (m) added to the trunk at ``t``: each flight's correction times its stairs blend."""
        t = np.asarray(t, dtype=float)
        out = np.zeros_like(t)
        for a, b, delta in lifts:
            blend = smootherstep((t - a) / _STAIRS_RAMP + 0.5) * smootherstep((b - t) / _STAIRS_RAMP + 0.5)
            out += blend * (self._lift_basis(t, len(delta) // 2) @ delta)
        return out

    def gait_phase(self, t: np.ndarray, ts: float, tf: float) -> np.ndarray:
        """Left gait phase of a bout: frozen at mid double support, C² cadence ramps at ts and tf."""
        r = _CADENCE_RAMP
        return self.freeze_phase + self.stride_freq * r * (_ramp_integral((t - ts) / r)
                                                           - _ramp_integral((t - tf) / r))

    def gait_window(self, t: np.ndarray, t0: float, t1: float, tf: float) -> np.ndarray:
        """Blend 0 (standing pose) → 1 (walking pose) of a bout."""
        ramp_in = smootherstep((t - t0) / _GAIT_RAMP)
        return ramp_in * (1.0 - smootherstep((t - tf - _CADENCE_RAMP) / _GAIT_RAMP))

    def channels(self, t: np.ndarray) -> dict[str, np.ndarray]:
        idx = np.clip(np.searchsorted(self.bounds, t, side="right") - 1, 0, len(self.cfg.phases) - 1)
        out: dict[str, np.ndarray] = {}
        for i, phase in enumerate(self.cfg.phases):
            sel = idx == i
            if not np.any(sel):
                continue
            tl = t[sel] - self.bounds[i]
            if phase.kind in _WALKING:
                continue
            if phase.kind in TRANSITIONS:
                ch = _transition(phase.kind, tl / phase.duration)
            elif phase.kind == "hip_flexion":
                side = phase.params.get("side", "both")
                if side == "both":
                    half = phase.duration / 2
                    first = tl < half
                    ch = _hip_flexion_moves(np.where(first, tl, tl - half), half, "left", phase.params)
                    ch2 = _hip_flexion_moves(tl - half, half, "right", phase.params)
                    ch = {k: np.where(first, ch.get(k, 0.0), ch2.get(k, 0.0)) for k in set(ch) | set(ch2)}
                else:
                    ch = _hip_flexion_moves(tl, phase.duration, side, phase.params)
            else:
                ch = _blend(_static_pose(_POSTURE_OF[phase.kind]), {}, np.zeros_like(tl))
            _put(out, ch, sel, t.shape)
        for bout in self.stepping:
            sel = (t >= bout[0]) & (t < bout[1])
            if np.any(sel):
                _put(out, self._walking(t[sel], *bout), sel, t.shape)
        self._add_sway(out, t)
        return out

    def _walking(self, t: np.ndarray, t0: float, t1: float, ts: float, tf: float) -> dict[str, np.ndarray]:
        stand = _static_pose("standing")
        s_angle = self.gait_window(t, t0, t1, tf)
        p_left = self.gait_phase(t, ts, tf)
        up, down = self.stairs_blend(t)
        walk = dict(pelvis_angles(p_left, self.pattern, up, down))
        for side, p in (("left", p_left), ("right", p_left + 0.5)):
            angles = leg_angles(p, self.patterns[side])
            for direction, f in (("up", up), ("down", down)):
                if np.any(f > 0):
                    for name, value in stairs_angles(p, self.pattern, direction).items():
                        angles[name] = angles[name] + (value - angles[name]) * f
            for name, value in angles.items():
                walk[f"{side}_{name}"] = value
            walk[f"{side}_foot_yaw"] = self._foot_yaw(t, p, self.patterns[side].stance_fraction)
            walk[f"w_{side}"] = contact_weight(p, self.patterns[side].stance_fraction,
                                               self.patterns[side].other_stance_fraction)
            walk[f"{side}_ground"] = np.ones_like(t)
        out = _blend(stand, walk, s_angle)
        for side in SIDES:
            out[f"w_{side}"] = 0.5 + (walk[f"w_{side}"] - 0.5) * s_angle
        out["w_free"] = np.zeros_like(t)
        return out

    def _foot_yaw(self, t: np.ndarray, p: np.ndarray, st: float) -> np.ndarray:
        """Foot heading relative to the pelvis heading: fixed during stance, turns during swing."""
        frac = np.mod(p, 1.0)
        t_ic = t - frac / self.stride_freq
        psi_prev, psi_next = self.heading(t_ic), self.heading(t_ic + 1.0 / self.stride_freq)
        f = smootherstep((frac - st) / (1.0 - st))
        return psi_prev + (psi_next - psi_prev) * f - self.heading(t)

    def _add_sway(self, out: dict[str, np.ndarray], t: np.ndarray) -> None:
        ph = self.sway
        a = 0.3 * DEG
        out["pelvis_tilt"] = out.get("pelvis_tilt", 0.0) + a * (np.sin(2 * np.pi * 0.23 * t + ph[0])
                                                                 + 0.5 * np.sin(2 * np.pi * 0.61 * t + ph[1]))
        out["pelvis_obliquity"] = out.get("pelvis_obliquity", 0.0) + a * np.sin(2 * np.pi * 0.31 * t + ph[2])
        out["chest_flexion"] = out.get("chest_flexion", 0.0) + a * np.sin(2 * np.pi * 0.4 * t + ph[3])


def _ramp_integral(x: np.ndarray) -> np.ndarray:
    """∫₀ˣ smootherstep: 0 before, x⁶ - 3x⁵ + 2.5x⁴ on [0, 1], x - 0.5 after."""
    x = np.asarray(x, dtype=float)
    xc = np.clip(x, 0.0, 1.0)
    return np.where(x > 1.0, x - 0.5, xc**4 * (xc * (xc - 3.0) + 2.5))


def _put(out: dict[str, np.ndarray], ch: dict, sel: np.ndarray, shape: tuple) -> None:
    for k, v in ch.items():
        if k not in out:
            out[k] = np.zeros(shape)
        out[k][sel] = v
    for k in out:
        if k not in ch:
            out[k][sel] = 0.0


_Q_UPRIGHT = quat.from_axis_angle([1.0, 0.0, 0.0], np.pi / 2)  # anatomical (x fwd, y up, z right) → ENU


def _upright(yaw: np.ndarray) -> np.ndarray:
    return quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], yaw), _Q_UPRIGHT)


def _zxy(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return joint_rotation("right", "hip", a, b, c)


class _Body:
    """Orientations and pelvis-relative point vectors of all segments for a set of channel values."""

    def __init__(self, cfg: SimulationConfig, ch: dict[str, np.ndarray], psi: np.ndarray) -> None:
        g = lambda k: ch.get(k, np.zeros_like(psi))  # noqa: E731
        q = {"pelvis": quat.multiply(_upright(psi), _zxy(g("pelvis_tilt"), g("pelvis_obliquity"),
                                                          g("pelvis_rotation")))}
        q["chest"] = quat.multiply(q["pelvis"], _zxy(-g("chest_flexion"), 0.0 * psi, 0.0 * psi))
        rp = quat.as_matrix(q["pelvis"])
        self.points = {"pelvis": np.zeros((*psi.shape, 3)), "chest": rp[..., :, 1] * cfg.trunk_length}
        self.contacts: dict[str, np.ndarray] = {"free": np.zeros((*psi.shape, 3))}
        foot_len = cfg.heel_length + cfg.toe_length
        for side in SIDES:
            sgn = 1.0 if side == "right" else -1.0
            thigh = quat.multiply(q["pelvis"], joint_rotation(
                side, "hip", g(f"{side}_hip_flexion"), g(f"{side}_hip_adduction"),
                g(f"{side}_hip_internal_rotation")))
            shank = quat.multiply(thigh, joint_rotation(
                side, "knee", g(f"{side}_knee_flexion"), g(f"{side}_knee_adduction"),
                g(f"{side}_knee_internal_rotation")))
            foot_chain = quat.multiply(shank, joint_rotation(
                side, "ankle", g(f"{side}_ankle_dorsiflexion"), g(f"{side}_ankle_inversion"),
                g(f"{side}_ankle_internal_rotation")))
            foot_ground = quat.multiply(_upright(psi + g(f"{side}_foot_yaw")),
                                        quat.from_axis_angle([0.0, 0.0, 1.0], g(f"{side}_foot_pitch")))
            foot = quat.slerp(foot_chain, foot_ground, np.clip(g(f"{side}_ground"), 0.0, 1.0))
            q[f"{side}_thigh"], q[f"{side}_shank"], q[f"{side}_foot"] = thigh, shank, foot
            hip = rp[..., :, 2] * (sgn * cfg.hip_width / 2)
            knee = hip - quat.as_matrix(thigh)[..., :, 1] * cfg.thigh_length
            ankle = knee - quat.as_matrix(shank)[..., :, 1] * cfg.shank_length
            rf = quat.as_matrix(foot)
            heel = ankle - rf[..., :, 0] * cfg.heel_length - rf[..., :, 1] * cfg.ankle_height
            toe = heel + rf[..., :, 0] * foot_len
            fwd = rf[..., :, 0] * np.array([1.0, 1.0, 0.0])
            fwd = fwd / np.linalg.norm(fwd, axis=-1, keepdims=True)
            # rolling foot: pivot on the heel while toe-up, on the toe while toe-down (same when flat)
            self.contacts[side] = np.where(rf[..., 2:3, 0] >= 0.0, heel, toe - fwd * foot_len)
            self.points[f"{side}_thigh"], self.points[f"{side}_shank"] = hip, knee
            self.points[f"{side}_foot"] = ankle
        self.orientation = q
        self.weights = {c: np.clip(g(f"w_{c}"), 0.0, 1.0) for c in _CONTACTS}


def _pins(body: _Body, ground: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """World pin (N, 3) of each contact at every sample, fixed while its weight stays positive; a foot's pin
    is at the ground height ``ground[k]`` (m, default 0) of the sample ``k`` where its contact starts."""
    n = body.weights["free"].shape[0]
    active = {c: body.weights[c] > 0.0 for c in _CONTACTS}
    pins = {c: np.full((n, 3), np.nan) for c in _CONTACTS}
    starts = sorted((k, c) for c in _CONTACTS
                    for k in np.flatnonzero(active[c] & ~np.concatenate([[False], active[c][:-1]])))
    current: dict[str, np.ndarray] = {}
    for k, c in starts:
        others = [o for o in _CONTACTS if o != c and active[o][k] and o in current]
        w = np.array([body.weights[o][k] for o in others])
        if others and w.sum() > 0:
            pelvis = sum(wi * (current[o] - body.contacts[o][k]) for wi, o in zip(w, others, strict=True))
            pelvis = pelvis / w.sum()
        elif c == "free":
            pelvis = np.array([0.0, 0.0, 0.5])
        else:
            pelvis = np.array([0.0, 0.0, -body.contacts[c][k][2]])
        pin = pelvis + body.contacts[c][k]
        if c != "free":
            pin[2] = 0.0 if ground is None else ground[k]
        current[c] = pin
        end = k + int(np.argmin(active[c][k:])) if not active[c][k:].all() else n
        pins[c][k:end] = pin
        pins[c][max(k - 1, 0)] = pin  # the step before the start (weight 0 at t, > 0 just after)
        if end < n:
            pins[c][end] = pin
    for c in _CONTACTS:
        pins[c] = np.nan_to_num(pins[c])
    return pins


def _pelvis_position(body: _Body, pins: dict[str, np.ndarray]) -> np.ndarray:
    total = sum(body.weights[c] for c in _CONTACTS)
    pos = sum(body.weights[c][..., None] * (pins[c] - body.contacts[c]) for c in _CONTACTS)
    with np.errstate(invalid="ignore"):  # no contact loaded: NaN (before a recording that starts walking)
        return pos / total[..., None]


# ----------------------------------------------------------------------------------------------------
# Simulation


def _validate(cfg: SimulationConfig) -> None:
    if not (np.isfinite(cfg.rate_hz) and cfg.rate_hz >= 10.0):
        raise ValueError(f"rate_hz must be >= 10 Hz, got {cfg.rate_hz}")
    if not cfg.phases:
        raise ValueError("phases is empty: give at least one Phase")
    if not 0.3 <= cfg.cadence <= 3.0:
        raise ValueError(f"cadence {cfg.cadence} steps/s outside the simulated range [0.3, 3.0]")
    if not 0.05 <= cfg.speed <= 2.5:
        raise ValueError(f"speed {cfg.speed} m/s outside the simulated range [0.05, 2.5]")
    if not MIN_STANCE <= cfg.stance_fraction <= MAX_STANCE:
        raise ValueError(f"stance_fraction {cfg.stance_fraction} outside [{MIN_STANCE}, {MAX_STANCE}]")
    if not (np.isfinite(cfg.stair_height) and 0.0 <= cfg.stair_height <= 0.25):
        raise ValueError(f"stair_height {cfg.stair_height} m outside [0, 0.25]")
    if cfg.paretic_side not in (None, *SIDES):
        raise ValueError(f"paretic_side must be None, 'left' or 'right', got {cfg.paretic_side!r}")
    if not MIN_STANCE <= cfg.paretic_stance_fraction <= MAX_STANCE:
        raise ValueError(f"paretic_stance_fraction {cfg.paretic_stance_fraction} outside [{MIN_STANCE}, "
                         f"{MAX_STANCE}]")
    if not 0.2 <= cfg.paretic_hip_range <= 1.5:
        raise ValueError(f"paretic_hip_range {cfg.paretic_hip_range} outside [0.2, 1.5]")
    if cfg.pathology is not None and cfg.pathology not in PATHOLOGIES:
        raise ValueError(f"unknown pathology {cfg.pathology!r}; expected None or one of "
                         f"{sorted(PATHOLOGIES)}")
    unknown = [s for s in cfg.segments if s not in SEGMENTS]
    if unknown:
        raise ValueError(f"unknown segments {unknown}; expected names from {SEGMENTS}")
    if isinstance(cfg.mounting, str) and cfg.mounting not in ("random", "aligned"):
        raise ValueError(f"mounting must be 'random', 'aligned' or {{segment: quaternion}}, "
                         f"got {cfg.mounting!r}")
    posture = None
    for i, ph in enumerate(cfg.phases):
        where = f"phase {i} ({ph.kind!r})"
        if ph.kind not in PHASE_KINDS:
            raise ValueError(f"{where}: unknown kind; expected one of {PHASE_KINDS}")
        minimum = 2.0 if ph.kind in TRANSITIONS or ph.kind in _WALKING else 0.5
        if ph.kind == "hip_flexion":
            minimum = 6.0 if ph.params.get("side", "both") == "both" else 3.0
        if not (np.isfinite(ph.duration) and ph.duration >= minimum):
            raise ValueError(f"{where}: duration {ph.duration} s is shorter than the minimum {minimum} s")
        if ph.kind == "hip_flexion" and ph.params.get("side", "both") not in ("left", "right", "both"):
            raise ValueError(f"{where}: side must be 'left', 'right' or 'both'")
        start, end = TRANSITIONS.get(ph.kind, (_POSTURE_OF.get(ph.kind),) * 2)
        if posture is not None and start != posture:
            raise ValueError(f"{where} starts {start} but the previous phase ends {posture}; "
                             "insert a transition (sit_to_stand, stand_to_sit, sit_to_lie, lie_to_sit)")
        posture = end


def _pattern(cfg: SimulationConfig, hip_range: float = 1.0) -> GaitPattern:
    scales = PATHOLOGIES.get(cfg.pathology, {}) if cfg.pathology else {}
    return GaitPattern(stance_fraction=cfg.stance_fraction,
                       hip_range=hip_range * scales.get("hip_range", 1.0),
                       knee_range=scales.get("knee_range", 1.0), foot_range=scales.get("foot_range", 1.0),
                       frontal_range=scales.get("frontal_range", 1.0))


def _side_patterns(cfg: SimulationConfig, pattern: GaitPattern) -> dict[str, GaitPattern]:
    """Each leg's pattern: both ``pattern``, or the paretic side's own curves, stance and hip range."""
    if cfg.paretic_side is None:
        return dict.fromkeys(SIDES, pattern)
    paretic = replace(pattern, paretic=True, stance_fraction=cfg.paretic_stance_fraction,
                      hip_range=pattern.hip_range * cfg.paretic_hip_range, hip_offset=cfg.paretic_hip_offset,
                      other_stance_fraction=pattern.stance_fraction)
    other = replace(pattern, other_stance_fraction=cfg.paretic_stance_fraction,
                    hip_offset=cfg.nonparetic_hip_offset)
    return {side: paretic if side == cfg.paretic_side else other for side in SIDES}


def _kinematics(cfg: SimulationConfig, pattern: GaitPattern, t: np.ndarray, offsets: tuple[float, ...]):
    """Bodies and pelvis positions at ``t + offset`` for each offset (pins from the samples ``t``)."""
    plan = _Plan(cfg, pattern)
    bodies = []
    for dt in offsets:
        tt = t + dt
        bodies.append(_Body(cfg, plan.channels(tt), plan.heading(tt)))
    pins = _pins(bodies[0], plan.ground(t) if plan.stairs else None)
    return plan, bodies, [_pelvis_position(b, pins) for b in bodies]


def _walking_speed(cfg: SimulationConfig, hip_range: float) -> float:
    """Mean forward pelvis speed of steady straight walking with a given hip flexion range scale."""
    stride = 2.0 / cfg.cadence
    t_start = 0.6 * _GAIT_RAMP + _CADENCE_RAMP + 0.2  # steady cadence from here on
    t_stop = t_start + 4 * stride
    probe = replace(cfg, phases=[Phase("walk", t_stop + _CADENCE_RAMP + _GAIT_RAMP + stride)], heading=0.0)
    t = np.linspace(0.0, t_stop, round(t_stop * 50) + 1)  # pins need the dense sequence of samples
    _, _, (pelvis,) = _kinematics(probe, _pattern(probe, hip_range), t, (0.0,))
    i0 = int(np.argmin(np.abs(t - t_start)))
    return float((pelvis[-1, 0] - pelvis[i0, 0]) / (t[-1] - t[i0]))


def _hip_range_for_speed(cfg: SimulationConfig) -> float:
    """Hip flexion range scale giving ``cfg.speed`` at ``cfg.cadence`` (secant on the emergent speed)."""
    if not any(p.kind in _WALKING for p in cfg.phases):
        return 1.0
    x0, x1 = 0.6, 1.2
    f0, f1 = _walking_speed(cfg, x0) - cfg.speed, _walking_speed(cfg, x1) - cfg.speed
    for _ in range(4):
        if abs(f1 - f0) < 1e-9:
            break
        x0, x1, f0 = x1, x1 - f1 * (x1 - x0) / (f1 - f0), f1
        x1 = float(np.clip(x1, 0.05, 2.5))
        f1 = _walking_speed(cfg, x1) - cfg.speed
        if abs(f1) < 2e-3:
            break
    if abs(f1) > 0.05:
        raise ValueError(f"speed {cfg.speed} m/s is not reachable at cadence {cfg.cadence} steps/s "
                         f"(step length {cfg.speed / cfg.cadence:.2f} m)")
    return x1


def _mountings(cfg: SimulationConfig, rng: np.random.Generator) -> dict[str, np.ndarray]:
    out = {}
    for seg in SEGMENTS:  # draw for every segment so the subset chosen does not change the others
        r = quat.canonical(quat.normalize(rng.normal(size=4)))
        if cfg.mounting == "aligned":
            r = quat.IDENTITY.copy()
        elif isinstance(cfg.mounting, dict):
            r = quat.normalize(np.asarray(cfg.mounting.get(seg, quat.IDENTITY), dtype=float))
        out[seg] = r
    return out


def _events(plan: _Plan, t_end: float) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """IC (gait phase crosses an integer) and TC (crosses the stance fraction) times per side, found on a
    0.1 ms grid with linear interpolation, inside the stepping part of each walking bout."""
    ics: dict[str, list[float]] = {s: [] for s in SIDES}
    tcs: dict[str, list[float]] = {s: [] for s in SIDES}
    for _t0, t1, ts, tf in plan.stepping:
        tt = np.arange(ts, min(tf + _CADENCE_RAMP, t1, t_end), 1e-4)
        p = plan.gait_phase(tt, ts, tf)
        for side, shift in (("left", 0.0), ("right", 0.5)):
            st = plan.patterns[side].stance_fraction
            for target, store in ((0.0, ics[side]), (st, tcs[side])):
                level = np.floor(p + shift - target)
                k = np.flatnonzero(np.diff(level) > 0)
                frac = (level[k + 1] - (p[k] + shift - target)) / (p[k + 1] - p[k])
                store.extend((tt[k] + frac * (tt[k + 1] - tt[k])).tolist())
    return {s: np.array(sorted(v)) for s, v in ics.items()}, {s: np.array(sorted(v)) for s, v in tcs.items()}


def _labels(cfg: SimulationConfig, plan: _Plan, t: np.ndarray):
    posture = np.empty(t.shape, dtype=object)
    locomotion = np.full(t.shape, "none", dtype=object)
    transitions, phases = [], []
    for i, ph in enumerate(cfg.phases):
        t0, t1 = plan.bounds[i], plan.bounds[i + 1]
        sel = (t >= t0) & (t < t1)
        phases.append((float(t0), float(t1), ph.kind))
        if ph.kind in TRANSITIONS:
            mid = 0.5 * (t0 + t1)
            posture[sel & (t < mid)], posture[sel & (t >= mid)] = TRANSITIONS[ph.kind]
            transitions.append((float(mid), ph.kind))
        else:
            posture[sel] = _POSTURE_OF[ph.kind]
    for _t0, _t1, ts, tf in plan.stepping:
        stepping = (t >= ts) & (t < tf + _CADENCE_RAMP)
        locomotion[stepping] = "level"
        for i, ph in enumerate(cfg.phases):
            if ph.kind in _STAIRS:
                locomotion[stepping & (t >= plan.bounds[i]) & (t < plan.bounds[i + 1])] = _STAIRS[ph.kind][1]
    return posture.astype(str), locomotion.astype(str), transitions, phases


def simulate(config: SimulationConfig) -> SimulatedSession:
    """Simulate the IMUs of ``config.segments`` and the exact ground truth (see module docstring)."""
    cfg = config
    _validate(cfg)
    rng = np.random.default_rng(cfg.seed)
    pattern = _pattern(cfg, _hip_range_for_speed(cfg))
    n = int(np.floor(sum(p.duration for p in cfg.phases) * cfg.rate_hz + 1e-9))
    t = np.arange(n) / cfg.rate_hz
    plan, (b0, bm, bp), (p0, pm, pp) = _kinematics(cfg, pattern, t, (0.0, -_H, _H))
    pm = np.where(np.isfinite(pm), pm, 2 * p0 - pp)  # t - H before a walk's start: no acceleration there
    # on stairs the trunk (pelvis, chest) rises step by step as real trunks do (_STAIRS_TRUNK_LIFT); the legs
    # hang from the pelvis the legs' geometry gives, so the feet stay pinned
    lifts = plan.trunk_lift(t, p0[:, 2] + b0.points["chest"][:, 2]) if plan.stairs else []
    trunk = [p.copy() for p in (p0, pm, pp)]
    for p, dt in zip(trunk, (0.0, -_H, _H), strict=True):
        p[:, 2] += plan.lift_height(t + dt, lifts)
    mounting = _mountings(cfg, rng)
    levers = {s: np.asarray((cfg.lever_arms or {}).get(s, _LEVER_ARMS[s]), dtype=float) for s in SEGMENTS}
    mag_world = cfg.mag_field * np.array([0.0, np.cos(cfg.mag_inclination), -np.sin(cfg.mag_inclination)])

    imu: dict[str, ImuSeries] = {}
    seg_q, sen_q, seg_p, sen_p, biases = {}, {}, {}, {}, {}
    for seg in SEGMENTS:
        seg_rng = np.random.default_rng([cfg.seed, SEGMENTS.index(seg), 1])
        r_conj = quat.conjugate(mounting[seg])
        qs = [quat.multiply(b.orientation[seg], r_conj) for b in (b0, bm, bp)]
        pelvis = trunk if seg in ("pelvis", "chest") else (p0, pm, pp)
        ps = [pel + b.points[seg] + quat.rotate(b.orientation[seg], levers[seg])
              for pel, b in zip(pelvis, (b0, bm, bp), strict=True)]
        seg_q[seg], sen_q[seg] = b0.orientation[seg], qs[0]
        seg_p[seg], sen_p[seg] = pelvis[0] + b0.points[seg], ps[0]
        gyr = quat.as_rotvec(quat.multiply(quat.conjugate(qs[1]), qs[2])) / (2 * _H)
        acc_world = (ps[2] - 2.0 * ps[0] + ps[1]) / _H**2 + np.array([0.0, 0.0, GRAVITY])
        acc = quat.rotate_inverse(qs[0], acc_world)
        bias = np.broadcast_to(seg_rng.normal(0.0, cfg.gyr_bias_std, 3), (n, 3))
        if cfg.gyr_bias_random_walk > 0:
            steps = seg_rng.normal(0.0, cfg.gyr_bias_random_walk / np.sqrt(cfg.rate_hz), (n, 3))
            bias = bias + np.cumsum(steps, axis=0)
        biases[seg] = np.array(bias)
        gyr = gyr + biases[seg] + seg_rng.normal(0.0, 1.0, (n, 3)) * cfg.gyr_noise_std
        acc = acc + seg_rng.normal(0.0, 1.0, (n, 3)) * cfg.acc_noise_std
        mag = None
        if cfg.with_magnetometer:
            field_w = np.broadcast_to(mag_world, (n, 3)).copy()
            for d0, d1, dseg, vec in cfg.mag_disturbances:
                if dseg is None or dseg == seg:
                    field_w[(t >= d0) & (t < d1)] += np.asarray(vec, dtype=float)
            mag = quat.rotate_inverse(qs[0], field_w) + seg_rng.normal(0.0, 1.0, (n, 3)) * cfg.mag_noise_std
        if seg in cfg.segments:
            imu[seg] = ImuSeries(segment=seg, t=t, acc=acc, gyr=gyr, mag=mag)

    ics, tcs = _events(plan, t[-1] + 1.0 / cfg.rate_hz)
    posture, locomotion, transitions, phases = _labels(cfg, plan, t)
    truth = GroundTruth(
        t=t, segment_orientation=seg_q, sensor_orientation=sen_q, segment_position=seg_p,
        sensor_position=sen_p, mounting=mounting, lever_arm=levers, gyr_bias=biases,
        joint_angles=true_joint_angles(seg_q), initial_contacts=ics, terminal_contacts=tcs,
        steps=np.sort(np.concatenate([ics["left"], ics["right"]])), posture=posture, locomotion=locomotion,
        transitions=transitions, phases=phases)
    return SimulatedSession(config=cfg, imu=imu, truth=truth)


# ----------------------------------------------------------------------------------------------------
# Scenarios


def _cfg(phases: list[Phase], **kw) -> SimulationConfig:
    return SimulationConfig(phases=phases, **kw)


def demo(**kw) -> SimulationConfig:
    """~103 s: standing, hip-flexion calibration (both legs, ~14 moves each), walking with a 180° turn,
    sit, stand."""
    return _cfg([Phase("stand", 5.0), Phase("hip_flexion", 30.0, {"side": "both"}), Phase("stand", 5.0),
                 Phase("walk", 16.0), Phase("turn", 4.0, {"angle": np.pi}), Phase("walk", 20.0),
                 Phase("stand", 3.0), Phase("stand_to_sit", 2.5), Phase("sit", 10.0),
                 Phase("sit_to_stand", 2.5), Phase("stand", 5.0)], **kw)


def walk(duration: float = 30.0, **kw) -> SimulationConfig:
    """Standing 5 s, straight walking, standing 3 s."""
    return _cfg([Phase("stand", 5.0), Phase("walk", duration), Phase("stand", 3.0)], **kw)


def calibration_hip_flexion(**kw) -> SimulationConfig:
    """Quiet standing 5 s, then 12 hip flexion/extension moves at 1 Hz per leg (thesis §3.6 protocol)."""
    phases = [Phase("stand", 5.0), Phase("hip_flexion", 28.0, {"side": "both"}), Phase("stand", 2.0)]
    return _cfg(phases, **kw)


def calibration_walking(**kw) -> SimulationConfig:
    """Quiet standing 5 s, then straight walking with >= 8 steps (PC8 protocol), standing 2 s."""
    return _cfg([Phase("stand", 5.0), Phase("walk", 7.0), Phase("stand", 2.0)], **kw)


TRAINING_LAP = (("walk", 20.0, {}), ("turn", 4.0, {"angle": np.pi}), ("walk", 20.0, {}), ("stand", 6.0, {}))
"""One lap of :func:`training`: 50 s."""


def training(duration: float = 600.0, **kw) -> SimulationConfig:
    """A walking-training session of ``duration`` s (at least 60): standing 5 s, the hip-flexion
    calibration 30 s, standing 5 s, then laps (walk 20 s, a 180° turn, walk 20 s, stand 6 s) until
    ``duration``, the last phase cut short (a walk or stand of under 2 s is left out)."""
    if not duration >= 60.0:
        raise ValueError(f"training: duration {duration:g} s is too short; give at least 60 s (40 s of "
                         "preamble and one walk)")
    phases = [Phase("stand", 5.0), Phase("hip_flexion", 30.0, {"side": "both"}), Phase("stand", 5.0)]
    left = duration - 40.0
    while left >= 2.0:
        for kind, length, params in TRAINING_LAP:
            if kind == "turn" and left < length + 2.0:  # no turn into the end of the session
                left = 0.0
            if left < 2.0:
                break
            phases.append(Phase(kind, min(length, left), dict(params)))
            left -= phases[-1].duration
    return _cfg(phases, **kw)


def activity(**kw) -> SimulationConfig:
    """Sit / stand / walk / lie sequence for the chest activity monitor (thesis Ch. 7)."""
    return _cfg([Phase("stand", 4.0), Phase("stand_to_sit", 2.5), Phase("sit", 8.0), Phase("sit_to_lie", 3.0),
                 Phase("lie", 10.0), Phase("lie_to_sit", 3.0), Phase("sit", 5.0), Phase("sit_to_stand", 2.5),
                 Phase("stand", 3.0), Phase("walk", 15.0), Phase("stand", 3.0), Phase("stand_to_sit", 2.5),
                 Phase("sit", 5.0), Phase("sit_to_stand", 2.5), Phase("stand", 4.0)], **kw)


def slow_gait(**kw) -> SimulationConfig:
    """Slow "pathological" walking: longer stance, smaller ranges, lower cadence."""
    kw = {"speed": 0.45, "cadence": 1.2, "stance_fraction": 0.68, "pathology": "slow", **kw}
    return _cfg([Phase("stand", 5.0), Phase("walk", 30.0), Phase("stand", 3.0)], **kw)


def stairs(**kw) -> SimulationConfig:
    """Standing, level walking, a flight of stairs up (~12 steps), level walking, a flight down, standing."""
    return _cfg([Phase("stand", 5.0), Phase("walk", 4.0), Phase("stairs_up", 8.0), Phase("walk", 4.0),
                 Phase("stairs_down", 8.0), Phase("walk", 4.0), Phase("stand", 3.0)], **kw)


def magnet_near_thigh(**kw) -> SimulationConfig:
    """Standing, a 10 s walk (walking calibration), standing 5 s, a 40 s walk during whose middle 20 s
    (30-50 s) a magnet near the left thigh adds 30 µT horizontally to the field that sensor alone sees
    (its 9D heading turns by about 50°), standing 3 s."""
    kw = {"mag_disturbances": [(30.0, 50.0, "left_thigh", (30e-6, 0.0, 0.0))], **kw}
    return _cfg([Phase("stand", 5.0), Phase("walk", 10.0), Phase("stand", 5.0), Phase("walk", 40.0),
                 Phase("stand", 3.0)], **kw)


def hemiparetic(duration: float = 40.0, **kw) -> SimulationConfig:
    """A walker after a stroke, paretic left leg (kinematics module docstring): standing 5 s, straight
    walking ``duration`` s at 0.8 m/s and 1.6 steps/s, standing 3 s. The paretic leg: shorter stance
    (60 % vs 66 %), hip range x 0.7 about a mean 6° more extended, the other hip 6° more flexed (it
    trails less: a shorter paretic step; both trailing limb angles about half the simulated healthy
    walk's 13°), knee hyperextension in stance, a flat landing, weak push-off, circumduction. Its true
    per-stride values: :func:`gait_biofeedback.sim.stride_truth.stride_truth`."""
    kw = {"speed": 0.8, "cadence": 1.6, "stance_fraction": 0.66, "paretic_side": "left",
          "paretic_stance_fraction": 0.6, "paretic_hip_range": 0.7, "paretic_hip_offset": -6 * DEG,
          "nonparetic_hip_offset": 6 * DEG, **kw}
    return _cfg([Phase("stand", 5.0), Phase("walk", duration), Phase("stand", 3.0)], **kw)


SCENARIOS: dict[str, Callable[..., SimulationConfig]] = {
    "demo": demo,
    "walk": walk,
    "training": training,
    "calibration_hip_flexion": calibration_hip_flexion,
    "calibration_walking": calibration_walking,
    "activity": activity,
    "slow_gait": slow_gait,
    "stairs": stairs,
    "magnet_near_thigh": magnet_near_thigh,
    "hemiparetic": hemiparetic,
}
