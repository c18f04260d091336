"""``gait-biofeedback analyze``: a recording → the live graph's outputs, offline, without DDS.

The offline twin of replaying a bag through the node graph (``docs/architecture.md``, "One core, two
paths"): the raw
IMU messages are read from the MCAP in log-time order and handed to the same core objects, through the
same message-conversion helpers, in the same order the nodes use them:

1. orientation per segment: :class:`~gait_biofeedback.core.orientation.stream.SegmentOrientationTracker`
   (``orientation_filter`` node) → ``/<segment>/imu/data``, one pass over the recording
   (:mod:`gait_biofeedback.orientation_pass`) shared with an ``auto`` calibration's look-ahead;
2. calibration: :class:`~gait_biofeedback.core.calibration.stream.CalibrationBuffer` fed with those
   orientations; a calibration file is in force from the start (the node reloads its file), and each
   ``calibrate_at`` request calibrates on the window ending at that instant, exactly as
   :meth:`CalibrationNode.calibrate_at <gait_biofeedback.nodes.calibration.CalibrationNode.calibrate_at>`
   does in a replay → ``/calibration/sensor_to_segment``;
3. joint angles: :class:`~gait_biofeedback.core.joints.stream.JointAngleStream` → ``/joint_states``,
   ``/skeleton``, and the body's segment frames ``/tf`` (:mod:`~gait_biofeedback.core.joints.body_pose`,
   one per joint state, encoded in bulk before each write of the output);
4. gait events and strides: :class:`~gait_biofeedback.core.gait.stream.GaitEventStream` →
   ``/gait/events``, ``/gait/cycles``, ``/gait/stride_space``;
5. activity on the chest's raw IMU: :class:`~gait_biofeedback.core.activity.run.ActivityRun` (the
   node's stream and publications, the period on recording time) → ``/activity/state``.

Each stage is set up from the same parameters dataclass its node declares
(:data:`gait_biofeedback.parameters.NODE_PARAMETERS`), checked the same way.

A calibration takes effect at the sample stamp in its message header (``apply_delay_s`` after the
window it was computed from), in the graph and here, so both paths switch at the same sample and give
the same numbers (test/test_analyze.py). ``/diagnostics`` carries the orientation streams' statuses
(what the ``orientation_filter`` node says of each sensor: dropouts, glitches, dropped samples, rate,
6D), every ``diagnostics_period_s`` s of recording time. What only exists live is left out: the other
nodes' statuses and the wall-clock rules (a stream that stops, the joint-angle sync timeout, the
activity monitor's periodic re-publication, here every ``publish_period_s`` s of recording time
instead).

The output bag carries the input's raw IMU and ``/ground_truth/...`` topics too, as a recording of
the live graph does, so :mod:`gait_biofeedback.report.session` reads it unchanged. It is written as
the analysis goes, in log-time order (:mod:`gait_biofeedback.io.log_order`: memory does not grow with
the recording's length), into a staging folder beside the output whose files move into it when the
analysis ends well: a failed one leaves nothing.
"""

from __future__ import annotations

import math
import os
import shutil
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.activity.output import ActivityState
from gait_biofeedback.core.activity.run import ActivityRun
from gait_biofeedback.core.activity.stream import ActivityParams
from gait_biofeedback.core.calibration.find import find_calibration
from gait_biofeedback.core.calibration.protocol import WORDS
from gait_biofeedback.core.calibration.sensor_to_segment import AUTO, REQUESTS, SessionCalibration
from gait_biofeedback.core.calibration.stream import (
    CALIBRATION_FILE,
    CalibrationAttempt,
    CalibrationBuffer,
    CalibrationParams,
    read_calibration_file,
    write_calibration_file,
)
from gait_biofeedback.core.gait.stream import GaitEventsParams, GaitEventStream
from gait_biofeedback.core.joints.alignment import said as stamps_off
from gait_biofeedback.core.joints.angles import segment_pair
from gait_biofeedback.core.joints.body_pose import angle_rows, body_transforms
from gait_biofeedback.core.joints.stream import (
    STREAM_SEGMENTS,
    JointAnglesParams,
    JointAngleStream,
    SyncedAngles,
)
from gait_biofeedback.core.orientation.stream import INFORMATION, OrientationParams
from gait_biofeedback.core.params import spec_by_name
from gait_biofeedback.core.rate import TOLERANCE as RATE_TOLERANCE
from gait_biofeedback.core.rate import RateCheck
from gait_biofeedback.core.spatial.provisional import SWING_TOLERANCES
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.io.bag import BagReader, BagRecoveryWarning, BagWriter
from gait_biofeedback.io.bag_writer import check_output
from gait_biofeedback.io.imu_bag import read_imu_bag
from gait_biofeedback.io.log_order import LogOrderWriter
from gait_biofeedback.io.schemas import type_name_of
from gait_biofeedback.orientation_pass import Filtered, OrientationPass, PassItem, truth_topics
from gait_biofeedback.parameters import stage_parameters
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.activity import activity_msg
from gait_biofeedback.wire.calibration import calibration_msg, entries, rotations
from gait_biofeedback.wire.cdr import Stamped, header_stamp_ns, serialize
from gait_biofeedback.wire.gait import event_msg, foot_frame, stride_output
from gait_biofeedback.wire.imu import (
    has_heading,
    is_recovering,
    orientation_sample,
    raw_sample,
)
from gait_biofeedback.wire.joints import JOINT_STATE_TYPE, joint_state_bytes, skeleton_msg
from gait_biofeedback.wire.tf import TF_TOPIC, TF_TYPE, tf_messages


