"""Node ``gait_events``: both feet's orientations → IC/TC events and per-stride temporal parameters.

Subscribes ``<side>_foot/imu/data`` (sensor_msgs/Imu with orientation, reliable) and
``calibration/sensor_to_segment`` (SegmentCalibrationArray, latched: rotation r of each foot, segment →
sensor). Publishes ``gait/events`` (GaitEvent, one sample after the event: stamp = the event sample's
stamp, ``detection_latency`` = to the confirming sample) and ``gait/cycles`` (GaitCycle at each IC that
closes a stride; an implausible stride, < ``min_stride_s`` or > ``max_stride_s`` or without exactly one
TC, is published with ``plausible = false`` and its ``flag``), plus ``/diagnostics``. The detection is
:class:`~gait_biofeedback.core.gait_events.GaitEventDetector` (thesis Algorithm 1), the strides
:class:`~gait_biofeedback.core.gait_cycles.GaitCycleTracker`.

Bad input: a foot without data for ``stale_after`` s (wall clock), a stamp gap > ``max_gap`` s or a
stamp going backwards resets that foot's detector and stride state, counted and said on /diagnostics.
Until a valid calibration of a foot arrives its samples are not used (counted), unless
``use_standing_reference``: then the foot's anterior axis is taken from its first orientation sample
(IMU x axis made horizontal, thesis §6.2.2 correction 1; assumes the IMU x axis points toe-ward).

Parameters: ``sides`` (["left", "right"]), ``rate_hz`` (nominal sample rate for Algorithm 1's sample
counts, 100.0), ``threshold`` (-0.2), ``refractory_s`` (0.15), ``window_s`` (0.15), ``trend_fraction``
(0.8), ``max_gap`` (0.5 s), ``stale_after`` (1.0 s), ``symmetry_window`` (10 steps), ``min_stride_s``
(0.4), ``max_stride_s`` (3.0), ``use_standing_reference`` (false), ``diagnostics_period`` (1.0 s).
"""

from __future__ import annotations

import math
import time

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.gait_cycles import GaitCycle, GaitCycleTracker
from gait_biofeedback.core.gait_events import INITIAL_CONTACT, GaitEvent, GaitEventDetector
from gait_biofeedback.core.segments import orientation_topic
from gait_biofeedback.nodes.common import (
    DIAGNOSTICS_TOPIC,
    LATCHED_QOS,
    RELIABLE_QOS,
    diagnostic_array,
    diagnostic_status,
    s_to_stamp,
    stamp_to_s,
)
from gait_biofeedback_msgs.msg import GaitCycle as GaitCycleMsg
from gait_biofeedback_msgs.msg import GaitEvent as GaitEventMsg
from gait_biofeedback_msgs.msg import SegmentCalibrationArray

EVENTS_TOPIC = "gait/events"
CYCLES_TOPIC = "gait/cycles"
CALIBRATION_TOPIC = "calibration/sensor_to_segment"
_SIDE_CODE = {"left": GaitEventMsg.SIDE_LEFT, "right": GaitEventMsg.SIDE_RIGHT}


def standing_reference(q: np.ndarray) -> np.ndarray:
    """Rotation r whose segment x axis is the horizontal projection of the IMU x axis at orientation q
    (y up): ``q_segment = q ⊗ r`` keeps the heading and removes the standing roll/pitch."""
    forward = quat.rotate(q, np.array([1.0, 0.0, 0.0]))
    forward[2] = 0.0
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0])
    segment_in_world = np.column_stack([forward, up, np.cross(forward, up)])
    return quat.from_matrix(quat.as_matrix(quat.conjugate(q)) @ segment_in_world)


