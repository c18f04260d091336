"""Node ``gait_events``: both feet's orientations → IC/TC events and per-stride temporal parameters.

Subscribes ``<side>_foot/imu/data`` (sensor_msgs/Imu with orientation, reliable) and
``calibration/sensor_to_segment`` (SegmentCalibrationArray, latched: rotation r of each foot, segment →
sensor). Publishes ``gait/events`` (GaitEvent, one sample after the event: stamp = the event sample's
stamp, ``detection_latency`` = to the confirming sample) and ``gait/cycles`` (GaitCycle at each IC that
closes a stride; an implausible stride, < ``min_stride_s`` or > ``max_stride_s`` or without exactly one
TC, is published with ``plausible = false`` and its ``flag``), plus ``/diagnostics``. The detection is
:class:`~gait_biofeedback.core.gait_events.GaitEventDetector` (thesis Algorithm 1), the strides
:class:`~gait_biofeedback.core.gait_cycles.GaitCycleTracker`, the stream rules below
:class:`~gait_biofeedback.core.gait_stream.GaitEventStream` (a calibration is in force from its header
stamp, 0 = at once).

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
from collections.abc import Callable

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from gait_biofeedback.core.gait_cycles import GaitCycle
from gait_biofeedback.core.gait_events import INITIAL_CONTACT, GaitEvent, GaitEventDetector
from gait_biofeedback.core.gait_stream import GaitEventStream, standing_reference
from gait_biofeedback.core.segments import orientation_topic
from gait_biofeedback.io.cdr import Stamped, decode_imu
from gait_biofeedback.nodes.common import (
    CALIBRATION_TOPIC,
    DIAGNOSTICS_TOPIC,
    LATCHED_QOS,
    RELIABLE_QOS,
    diagnostic_array,
    diagnostic_status,
    ns_to_stamp,
    s_to_stamp,
    stamp_to_s,
)
from gait_biofeedback_msgs.msg import GaitCycle as GaitCycleMsg
from gait_biofeedback_msgs.msg import GaitEvent as GaitEventMsg
from gait_biofeedback_msgs.msg import SegmentCalibrationArray

EVENTS_TOPIC = "gait/events"
CYCLES_TOPIC = "gait/cycles"
__all__ = ["GaitEventsNode", "apply_calibration_msg", "cycle_msg", "event_msg", "imu_to_foot_sample",
           "standing_reference", "stream_options"]
_SIDE_CODE = {"left": GaitEventMsg.SIDE_LEFT, "right": GaitEventMsg.SIDE_RIGHT}


def event_msg(event: GaitEvent) -> GaitEventMsg:
    """``gait/events`` message of a core event (stamp = the event sample's stamp, int ns)."""
    out = GaitEventMsg()
    out.header.stamp = ns_to_stamp(event.stamp)
    out.header.frame_id = f"{event.side}_foot"
    out.side = _SIDE_CODE[event.side]
    out.type = (GaitEventMsg.INITIAL_CONTACT if event.kind == INITIAL_CONTACT
                else GaitEventMsg.TERMINAL_CONTACT)
    out.detection_latency = float(event.latency)
    out.signal_value = float(event.signal)
    out.event_index = int(event.index)
    return out


def cycle_msg(c: GaitCycle, stamp_of: Callable[[str, float], int | None]) -> GaitCycleMsg:
    """``gait/cycles`` message of a core stride; ``stamp_of(side, t)`` gives the exact stamps (ns) of
    its events (a stamp rounded from ``t`` when unknown, an empty stamp for NaN)."""

    def stamp(t: float) -> Time:
        if not math.isfinite(t):
            return Time()
        ns = stamp_of(c.side, t)
        return s_to_stamp(t) if ns is None else ns_to_stamp(ns)

    out = GaitCycleMsg()
    out.header.stamp = stamp(c.end)
    out.header.frame_id = f"{c.side}_foot"
    out.side = _SIDE_CODE[c.side]
    out.stride_index = c.index
    out.start = stamp(c.start)
    out.terminal_contact = stamp(c.terminal_contact)
    for name in ("stride_time", "stance_time", "swing_time", "stance_fraction", "swing_fraction",
                 "step_time", "cadence", "double_support_time", "double_support_fraction",
                 "step_time_symmetry_index"):
        setattr(out, name, float(getattr(c, name)))
    out.plausible = bool(c.plausible)
    out.flag = c.flag
    return out


def apply_calibration_msg(stream: GaitEventStream, msg: SegmentCalibrationArray) -> None:
    """Hand the feet's entries of a calibration message to the core stream (in force from its stamp)."""
    from_t = stamp_to_s(msg.header.stamp)
    for entry in msg.segments:
        side = entry.segment.removesuffix("_foot")
        if side not in stream.detectors or entry.segment != f"{side}_foot":
            continue
        r = entry.rotation
        stream.set_calibration(side, np.array([r.w, r.x, r.y, r.z]), bool(entry.valid), entry.message, from_t)


def imu_to_foot_sample(imu: Stamped) -> tuple[float, tuple[float, float, float, float]]:
    """(stamp s, sensor→world q) of a decoded ``<side>_foot/imu/data`` message; the stream is given
    the stamp in ns (``imu.ns``) to hand back with events."""
    v = imu.values
    return imu.ns / 1_000_000_000, (v[3], v[0], v[1], v[2])


def stream_options(get: Callable[[str, object], object]) -> dict[str, object]:
    """:class:`GaitEventStream` keyword arguments from parameters (``get(name, default)``)."""
    options: dict[str, object] = {"sides": [s for s in get("sides", ["left", "right"]) if s],
                                  "rate_hz": float(get("rate_hz", 100.0))}
    for name, default in (("threshold", -0.2), ("refractory_s", 0.15), ("window_s", 0.15),
                          ("trend_fraction", 0.8), ("max_gap", 0.5)):
        options[name] = float(get(name, default))
    options["use_standing_reference"] = bool(get("use_standing_reference", False))
    options["symmetry_window"] = int(get("symmetry_window", 10))
    options["min_stride_s"] = float(get("min_stride_s", 0.4))
    options["max_stride_s"] = float(get("max_stride_s", 3.0))
    return options


class GaitEventsNode(Node):
    """Gait events and stride parameters of both feet (see module docstring)."""

    def __init__(self, context: Context | None = None, **overrides: object) -> None:
        super().__init__("gait_events", context=context,
                         parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.stream = GaitEventStream(**stream_options(lambda n, d: self.declare_parameter(n, d).value))
        self.sides = self.stream.sides
        self.stale_after = float(self.declare_parameter("stale_after", 1.0).value)
        diagnostics_period = float(self.declare_parameter("diagnostics_period", 1.0).value)
        self._last_arrival: dict[str, float] = {}
        self._stopped: dict[str, bool] = {s: False for s in self.sides}
        self._events = self.create_publisher(GaitEventMsg, EVENTS_TOPIC, RELIABLE_QOS)
        self._cycles = self.create_publisher(GaitCycleMsg, CYCLES_TOPIC, RELIABLE_QOS)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE_QOS)
        for side in self.sides:
            self.create_subscription(Imu, orientation_topic(f"{side}_foot"),
                                     lambda data, s=side: self._on_imu(s, data), RELIABLE_QOS, raw=True)
        self.create_subscription(SegmentCalibrationArray, CALIBRATION_TOPIC, self._on_calibration,
                                 LATCHED_QOS)
        self.create_timer(diagnostics_period, self._check_streams)

    @property
    def detectors(self) -> dict[str, GaitEventDetector]:
        """Per-foot detectors (held by the core stream)."""
        return self.stream.detectors

    @property
    def calibrated(self) -> dict[str, bool]:
        """Whether each foot's calibration is in force."""
        return self.stream.calibrated

    @property
    def counts(self) -> dict[str, dict[str, int]]:
        """Per-foot counters shown on /diagnostics."""
        return self.stream.counts

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        apply_calibration_msg(self.stream, msg)

    def _say(self) -> None:
        for level, text in self.stream.pop_messages():
            (self.get_logger().warning if level == "warn" else self.get_logger().info)(text)

    def _on_imu(self, side: str, data: bytes) -> None:
        self._last_arrival[side] = time.monotonic()
        self._stopped[side] = False
        imu = decode_imu(data)
        t, q = imu_to_foot_sample(imu)
        for event, cycle in self.stream.update(side, t, q, imu.ns):
            self._events.publish(event_msg(event))
            if cycle is not None:
                self._cycles.publish(cycle_msg(cycle, self.stream.stamp_of))
        self._say()

    def _check_streams(self) -> None:
        now = time.monotonic()
        statuses = []
        note = self.stream.notes
        for side in self.sides:
            last = self._last_arrival.get(side)
            level, message = DiagnosticStatus.OK, "detecting"
            if last is None:
                level, message = DiagnosticStatus.WARN, f"no {side} foot orientation yet"
            elif now - last > self.stale_after:
                if not self._stopped[side]:
                    self._stopped[side] = True
                    self.stream.stream_stopped(side, now - last)
                    self._say()
                level = DiagnosticStatus.ERROR
                message = (f"no data for {now - last:.1f} s: {side} foot state reset; check the sensor "
                           "and the orientation filter")
            elif not self.calibrated[side]:
                level, message = DiagnosticStatus.WARN, "waiting for the foot calibration " + (
                    f"({note[side]})" if note[side] else "(calibration/sensor_to_segment)")
            elif note[side]:
                level, message = DiagnosticStatus.WARN, note[side]
                note[side] = ""
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