@dataclass
class AnalysisResult:
    """What :func:`analyze_recording` produced.

    ``output``: the bag written (None: nothing written, the messages are in ``messages`` as
    ``(topic, rclpy message, log_time_ns)``); ``counts``: messages per output topic;
    ``start_ns``: log time of the recording's first message, the zero of ``calibrate_at``;
    ``calibrations``: every calibration request's outcome, in order; ``calibration_file``: the
    calibration in force at the end, saved as ``<output>/calibration.yaml`` (None: none in force or
    nothing written); ``warnings``: what the stages said (time going back, gaps, requests that never
    ran, chunks of the recording that could not be read); ``notes``: what ``auto`` calibration
    instants found and information about the kit; ``live_only``: what the live graph would have done
    otherwise (e.g. provisional values it would have withheld), not printed by ``analyze``: offline
    every stride has its smoothed values; ``requested``: the calibration requests looked for (an
    ``auto`` one is dropped from a recording without leg or foot sensors: :func:`drop_needless_auto`)."""

    output: Path | None
    start_ns: int = 0
    calibration_file: Path | None = None
    counts: dict[str, int] = field(default_factory=dict)
    calibrations: list[CalibrationAttempt] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    messages: list[tuple[str, Any, int]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    live_only: list[str] = field(default_factory=list)
    requested: int = 0


AUTO_MARGIN_S = 0.5  # an auto calibration instant: this long after the motion it found (or the end)
# another lab's recording: a shorter standing (core/calibration/windows.py) or none (calibration/walk.py)
AUTO_OPTIONS = {"shorter_standing": True, "walk_only": True}
NO_STANDING = "no quiet standing before a protocol"
"""What an ``auto`` note says when the recording starts walking (the feet calibrate from the walk)."""
WAITING_WARN_NS = 2 * NS_PER_S
"""A calibrated joint left without angles this long (no common heading yet) is named in the warnings."""
SWING_WORDS = {"max_sensor_height": "foot heights", "min_toe_clearance": "toe clearances",
               "foot_angle_ic": "foot angles at IC", "foot_angle_tc": "foot angles at TC",
               "turning_angle": "turning angles", "lateral_excursion": "lateral excursions"}
SWING_TOLERANCE_TEXT = {k: f"{math.degrees(v):.0f}°" if "angle" in k else
                        f"{100 * v:.0f} cm" for k, v in SWING_TOLERANCES.items()}
SESSION_CONDITIONS = ("losing samples", "6D", "no gyro")
"""Orientation conditions ``analyze`` also sums up in its warnings (the others are said as they happen)."""
CALIBRATED_LIMBS = ("_thigh", "_shank", "_foot")
"""Segments whose calibration the joint angles and gait events need (a recording without any: ``auto``
is not looked for)."""
_NO_QUATERNION = np.full(4, np.nan)  # the chest's orientation before its first sample


def parse_calibrate_at(text: str) -> tuple[float | None, str]:
    """``"T:protocol"`` → (T, protocol): T in s into the recording or ``auto`` (None: found by
    :func:`resolve_calibrate_at`); protocol ``hip_flexion``, ``walking`` or ``auto`` (the one the
    movement shows); ``"auto"`` alone = ``"auto:auto"``; a time alone = ``"T:auto"`` (it was hip_flexion:
    a walk calibrated at T was then refused as not hip flexion)."""
    time_text, _, protocol = text.partition(":")
    protocol = protocol or AUTO
    example = "expected SECONDS:PROTOCOL, e.g. 36:hip_flexion, 75:walking, 75:auto or auto"
    if time_text == AUTO:
        t = None
    else:
        try:
            t = float(time_text)
        except ValueError:
            raise ValueError(f"--calibrate-at {text!r}: {example}") from None
        if not math.isfinite(t) or t < 0:
            raise ValueError(f"--calibrate-at {text!r}: the time must be finite and >= 0 s ({example})")
    if protocol not in REQUESTS:
        raise ValueError(f"--calibrate-at {text!r}: the protocol must be one of {list(REQUESTS)}")
    return t, protocol


def drop_needless_auto(segments: Sequence[str], requests: list[tuple[float | None, str]]
                       ) -> tuple[list[tuple[float | None, str]], list[str]]:
    """(``requests`` without the ``auto`` ones, what was done in words) for a recording whose raw IMU
    ``segments`` hold no leg or foot sensor: nothing there needs a calibration (the activity monitor
    finds its own upright reference), and a trunk's movements would be searched in vain for a protocol.
    Other recordings: ``requests`` unchanged, no note."""
    segments = sorted(segments)
    if all(t is not None for t, _ in requests) or any(seg.endswith(CALIBRATED_LIMBS) for seg in segments):
        return requests, []
    return [r for r in requests if r[0] is not None], [
        f"--calibrate-at auto: no thigh, shank or foot sensor in the recording ({', '.join(segments)}): "
        "nothing to calibrate (the activity monitor finds its own upright reference); analysed without one"]


TRUNK_FALLBACK = "pelvis"
"""The activity monitor's sensor in a kit without a chest sensor (a lower-back or waist sensor is
imported as the pelvis), with ``placement: pelvis``."""
RATE_STAGES = {"orientation_filter": None, "gait_events": ("left_foot", "right_foot"),
               "activity_monitor": "segment"}
"""The stages with a ``rate_hz`` and the segments whose rate it is (None: every sensor; "segment": the
one the stage's ``segment`` parameter names)."""


def recording_rates(bag: str | Path) -> dict[str, float]:
    """Each raw IMU stream's rate as the stages decide it (:class:`~gait_biofeedback.core.rate.RateCheck`
    over its first stamps), rounded as they round it; segment → Hz (NaN: too few stamps), every segment
    of the recording (:func:`drop_needless_auto` takes them from here, the bag read once)."""
    with BagReader(bag) as reader:
        segment_of = {topic: seg for seg, topic in _raw_topics(reader, bag)[0].items()}
        checks = {seg: RateCheck(1.0) for seg in segment_of.values()}
        for topic, _, data, _ in reader.raw_messages(list(segment_of)):
            stamp_ns = header_stamp_ns(data)
            check = checks[segment_of[topic]]
            if stamp_ns is not None:
                check.update(stamp_ns)
            if all(c.measured_hz is not None for c in checks.values()):
                break
    for check in checks.values():
        check.decide()
    return {seg: round(c.measured_hz, 3) if c.measured_hz else math.nan for seg, c in checks.items()}


def with_recording_rate(rates: dict[str, float], params: dict[str, dict] | None
                        ) -> tuple[dict[str, dict], list[str]]:
    """(``params`` fitted to the recording, what was set, in words): each stage's ``rate_hz`` set to the
    recording's (``rates``: :func:`recording_rates`), where the parameters do not give one and the
    stage's sensors share a rate more than 10 % from the default; and the activity monitor on the
    :data:`TRUNK_FALLBACK` sensor where the kit has no chest sensor and the parameters name no
    ``segment`` or ``placement``. The stage would switch to that rate after its first stamps anyway, with
    a warning meant for a live sensor set to the wrong rate; a recording states its rate. ``replay``
    gives the graph the same."""
    params = {node: values.copy() for node, values in (params or {}).items()}
    notes = []
    activity = params.setdefault("activity_monitor", {})
    if "segment" not in activity and "placement" not in activity:
        chosen = stage_parameters("activity_monitor", activity).segment
        if chosen not in rates and TRUNK_FALLBACK in rates:
            activity.update(segment=TRUNK_FALLBACK, placement=TRUNK_FALLBACK)
            notes.append(f"activity_monitor: the {TRUNK_FALLBACK} sensor (this kit has no {chosen} sensor): "
                         "posture from the pelvis tilt, walking and steps from the lower back")
    for node, which in RATE_STAGES.items():
        values = params.setdefault(node, {})
        if "rate_hz" in values:
            continue
        stage = stage_parameters(node, values)
        segments = ([stage.segment] if which == "segment" else list(rates) if which is None else which)
        found = {rates[s] for s in segments if math.isfinite(rates.get(s, math.nan))}
        if len(found) != 1:
            continue
        (rate,) = found
        default, spec = stage.rate_hz, spec_by_name(type(stage))["rate_hz"]
        if abs(rate / default - 1.0) > RATE_TOLERANCE and spec.low <= rate <= spec.high:
            values["rate_hz"] = rate
            notes.append(f"{node}: rate_hz {rate:g} Hz, the recording's (the default is {default:g})")
    return {node: values for node, values in params.items() if values}, notes


def resolve_calibrate_at(bag: str | Path, requests: Sequence[tuple[float | None, str]],
                         standing_duration: float = CalibrationParams.default_standing_duration_s
                         ) -> tuple[list[tuple[float, str]], list[str]]:
    """(requests with every ``auto`` time found, what was found in words). An ``auto`` time is the
    end (+ 0.5 s) of the first calibration in the recording's raw IMU data
    (:func:`~gait_biofeedback.core.calibration.find.find_calibration`: a quiet standing of
    ``standing_duration`` s, the calibration stage's ``default_standing_duration_s``, then movement that
    looks like a protocol; without one, a walk); with protocol ``auto`` the protocol it looks like.
    ValueError (saying what was looked for) when there is none. The calibration node runs an ``auto``
    time with :data:`AUTO_OPTIONS`."""
    if all(t is not None for t, _ in requests):
        return [(float(t), p) for t, p in requests], []
    if sum(t is None for t, _ in requests) > 1:
        raise ValueError("--calibrate-at auto finds one calibration: give it once")
    data = read_imu_bag(bag)
    with BagReader(bag) as reader:
        start_s = reader.start_time_ns / NS_PER_S
    standing, motion, check = find_calibration(data, standing_duration)
    m0, m1 = (b - start_s for b in motion)
    found = (f"quiet standing {standing[0] - start_s:.2f}-{standing[1] - start_s:.2f} s" if standing else
             f"{NO_STANDING} (the feet calibrate from the walk's stance phases, no joint angles)")
    ends = min(d.t[-1] for d in data.values() if len(d))  # every sensor's data reaches the instant
    at = min(m1 + AUTO_MARGIN_S, ends - start_s)
    resolved, notes = [], []
    for t, protocol in requests:
        if t is None:
            seen = check.looks_like or AUTO
            chosen = seen if protocol == AUTO else protocol
            notes.append(f"--calibrate-at auto: {found}, then "
                         f"{WORDS.get(seen, seen)} {m0:.2f}-{m1:.2f} s ({check.evidence()}): "
                         f"calibrating at {at:.2f}:{chosen}")
            resolved.append((at, chosen))
        else:
            resolved.append((float(t), protocol))
    return resolved, notes


def _raw_topics(reader: BagReader, bag: str | Path) -> tuple[dict[str, str], dict[str, str]]:
    types = reader.topics()
    imu, mag = topics.recorded_imu_topics(types)
    if not imu:
        found = ", ".join(sorted(types)) or "no topics at all"
        raise ValueError(f"{bag}: no raw IMU topics (/<segment>/imu/data_raw, sensor_msgs/msg/Imu) to "
                         f"analyse (found: {found}); analyse a sensor recording, e.g. one made by "
                         "`gait-biofeedback simulate`, `import` or `record`")
    return imu, mag


def analyze_recording(
    bag: str | Path,
    output: str | Path | None = None,
    calibrate_at: Sequence[tuple[float | None, str]] | None = None,
    calibration_file: str | Path | None = None,
    params: dict[str, dict] | None = None,
    overwrite: bool = False,
) -> AnalysisResult:
    """Run the graph's core objects over the raw IMU topics of ``bag`` (see module docstring).

    ``calibrate_at``: ``[(seconds into the recording, protocol)]``, the instants a clinician pressed
    Calibrate (each calibrates on the window ending there; None = found, and protocol ``auto`` = the
    one the movement shows: :func:`resolve_calibrate_at`; not looked for without leg or foot sensors:
    :func:`drop_needless_auto`); ``calibration_file``: a ``calibration.yaml`` in force from the start;
    ``params``: node name → parameters, as :func:`~gait_biofeedback.parameters.load_params_file` gives
    them (orientation_filter, calibration, joint_angles, gait_events, activity_monitor are used; the
    others are checked and ignored; a ``rate_hz`` they do not give is the recording's:
    :func:`with_recording_rate`). Writes the outputs to the bag folder ``output`` (``overwrite``
    replaces an existing one). Raises ValueError for a bag without raw IMU topics, a bad request or parameter
    (:class:`~gait_biofeedback.core.params.ParameterError` names it), FileNotFoundError for a
    missing bag or calibration file.
    """
    if output is not None:
        check_output(output, overwrite)  # before the analysis, not after it
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagRecoveryWarning)  # they go into result.warnings, said once
        rates = recording_rates(bag)
        params, rate_notes = with_recording_rate(rates, params)
        stages = {node: stage_parameters(node, values) for node, values in params.items()}
        for _t, protocol in calibrate_at or []:
            if protocol not in REQUESTS:
                raise ValueError(f"unknown calibration protocol {protocol!r}; use one of {list(REQUESTS)}")
        standing_s = (stages.get("calibration") or CalibrationParams()).default_standing_duration_s
        calibrate_at, notes = drop_needless_auto(list(rates), list(calibrate_at or []))
        requests, found_notes = resolve_calibrate_at(bag, calibrate_at, standing_s)
        notes += rate_notes + found_notes
        is_auto = [asked is None for asked, _ in calibrate_at or []]
        auto = [r for r, a in zip(requests, is_auto, strict=True) if a]
        pressed = [r for r, a in zip(requests, is_auto, strict=True) if not a]
        found, kept = None, []
        rest = (pressed, calibration_file, stages)
        with BagReader(bag) as reader:
            run = _orientation_pass(reader, bag, stages)
            if auto:
                found, kept = _calibrate_ahead(run, auto[0], stages)
            if kept is not None:
                run.put_back(kept)
                result = _analyze_into(output, overwrite, reader, run, *rest, found)
        if kept is None:  # too long to keep: read again
            with BagReader(bag) as reader:
                run = _orientation_pass(reader, bag, stages)
                result = _analyze_into(output, overwrite, reader, run, *rest, found)
    if found is not None and found.success:
        notes.append("--calibrate-at auto: that calibration is in force from the start of the recording "
                     "(offline, as a calibration file would be; replay presses Calibrate at that instant, "
                     "or, for a calibration made of the walk itself, puts it in force from the start too)")
    result.notes[:0] = notes  # before what the analysis noted
    result.requested = len(calibrate_at)
    return result