class GaitEventsNode(Node):
    """Gait events and stride parameters of both feet (see module docstring)."""

    def __init__(self, context: Context | None = None, **overrides: object) -> None:
        super().__init__("gait_events", context=context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.sides = [s for s in self.declare_parameter("sides", ["left", "right"]).value if s]
        if not self.sides or any(s not in _SIDE_CODE for s in self.sides):
            raise ValueError(f"gait_events: sides must be 'left' and/or 'right', got {self.sides}")
        rate_hz = float(self.declare_parameter("rate_hz", 100.0).value)
        options = {name: float(self.declare_parameter(name, default).value) for name, default in (
            ("threshold", -0.2), ("refractory_s", 0.15), ("window_s", 0.15), ("trend_fraction", 0.8))}
        self.max_gap = float(self.declare_parameter("max_gap", 0.5).value)
        self.stale_after = float(self.declare_parameter("stale_after", 1.0).value)
        self.use_standing_reference = bool(self.declare_parameter("use_standing_reference", False).value)
        self.tracker = GaitCycleTracker(
            symmetry_window=int(self.declare_parameter("symmetry_window", 10).value),
            min_stride_s=float(self.declare_parameter("min_stride_s", 0.4).value),
            max_stride_s=float(self.declare_parameter("max_stride_s", 3.0).value))
        diagnostics_period = float(self.declare_parameter("diagnostics_period", 1.0).value)

        self.detectors = {s: GaitEventDetector(s, rate_hz, **options) for s in self.sides}
        self.calibrated = {s: False for s in self.sides}
        self.counts = {s: {"samples": 0, "uncalibrated": 0, "resets": 0, "stream_stops": 0, "ic": 0, "tc": 0,
                           "strides": 0, "implausible_strides": 0} for s in self.sides}
        self._last_t: dict[str, float | None] = {s: None for s in self.sides}
        self._last_arrival: dict[str, float] = {}
        self._stopped: dict[str, bool] = {s: False for s in self.sides}
        self._note: dict[str, str] = {s: "" for s in self.sides}
        self._stamps: dict[tuple[str, float], Time] = {}
        self._events = self.create_publisher(GaitEventMsg, EVENTS_TOPIC, RELIABLE_QOS)
        self._cycles = self.create_publisher(GaitCycleMsg, CYCLES_TOPIC, RELIABLE_QOS)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE_QOS)
        for side in self.sides:
            self.create_subscription(Imu, orientation_topic(f"{side}_foot"),
                                     lambda msg, s=side: self._on_imu(s, msg), RELIABLE_QOS)
        self.create_subscription(SegmentCalibrationArray, CALIBRATION_TOPIC, self._on_calibration,
                                 LATCHED_QOS)
        self.create_timer(diagnostics_period, self._check_streams)

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        for entry in msg.segments:
            side = entry.segment.removesuffix("_foot")
            if side not in self.detectors or entry.segment != f"{side}_foot":
                continue
            if not entry.valid:
                self._note[side] = f"calibration invalid: {entry.message}"
                continue
            r = entry.rotation
            self.detectors[side].set_mounting(np.array([r.w, r.x, r.y, r.z]))
            self._reset(side, "new calibration")
            self.calibrated[side] = True
            self._note[side] = ""

    def _reset(self, side: str, why: str) -> None:
        self.detectors[side].reset()
        self.tracker.reset(side)
        self._last_t[side] = None
        self.counts[side]["resets"] += 1
        self._note[side] = f"state reset: {why}"

    def _on_imu(self, side: str, msg: Imu) -> None:
        self._last_arrival[side] = time.monotonic()
        self._stopped[side] = False
        counts = self.counts[side]
        counts["samples"] += 1
        o = msg.orientation
        q = (o.w, o.x, o.y, o.z)
        if not all(math.isfinite(v) for v in q) or q == (0.0, 0.0, 0.0, 0.0):
            return
        if not self.calibrated[side]:
            if not self.use_standing_reference:
                counts["uncalibrated"] += 1
                return
            self.detectors[side].set_mounting(standing_reference(np.array(q)))
            self.calibrated[side] = True
        t = stamp_to_s(msg.header.stamp)
        last = self._last_t[side]
        if last is not None and (t <= last or t - last > self.max_gap):
            self._reset(side, "time went backwards" if t <= last else f"{t - last:.2f} s gap in the stamps")
            self.get_logger().warning(f"{side} foot: {self._note[side]}")
        self._last_t[side] = t
        event = self.detectors[side].update(t, q, msg.header.stamp)
        if event is not None:
            self._publish_event(event)

    def _publish_event(self, event: GaitEvent) -> None:
        side = event.side
        self.counts[side][event.kind] += 1
        out = GaitEventMsg()
        out.header.stamp = event.stamp
        out.header.frame_id = f"{side}_foot"
        out.side = _SIDE_CODE[side]
        out.type = (GaitEventMsg.INITIAL_CONTACT if event.kind == INITIAL_CONTACT
                    else GaitEventMsg.TERMINAL_CONTACT)
        out.detection_latency = float(event.latency)
        out.signal_value = float(event.signal)
        out.event_index = int(event.index)
        self._events.publish(out)
        self._stamps[(side, event.t)] = event.stamp
        if len(self._stamps) > 64:
            del self._stamps[next(iter(self._stamps))]
        cycle = self.tracker.add(event)
        if cycle is not None:
            self._publish_cycle(cycle)

    def _stamp(self, side: str, t: float) -> Time:
        if not math.isfinite(t):
            return Time()
        return self._stamps.get((side, t)) or s_to_stamp(t)

    def _publish_cycle(self, c: GaitCycle) -> None:
        counts = self.counts[c.side]
        counts["strides"] += 1
        if not c.plausible:
            counts["implausible_strides"] += 1
            self.get_logger().warning(f"{c.side} stride {c.index} flagged: {c.flag}")
        out = GaitCycleMsg()
        out.header.stamp = self._stamp(c.side, c.end)
        out.header.frame_id = f"{c.side}_foot"
        out.side = _SIDE_CODE[c.side]
        out.stride_index = c.index
        out.start = self._stamp(c.side, c.start)
        out.terminal_contact = self._stamp(c.side, c.terminal_contact)
        for name in ("stride_time", "stance_time", "swing_time", "stance_fraction", "swing_fraction",
                     "step_time", "cadence", "double_support_time", "double_support_fraction",
                     "step_time_symmetry_index"):
            setattr(out, name, float(getattr(c, name)))
        out.plausible = bool(c.plausible)
        out.flag = c.flag
        self._cycles.publish(out)

    def _check_streams(self) -> None:
        now = time.monotonic()
        statuses = []
        for side in self.sides:
            last = self._last_arrival.get(side)
            level, message = DiagnosticStatus.OK, "detecting"
            if last is None:
                level, message = DiagnosticStatus.WARN, f"no {side} foot orientation yet"
            elif now - last > self.stale_after:
                if not self._stopped[side]:
                    self._stopped[side] = True
                    self.counts[side]["stream_stops"] += 1
                    self._reset(side, "stream stopped")
                    self.get_logger().warning(f"{side} foot: no data for {now - last:.1f} s, state reset")
                level = DiagnosticStatus.ERROR
                message = (f"no data for {now - last:.1f} s: {side} foot state reset; check the sensor "
                           "and the orientation filter")
            elif not self.calibrated[side]:
                level, message = DiagnosticStatus.WARN, "waiting for the foot calibration " + (
                    f"({self._note[side]})" if self._note[side] else "(calibration/sensor_to_segment)")
            elif self._note[side]:
                level, message = DiagnosticStatus.WARN, self._note[side]
                self._note[side] = ""
            statuses.append(diagnostic_status(f"gait_events: {side} foot", level, message, f"{side}_foot",
                                              {**self.counts[side], "waiting_for_ic":
                                               self.detectors[side].waiting_for_ic}))
        self._diagnostics.publish(diagnostic_array(self, statuses))


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([GaitEventsNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
