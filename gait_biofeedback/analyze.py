"""``gait-biofeedback analyze``: a recording → the live graph's outputs, offline, without DDS.

The offline twin of replaying a bag through the node graph (DESIGN.md "Two paths, one core"): the raw
IMU messages are read from the MCAP in log-time order and handed to the same core objects, through the
same message-conversion helpers, in the same order the nodes use them:

1. orientation per segment: :class:`~gait_biofeedback.core.orientation_stream.SegmentOrientationTracker`
   (``orientation_filter`` node) → ``/<segment>/imu/data``;
2. calibration: :class:`~gait_biofeedback.core.calibration_windows.CalibrationBuffer` fed with those
   orientations; a calibration file is in force from the start (the node reloads its file), and each
   ``calibrate_at`` request calibrates on the window ending at that instant, exactly as
   :meth:`CalibrationNode.calibrate_at <gait_biofeedback.nodes.calibration.CalibrationNode.calibrate_at>`
   does in a replay → ``/calibration/sensor_to_segment``;
3. joint angles: :class:`~gait_biofeedback.core.joint_angles.JointAngleStream` → ``/joint_states``,
   ``/skeleton``;
4. gait events and strides: :class:`~gait_biofeedback.core.gait_stream.GaitEventStream` →
   ``/gait/events``, ``/gait/cycles``;
5. activity on the chest's raw accelerometer: :class:`~gait_biofeedback.core.activity.ActivityMonitor`
   → ``/activity/state``.

A calibration takes effect at the sample stamp in its message header (``apply_delay`` after the
window it was computed from), in the graph and here, so both paths switch at the same sample and give
the same numbers (test/test_analyze.py). What only exists live is left out: ``/diagnostics`` and the
wall-clock rules (a stream that stops, the joint-angle sync timeout, the activity monitor's periodic
re-publication, here every ``publish_period`` s of recording time instead).

The output bag carries the input's raw IMU and ``/ground_truth/...`` topics too, as a recording of
the live graph does, so :mod:`gait_biofeedback.report` reads it unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu

from gait_biofeedback.core.activity_stream import ActivityStream
from gait_biofeedback.core.calibration import PROTOCOLS
from gait_biofeedback.core.calibration_windows import CalibrationAttempt, CalibrationBuffer
from gait_biofeedback.core.filters import ALGORITHMS, DEFAULT_ALGORITHM
from gait_biofeedback.core.gait_stream import GaitEventStream
from gait_biofeedback.core.joint_angles import JointAngleStream
from gait_biofeedback.core.orientation_stream import SegmentOrientationTracker
from gait_biofeedback.core.segments import SEGMENTS
from gait_biofeedback.io.bag import BagReader, BagWriter
from gait_biofeedback.io.cdr import Stamped, decode_imu, decode_mag
from gait_biofeedback.io.imu_messages import IMU_TYPE, MAG_TYPE
from gait_biofeedback.io.schemas import type_name_of
from gait_biofeedback.io.session_bag import TRUTH_PREFIX
from gait_biofeedback.nodes.activity_monitor import apply_calibration_msg as apply_activity_calibration
from gait_biofeedback.nodes.activity_monitor import chest_sample
from gait_biofeedback.nodes.activity_monitor import to_message as activity_msg
from gait_biofeedback.nodes.calibration import (
    calibration_array_msg,
    imu_to_calibration_sample,
    load_calibration_file,
)
from gait_biofeedback.nodes.gait_events import (
    apply_calibration_msg,
    cycle_msg,
    event_msg,
    imu_to_foot_sample,
    stream_options,
)
from gait_biofeedback.nodes.joint_angles import (
    JOINT_SEGMENTS,
    calibration_rotations,
    imu_to_joint_sample,
    joint_state_msg,
    segment_lengths,
    skeleton_msg,
)
from gait_biofeedback.nodes.orientation_filter import mag_sample, orientation_payload, raw_imu_sample

# Defaults of the nodes this module stands in for (their declare_parameter defaults).
ORIENTATION_DEFAULTS: dict[str, Any] = {"segments": list(SEGMENTS), "algorithm": DEFAULT_ALGORITHM,
                                        "rate_hz": 100.0, "startup_s": 1.0, "max_gap": 0.5,
                                        "mag_max_age": 0.05, "orientation_variance": 0.0012}
CALIBRATION_DEFAULTS: dict[str, Any] = {"segments": list(SEGMENTS), "buffer_s": 90.0,
                                        "default_standing_duration": 3.0, "apply_delay": 0.5}
JOINT_DEFAULTS: dict[str, Any] = {"max_wait": 0.1, "remove_standing_offset": True, "offset_window_s": 2.0,
                                  "still_gyro": 0.2, "skeleton_every": 5}
ACTIVITY_DEFAULTS: dict[str, Any] = {"segment": "chest", "rate_hz": 100.0, "units": "m/s2",
                                     "reference_s": 2.0, "thigh_length": 0.42, "initial_posture": "standing",
                                     "forward_axis": [1.0, 0.0, 0.0], "max_gap": 0.5, "publish_period": 1.0}


@dataclass
class AnalysisResult:
    """What :func:`analyze_recording` produced.

    ``output``: the bag written (None: nothing written, the messages are in ``messages`` as
    ``(topic, rclpy message, log_time_ns)``); ``counts``: messages per output topic;
    ``start_time``: log time (s) of the recording's first message, the zero of ``calibrate_at``;
    ``calibrations``: every calibration request's outcome, in order (stamps in s);
    ``warnings``: what the cores said (time going back, gaps, requests that never ran)."""

    output: Path | None
    start_time: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)
    calibrations: list[CalibrationAttempt] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    messages: list[tuple[str, Any, int]] = field(default_factory=list)


def parse_calibrate_at(text: str) -> tuple[float, str]:
    """``"T:protocol"`` (T in s into the recording; protocol default hip_flexion) → (T, protocol)."""
    time_text, _, protocol = text.partition(":")
    protocol = protocol or "hip_flexion"
    try:
        t = float(time_text)
    except ValueError:
        raise ValueError(f"--calibrate-at {text!r}: expected SECONDS:PROTOCOL, e.g. 36:hip_flexion") from None
    if protocol not in PROTOCOLS or not math.isfinite(t) or t < 0:
        raise ValueError(f"--calibrate-at {text!r}: time must be >= 0 s and the protocol one of "
                         f"{list(PROTOCOLS)}")
    return t, protocol


def _settings(params: dict[str, dict] | None, node: str, defaults: dict[str, Any]) -> dict[str, Any]:
    given = dict((params or {}).get(node, {}))
    return {**defaults, **given}


class _ActivityRun:
    """The ``activity_monitor`` node offline: the same :class:`ActivityStream`, a state published on
    every change and every ``publish_period`` s of recording time (the node: of wall-clock time)."""

    def __init__(self, settings: dict[str, Any]) -> None:
        self.segment = str(settings["segment"])
        self.period = float(settings["publish_period"])
        self.stream = ActivityStream(
            float(settings["rate_hz"]), max_gap=float(settings["max_gap"]), units=settings["units"],
            reference_s=float(settings["reference_s"]), thigh_length_m=float(settings["thigh_length"]),
            initial_posture=settings["initial_posture"], forward_axis=list(settings["forward_axis"]))
        self._next_periodic: float | None = None
        self.warnings: list[str] = []  # what the node would log as warnings

    def update(self, raw: Stamped) -> list[Any]:
        t, acc = chest_sample(raw)
        out = []
        if self._next_periodic is None:
            self._next_periodic = t + self.period
        elif t >= self._next_periodic and self.stream.latest is not None:
            self._next_periodic = t + self.period
            out.append(activity_msg(self.stream.latest, t, self.segment))
        state, changed, warning = self.stream.update(t, acc)
        if warning:
            self.warnings.append(f"{self.segment}: {warning}")
        if changed:
            out.append(activity_msg(state, t, self.segment))
        return out


def _raw_topics(reader: BagReader, bag: str | Path) -> tuple[dict[str, str], dict[str, str]]:
    types = reader.topics()
    imu = {topic.split("/")[-3]: topic for topic, type_name in types.items()
           if type_name == IMU_TYPE and topic.endswith("/imu/data_raw") and topic.count("/") >= 3}
    if not imu:
        found = ", ".join(sorted(types)) or "no topics at all"
        raise ValueError(f"{bag}: no raw IMU topics (/<segment>/imu/data_raw, sensor_msgs/msg/Imu) to "
                         f"analyse (found: {found}); analyse a sensor recording, e.g. one made by "
                         "`gait-biofeedback simulate`, `import` or `record`")
    mag = {seg: topic[: -len("data_raw")] + "mag" for seg, topic in imu.items()}
    return imu, {seg: t for seg, t in mag.items() if types.get(t) == MAG_TYPE}


def analyze_recording(
    bag: str | Path,
    output: str | Path | None = None,
    calibrate_at: Sequence[tuple[float, str]] | None = None,
    calibration_file: str | Path | None = None,
    params: dict[str, dict] | None = None,
    overwrite: bool = False,
) -> AnalysisResult:
    """Run the graph's core objects over the raw IMU topics of ``bag`` (see module docstring).

    ``calibrate_at``: ``[(seconds into the recording, protocol)]``, the instants a clinician pressed
    Calibrate (each calibrates on the window ending there); ``calibration_file``: a ``calibration.yaml``
    in force from the start; ``params``: node name → parameters, as ``config/session.yaml`` /
    ``replay_through_graph(node_parameters=...)`` (orientation_filter, calibration, joint_angles,
    gait_events, activity_monitor; others are ignored). Writes the outputs to the bag folder
    ``output`` (``overwrite`` replaces an existing one). Raises ValueError for a bag without raw IMU
    topics or a bad request, FileNotFoundError for a missing bag or calibration file.
    """
    reader = BagReader(bag)
    try:
        return _analyze(reader, bag, output, list(calibrate_at or []), calibration_file, params, overwrite)
    finally:
        reader.close()


def _analyze(reader: BagReader, bag: str | Path, output: str | Path | None,
             calibrate_at: list[tuple[float, str]], calibration_file: str | Path | None,
             params: dict[str, dict] | None, overwrite: bool) -> AnalysisResult:
    raw_topics, mag_topics = _raw_topics(reader, bag)
    result = AnalysisResult(Path(output) if output is not None else None)
    for _t, protocol in calibrate_at:
        if protocol not in PROTOCOLS:
            raise ValueError(f"unknown calibration protocol {protocol!r}; use one of {list(PROTOCOLS)}")
    calibration = None
    if calibration_file is not None:
        path = Path(calibration_file)
        if not path.is_file():
            raise FileNotFoundError(f"calibration file {path} not found")
        calibration = load_calibration_file(path)

    # -- the core objects, set up from the nodes' parameters --------------------------------------
    o_set = _settings(params, "orientation_filter", ORIENTATION_DEFAULTS)
    trackers: dict[str, SegmentOrientationTracker] = {}
    for seg in [s for s in o_set["segments"] if s]:
        if seg not in SEGMENTS:
            raise ValueError(f"orientation_filter: unknown segment {seg!r}; known: {list(SEGMENTS)}")
        nested = o_set.get(seg) if isinstance(o_set.get(seg), dict) else {}
        algorithm = o_set.get(f"{seg}.algorithm") or nested.get("algorithm") or o_set["algorithm"]
        if algorithm not in ALGORITHMS:
            raise ValueError(f"orientation_filter: {seg}.algorithm {algorithm!r} is not one of "
                             f"{sorted(ALGORITHMS)}")
        if seg in raw_topics:
            trackers[seg] = SegmentOrientationTracker(
                seg, rate_hz=float(o_set["rate_hz"]), algorithm=algorithm,
                startup_s=float(o_set["startup_s"]), max_gap=float(o_set["max_gap"]),
                mag_max_age=float(o_set["mag_max_age"]))
    variance = float(o_set["orientation_variance"])
    c_set = _settings(params, "calibration", CALIBRATION_DEFAULTS)
    buffer = CalibrationBuffer([s for s in c_set["segments"] if s], float(c_set["buffer_s"]),
                               float(c_set["default_standing_duration"]), float(c_set["apply_delay"]))
    j_set = _settings(params, "joint_angles", JOINT_DEFAULTS)
    joints = JointAngleStream(JOINT_SEGMENTS, float(j_set["max_wait"]), bool(j_set["remove_standing_offset"]),
                              float(j_set["offset_window_s"]), float(j_set["still_gyro"]))
    lengths = segment_lengths(lambda name, default: j_set.get(name, default))
    skeleton_every = int(j_set["skeleton_every"])
    g_params = (params or {}).get("gait_events", {})
    gait = GaitEventStream(**stream_options(lambda name, default: g_params.get(name, default)))
    a_set = _settings(params, "activity_monitor", ACTIVITY_DEFAULTS)
    activity = _ActivityRun(a_set) if a_set["segment"] in raw_topics else None

    start_ns = reader.start_time_ns
    result.start_time = start_ns / 1_000_000_000
    for t, protocol in calibrate_at:
        buffer.schedule((start_ns + round(t * 1e9)) / 1_000_000_000, protocol)

    out: list[tuple[int, str, str, bytes]] = []
    keep = output is None
    emitted_joints = 0

    def emit(topic: str, msg: Any, log_ns: int) -> None:
        out.append((log_ns, topic, type_name_of(msg), serialize_message(msg)))
        result.counts[topic] = result.counts.get(topic, 0) + 1
        if keep:
            result.messages.append((topic, msg, log_ns))

    def emit_imu(topic: str, data: bytes, log_ns: int) -> None:
        """An Imu the node publishes as CDR bytes: recorded as those bytes."""
        out.append((log_ns, topic, IMU_TYPE, data))
        result.counts[topic] = result.counts.get(topic, 0) + 1
        if keep:
            result.messages.append((topic, deserialize_message(data, Imu), log_ns))

    def publish_calibration(msg: Any, log_ns: int) -> None:
        emit("/calibration/sensor_to_segment", msg, log_ns)
        rotations, from_ns = calibration_rotations(msg)
        joints.set_calibration(rotations, from_ns)
        apply_calibration_msg(gait, msg)
        if activity is not None:
            said([apply_activity_calibration(activity.stream, msg, activity.segment)])

    def publish_joints(emitted: list, log_ns: int) -> None:
        nonlocal emitted_joints
        for synced in emitted:
            if synced.angles:
                emit("/joint_states", joint_state_msg(synced), log_ns)
            emitted_joints += 1
            if skeleton_every > 0 and emitted_joints % skeleton_every == 0:
                emit("/skeleton", skeleton_msg(synced, lengths), log_ns)

    def said(messages: list[tuple[str, str]]) -> None:
        result.warnings.extend(text for level, text in messages if level != "info")

    def downstream(segment: str, imu: Stamped, log_ns: int) -> None:
        if segment in buffer.buffers:
            buffer.add(segment, *imu_to_calibration_sample(imu))
            if buffer.scheduled:
                for attempt in buffer.run_due():
                    result.calibrations.append(attempt)
                    if attempt.success and attempt.calibration is not None:
                        publish_calibration(calibration_array_msg(attempt.calibration, attempt.applies_from),
                                            log_ns)
        if segment in JOINT_SEGMENTS:
            ns, q, gyro_norm = imu_to_joint_sample(imu)
            publish_joints(joints.add(segment, ns, q, gyro_norm), log_ns)
        side = segment.removesuffix("_foot")
        if segment.endswith("_foot") and side in gait.detectors:
            t, q = imu_to_foot_sample(imu)
            for event, cycle in gait.update(side, t, q, imu.ns):
                emit("/gait/events", event_msg(event), log_ns)
                if cycle is not None:
                    emit("/gait/cycles", cycle_msg(cycle, gait.stamp_of), log_ns)
            said(gait.pop_messages())

    if calibration is not None:
        publish_calibration(calibration_array_msg(calibration, 0.0), start_ns)

    segment_of = {topic: seg for seg, topic in raw_topics.items()}
    mag_of = {topic: seg for seg, topic in mag_topics.items()}
    copied: list[tuple[int, str, str, bytes]] = []
    truth = [t for t in reader.topics() if t.startswith(TRUTH_PREFIX + "/")]
    for topic, type_name, data, log_ns in reader.raw_messages([*segment_of, *mag_of, *truth]):
        if output is not None:
            copied.append((log_ns, topic, type_name, data))
        if topic in truth:
            continue
        if topic in mag_of:
            seg = mag_of[topic]
            if seg in trackers:
                trackers[seg].add_mag(*mag_sample(decode_mag(data)))
            continue
        seg = segment_of[topic]
        raw = decode_imu(data)
        if activity is not None and seg == activity.segment:
            for state in activity.update(raw):
                emit("/activity/state", state, log_ns)
            result.warnings.extend(activity.warnings)
            activity.warnings.clear()
        tracker = trackers.get(seg)
        if tracker is None:
            continue
        samples = tracker.update(*raw_imu_sample(raw), raw.ns)
        said(tracker.pop_messages())
        for sample in samples:
            filtered = orientation_payload(seg, sample, raw, variance)
            emit_imu(f"/{seg}/imu/data", filtered, log_ns)
            downstream(seg, decode_imu(filtered), log_ns)
    publish_joints(joints.flush(force=True), reader.end_time_ns)
    for until, protocol in buffer.scheduled:
        result.warnings.append(f"calibration ({protocol}) at {until - start_ns * 1e-9:.2f} s never ran: "
                               "the recording ends before every sensor's data gets there")
    if output is not None:
        _write(Path(output), [*copied, *out], overwrite)
    return result


def _write(path: Path, records: list[tuple[int, str, str, bytes]], overwrite: bool) -> None:
    records.sort(key=lambda r: r[0])
    with BagWriter(path, overwrite=overwrite) as writer:
        for log_ns, topic, type_name, data in records:
            writer.write_serialized(topic, type_name, data, log_ns)