def calibration_ahead(bag: str | Path, request: tuple[float, str], params: dict[str, dict] | None = None
                      ) -> CalibrationAttempt:
    """What ``analyze`` puts in force from the start for an ``auto`` request (:func:`_calibrate_ahead`),
    with ``params`` as :func:`analyze_recording` takes them (``replay`` of a recording that starts
    walking uses it: live, Calibrate needs a standing)."""
    stages = {node: stage_parameters(node, values) for node, values in (params or {}).items()}
    with BagReader(bag) as reader:
        return _calibrate_ahead(_orientation_pass(reader, bag, stages), request, stages, keep=False)[0]


KEPT_MESSAGES = 250_000
"""The look-ahead of an ``auto`` calibration keeps the orientation pass's items for the analysis up to
this many messages (about 2.5 min of 8 sensors with magnetometers at 100 Hz, about 1.7 kB each); past
it, the analysis reads the recording again."""


def _orientation_pass(reader: BagReader, bag: str | Path, stages: dict[str, Any]) -> OrientationPass:
    raw_topics, mag_topics = _raw_topics(reader, bag)
    return OrientationPass(reader, raw_topics, mag_topics, truth_topics(reader),
                           stages.get("orientation_filter") or OrientationParams())


def _calibrate_ahead(run: OrientationPass, request: tuple[float, str], stages: dict[str, Any],
                     keep: bool = True) -> tuple[CalibrationAttempt, list[PassItem] | None]:
    """(the calibration the live graph computes when Calibrate is pressed at ``request`` (s into the
    recording, protocol), the items of ``run`` read to get there: None without ``keep`` or past
    :data:`KEPT_MESSAGES`). The calibration buffer with the stages' parameters is fed ``run``'s
    orientations in log order, as :func:`_analyze` feeds its own, up to that instant."""
    buffer = CalibrationBuffer(stages.get("calibration") or CalibrationParams())
    buffer.schedule(run.start_ns + round(request[0] * NS_PER_S), request[1], **AUTO_OPTIONS)
    kept: list[PassItem] | None = [] if keep else None

    def feed(seg: str, filtered: Filtered) -> list[CalibrationAttempt]:
        for _, sample in filtered:
            if seg in buffer.buffers:
                buffer.add(seg, *orientation_sample(sample), heading=has_heading(sample))
        return buffer.run_due()

    for item in run:
        if kept is not None:
            kept.append(item)
            if len(kept) > KEPT_MESSAGES:
                kept = None
        if item.filtered is not None and (done := feed(item.segment, item.filtered)):
            return done[0], kept
    end = run.finish()
    for seg in run.last_raw:
        if done := feed(seg, end.flushed[seg]):
            return done[0], kept
    return CalibrationAttempt(request[1], False, f"the recording ends before every sensor's data reaches "
                              f"the calibration instant ({request[0]:.2f} s): ask for an earlier one"), kept


def _analyze_into(output: str | Path | None, overwrite: bool, *args: Any) -> AnalysisResult:
    """:func:`_analyze` (``args``) written to the bag folder ``output`` as it goes (None: kept in
    memory), in a staging folder beside it whose files move into ``output`` when it ends well (a
    failed analysis leaves nothing, as when the bag was written at the end)."""
    if output is None:
        return _analyze(None, *args)
    output = Path(output)
    staging = output.parent / f".{output.name}.analyzing"
    shutil.rmtree(staging, ignore_errors=True)  # left by a run that was killed
    try:
        with BagWriter(staging / output.name, flush_period_s=None) as writer:
            ordered = LogOrderWriter(writer)
            result = _analyze(ordered, *args)
            ordered.close()
        if overwrite and output.is_dir():
            for old in output.iterdir():
                if old.is_dir():  # the tables of an earlier analysis (check_output let nothing else by)
                    shutil.rmtree(old)
                else:
                    old.unlink()
        output.mkdir(parents=True, exist_ok=True)
        for done in writer.path.iterdir():
            os.replace(done, output / done.name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    result.output = output
    if result.calibration_file is not None:
        result.calibration_file = output / CALIBRATION_FILE
    return result


def _analyze(ordered: LogOrderWriter | None, reader: BagReader, run: OrientationPass,
             calibrate_at: list[tuple[float, str]], calibration_file: str | Path | None,
             stages: dict[str, Any], ahead: CalibrationAttempt | None = None) -> AnalysisResult:
    result = AnalysisResult(None)
    calibration = None
    c_params: CalibrationParams = stages.get("calibration") or CalibrationParams()
    calibration_file = calibration_file or c_params.calibration_file or None
    if calibration_file is not None:
        path = Path(calibration_file)
        if not path.is_file():
            raise FileNotFoundError(f"calibration file {path} not found")
        calibration, saved_at = read_calibration_file(path)

    # -- the core objects, set up from the nodes' parameters --------------------------------------
    o_params, raw_topics, trackers = run.params, run.raw_topics, run.trackers
    for seg in raw_topics:
        if seg not in o_params.segments:
            known = ", ".join(o_params.segments)
            result.warnings.append(f"{raw_topics[seg]}: '{seg}' is not one of the graph's segments "
                                   f"({known}): not analysed; import it under the segment it was worn on")
    buffer = CalibrationBuffer(c_params)
    j_params: JointAnglesParams = stages.get("joint_angles") or JointAnglesParams()
    joints = JointAngleStream(j_params)
    gait = GaitEventStream(stages.get("gait_events") or GaitEventsParams())
    a_params: ActivityParams = stages.get("activity_monitor") or ActivityParams()
    activity = ActivityRun(a_params) if a_params.segment in raw_topics else None  # on recording time
    if activity is None and not {a_params.segment, TRUNK_FALLBACK} & set(raw_topics):
        result.notes.append("no chest or pelvis sensor in this kit: no activity monitor (posture, "
                            "transitions, walking bouts)")
    elif activity is None:  # the parameters chose a sensor the recording does not have
        fix = ("; a lower-back or waist sensor: set activity_monitor segment: pelvis and placement: pelvis"
               if TRUNK_FALLBACK in raw_topics else "")
        result.warnings.append(f"no {a_params.segment} sensor in the recording: the activity monitor "
                               f"(posture, transitions, walking bouts) did not run{fix}")
    streams = [gait, *([activity.stream] if activity is not None else [])]  # the trackers': ``run``

    start_ns = reader.start_time_ns
    result.start_ns = start_ns
    for t, protocol in calibrate_at:
        buffer.schedule(start_ns + round(t * 1e9), protocol)

    keep = ordered is None
    emitted_joints = 0
    imu_type = topics.orientation("x").type_name

    def emit(topic: str, msg: Any, log_ns: int) -> None:
        if ordered is not None:
            ordered.produced(log_ns, topic, type_name_of(msg), serialize(msg), True)
        result.counts[topic] = result.counts.get(topic, 0) + 1
        if keep:
            result.messages.append((topic, msg, log_ns))

    def emit_data(topic: str, data: bytes, log_ns: int, cls: type = Imu, type_name: str = imu_type) -> None:
        """A message of ``cls`` as its CDR bytes, padding zeroed (an Imu the node publishes as bytes,
        joint states written without an rclpy message): recorded as those bytes."""
        if ordered is not None:
            ordered.produced(log_ns, topic, type_name, data, True)
        result.counts[topic] = result.counts.get(topic, 0) + 1
        if keep:
            result.messages.append((topic, deserialize_message(data, cls), log_ns))

    def said() -> None:
        for stream in streams:
            if stream.notices:
                result.warnings.extend(n.text for n in stream.notices.pop() if n.level != "info")

    in_force: list[SessionCalibration] = []

    def publish_calibration(msg: Any, log_ns: int, calibration: SessionCalibration) -> None:
        in_force[:] = [calibration]
        emit(topics.CALIBRATION.absolute(), msg, log_ns)
        joints.set_calibration(*rotations(msg))
        gait.apply_calibration(*entries(msg))
        if activity is not None:
            activity.stream.apply_calibration(*entries(msg))

    waiting: dict[str, list[int]] = {}  # joint → [first, last] stamp it was left out for want of a heading

    body_rows: list[tuple] = []  # (log ns, stamp, pelvis q, its r, angles, chest q, its r) per instant
    chest_q: list[np.ndarray] = [_NO_QUATERNION]  # the chest sensor's newest orientation

    def body_frames() -> None:
        """The ``/tf`` of the instants held, encoded in one go (the writer asks before it writes)."""
        if not body_rows:
            return
        log, ns, pelvis, pelvis_r, angles, chest, chest_r = zip(*body_rows, strict=True)
        body_rows.clear()
        pelvis_q = quat.multiply(np.array(pelvis), np.array(pelvis_r))
        chest_seg = quat.multiply(np.array(chest), np.array(chest_r))
        frames = tf_messages(np.array(ns), *body_transforms(pelvis_q, angle_rows(angles), chest_seg,
                                                            j_params.body))
        for log_ns, data in zip(log, frames, strict=True):
            if data:
                ordered.batched(log_ns, TF_TOPIC, TF_TYPE, data, True)
        result.counts[TF_TOPIC] = result.counts.get(TF_TOPIC, 0) + sum(map(bool, frames))

    if ordered is not None:
        ordered.prepare = body_frames

    def hold_body(synced: SyncedAngles, log_ns: int) -> None:
        r = synced.rotations
        if ordered is None or "pelvis" not in synced.sensor_quats or "pelvis" not in r:
            return
        body_rows.append((log_ns, synced.ns, synced.sensor_quats["pelvis"], r["pelvis"], synced.angles,
                          chest_q[0], r.get("chest", _NO_QUATERNION)))

    def publish_joints(emitted: list, log_ns: int) -> None:
        nonlocal emitted_joints
        for synced in emitted:
            for joint in synced.no_heading:
                if all(s in synced.rotations for s in segment_pair(*joint.split("_", 1))):
                    waiting.setdefault(joint, [synced.ns, synced.ns])[1] = synced.ns
            if synced.angles:
                emit_data(topics.JOINT_STATES.absolute(), joint_state_bytes(synced.angles, synced.ns,
                          synced.recovering), log_ns, JointState, JOINT_STATE_TYPE)
                hold_body(synced, log_ns)
            emitted_joints += 1
            every = j_params.skeleton_every
            if every > 0 and emitted_joints % every == 0:
                emit(topics.SKELETON.absolute(), skeleton_msg(synced, j_params.body), log_ns)

    def downstream(segment: str, imu: Stamped, log_ns: int) -> None:
        if segment == "chest":
            chest_q[0] = orientation_sample(imu)[3]
        if segment in buffer.buffers:
            buffer.add(segment, *orientation_sample(imu), heading=has_heading(imu))
            if buffer.scheduled:
                for attempt in buffer.run_due():
                    result.calibrations.append(attempt)
                    if attempt.success and attempt.calibration is not None:
                        publish_calibration(calibration_msg(attempt.calibration, attempt.applies_from_ns),
                                            log_ns, attempt.calibration)
        if segment in STREAM_SEGMENTS:
            _, acc, gyr, q = orientation_sample(imu)
            publish_joints(joints.add(segment, imu.ns, q, gyr, acc, recovering=is_recovering(imu),
                                      magnetic=has_heading(imu), received_ns=log_ns), log_ns)
        side = segment.removesuffix("_foot")
        if segment == foot_frame(side) and side in gait.detectors:
            _, acc, gyr, q = orientation_sample(imu)
            events, cycles = gait.update(side, imu.ns, q, is_recovering(imu), gyr, acc)
            for event in events:
                emit(topics.GAIT_EVENTS.absolute(), event_msg(event), log_ns)
            for cycle in cycles:
                topic, msg = stride_output(cycle)
                emit(topic.absolute(), msg, log_ns)

    if calibration is not None:
        source = f"from {Path(calibration_file).absolute()} (saved {saved_at or 'at an unknown time'})"
        publish_calibration(calibration_msg(calibration, 0, source), start_ns, calibration)
    if ahead is not None:
        result.calibrations.append(ahead)
        if ahead.success and ahead.calibration is not None:
            until = (ahead.until_ns or start_ns) - start_ns
            source = f"found by --calibrate-at auto on the data up to {until / NS_PER_S:.1f} s"
            publish_calibration(calibration_msg(ahead.calibration, 0, source), start_ns, ahead.calibration)

    def publish_activity(states: list[ActivityState], log_ns: int) -> None:
        """The states due as the node publishes them (headed by the newest chest stamp)."""
        for state in states:
            msg = activity_msg(state, activity.newest_ns, activity.segment)
            emit(topics.ACTIVITY.absolute(), msg, log_ns)

    def orientations(seg: str, filtered: Filtered, log_ns: int) -> None:
        for data, sample in filtered:
            emit_data(topics.orientation(seg).absolute(), data, log_ns)
            downstream(seg, sample, log_ns)

    for item in run:
        if item.status is not None:
            emit(topics.DIAGNOSTICS.name, item.status, item.log_ns)
        if ordered is not None:
            # what is logged from here on comes at or after this message, or, the last /diagnostics,
            # at the newest raw IMU sample the orientation pass has read (its look-ahead included)
            ordered.release(min(item.log_ns, run.newest_ns or item.log_ns))
            ordered.copied(item.log_ns, item.topic, item.type_name, item.data)
        if item.raw is None:  # ground truth or magnetometer
            continue
        seg, log_ns = item.segment, item.log_ns
        if activity is not None and seg == activity.segment:
            stamp_ns, gyro, acc = raw_sample(item.raw)
            publish_activity(activity.update(stamp_ns, acc, gyro), log_ns)
        elif activity is not None and seg in activity.stream.thighs.segments:
            stamp_ns, _, acc = raw_sample(item.raw)
            publish_activity(activity.update_thigh(seg, stamp_ns, acc), log_ns)
        if item.filtered is not None:
            orientations(seg, item.filtered, log_ns)
        result.warnings.extend(item.notices)
        said()
    end = run.finish()  # what the reorder windows still hold (the node: on silence)
    for seg, filtered in end.flushed.items():
        orientations(seg, filtered, reader.end_time_ns)
    result.warnings.extend(end.notices)
    said()
    if end.status is not None:
        emit(topics.DIAGNOSTICS.name, end.status, end.status_ns)
    last_log = run.last_log
    publish_joints(joints.flush(force=True), reader.end_time_ns)
    for cycle in gait.finish():
        topic, msg = stride_output(cycle)
        emit(topic.absolute(), msg, reader.end_time_ns)
    if activity is not None:
        publish_activity(activity.finish(), reader.end_time_ns)
    result.warnings[:0] = reader.warnings  # a damaged file, a chunk skipped: the time range lost
    imu_end_ns = max(last_log.values(), default=0)  # a recorder stopped after the sensors is no silence
    for seg, last_ns in last_log.items():
        silent = (imu_end_ns - last_ns) / NS_PER_S
        if silent > o_params.stale_after_s:
            since = (last_ns - start_ns) / NS_PER_S
            result.warnings.append(f"{seg}: no data from {since:.1f} s on, {silent:.1f} s before the other "
                                   "sensors' last: check the sensor, its battery and the link; its joints "
                                   "and events stop there")
    for seg, (first_ns, off) in joints.alignment.first.items():
        last_ns = joints.alignment.last[seg][0]
        span = f"{(first_ns - start_ns) / NS_PER_S:.1f}-{(last_ns - start_ns) / NS_PER_S:.1f} s"
        result.warnings.append(f"{span} into the recording: {stamps_off(seg, off)}")
    moves_end = max((a.until_ns for a in result.calibrations if a.success and a.until_ns), default=None)
    for joint, (first, last) in waiting.items():
        if last - first < WAITING_WARN_NS:
            continue  # a hip's axis heading: 1 s after the calibration
        span = f"{(first - start_ns) / NS_PER_S:.1f} to {(last - start_ns) / NS_PER_S:.1f} s"
        if moves_end is not None and last <= moves_end:  # the calibration's own movements: as expected
            result.notes.append(f"{joint.replace('_', ' ')}: no angles from {span}, during the calibration "
                                "movements: its two sensors had no common heading yet (it comes from the "
                                "legs' movement)")
            continue
        result.warnings.append(
            f"{joint.replace('_', ' ')}: no angles from {span} into the recording, though calibrated: its "
            "two sensors had no common heading yet (the kinematic heading needs about 15 s of walking)")
    said_by: dict[str, list[str]] = {}  # what only /diagnostics said along the way, over the session
    for seg, tracker in trackers.items():
        for text in tracker.conditions({}):
            if text.startswith(SESSION_CONDITIONS):
                said_by.setdefault(text, []).append(seg)
    for text, segments in said_by.items():
        who = segments[0] if len(segments) == 1 else f"{', '.join(segments)} ({len(segments)} sensors)"
        (result.notes if text in INFORMATION else result.warnings).append(f"{who}: over the session: {text}")
    for side, foot in gait.feet.items():  # what the live graph would have held back
        swing = {k: a.withheld for k, a in foot.swing_agreement.values.items() if a.withheld}
        if swing:
            result.live_only.append(
                f"{side} foot, live only: provisional "
                + ", ".join(f"{SWING_WORDS[k]} withheld {n} times" for k, n in swing.items())
                + " (their last estimates differed from the smoothed ones by more than "
                + ", ".join(SWING_TOLERANCE_TEXT[k] for k in swing)
                + " RMS); offline every stride has its smoothed values")
        rest = foot.rest_of_swing
        if rest.withheld:
            result.live_only.append(
                f"{side} foot, live only: {rest.withheld} provisional stride lengths withheld (those strides "
                f"wait for their smoothed values) while their last estimates differed from the smoothed ones "
                f"by more than provisional_tolerance_m, {100 * rest.tolerance:g} cm RMS (at the end of the "
                f"recording {100 * rest.spread:.1f} cm); offline every stride has its smoothed values")
    for until_ns, protocol in buffer.scheduled:
        at = (until_ns - start_ns) / NS_PER_S
        result.warnings.append(f"calibration ({protocol}) at {at:.2f} s never ran: "
                               "the recording ends before every sensor's data gets there")
    if ordered is not None and in_force:
        result.calibration_file = ordered.writer.path / CALIBRATION_FILE
        write_calibration_file(result.calibration_file, in_force[0], time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    return result
