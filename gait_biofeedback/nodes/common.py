"""What every node shares: QoS profiles, time conversion, executors, diagnostics, `main`.

Nodes stay thin: they convert messages, hold parameters and call the core. Executor choice is
measured (ROS_FROM_PYPI.md): an ``EventsExecutor`` driven by ``spin_once`` in a loop is about 3×
cheaper than the ``SingleThreadedExecutor``; its ``spin()`` is broken in rclpy 7.1.6, so it is never
called. ``GAIT_EXECUTOR=single`` selects the fallback.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence

import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

SENSOR_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
"""Raw sensor streams (DESIGN.md: best effort, depth 100)."""

RELIABLE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=300,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Derived streams: orientations, joint states, events, cues. Depth 300, not DESIGN.md's 100: the
orientation filter releases its start-up window (1 s = 100 samples at 100 Hz, 200 at 200 Hz) in one
burst, and a KEEP_LAST history as deep as the burst drops its first samples."""

LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""State a late subscriber must still get: the calibration in force."""

DIAGNOSTICS_TOPIC = "/diagnostics"
CALIBRATION_TOPIC = "calibration/sensor_to_segment"  # latched SegmentCalibrationArray


def stamp_to_ns(stamp: Time) -> int:
    """builtin_interfaces/Time → integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """Integer nanoseconds → builtin_interfaces/Time (floor division keeps nanosec in range)."""
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def stamp_to_s(stamp: Time) -> float:
    """builtin_interfaces/Time → the float nearest to its exact value in seconds (the same number
    :func:`gait_biofeedback.io.imu_messages.ns_to_seconds` gives, so live and offline agree)."""
    return stamp_to_ns(stamp) / 1_000_000_000


def s_to_stamp(t: float) -> Time:
    """Float seconds → builtin_interfaces/Time, rounded to the nanosecond."""
    whole = math.floor(t)
    return ns_to_stamp(int(whole) * 1_000_000_000 + round((t - whole) * 1e9))


def diagnostic_status(
    name: str, level: int | bytes, message: str, hardware_id: str = "", values: dict | None = None
) -> DiagnosticStatus:
    """One DiagnosticStatus with ``values`` rendered as strings (floats with 4 significant digits);
    ``level`` is DiagnosticStatus.OK/WARN/ERROR/STALE (bytes) or the same as an int."""
    if isinstance(level, int):
        level = bytes([level])
    status = DiagnosticStatus(name=name, level=level, message=message, hardware_id=hardware_id)
    for key, value in (values or {}).items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        status.values.append(KeyValue(key=str(key), value=text))
    return status


def diagnostic_array(node: Node, statuses: Iterable[DiagnosticStatus]) -> DiagnosticArray:
    """DiagnosticArray stamped with the node clock."""
    msg = DiagnosticArray()
    msg.header.stamp = node.get_clock().now().to_msg()
    msg.status = list(statuses)
    return msg


def make_executor(context: Context | None = None) -> Executor:
    """The project's executor: EventsExecutor (driven by spin_once) unless GAIT_EXECUTOR=single."""
    if os.environ.get("GAIT_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor(context=context)
    from rclpy.experimental import EventsExecutor

    return EventsExecutor(context=context)


def spin_until(
    executor: Executor,
    done: Callable[[], bool],
    timeout: float | None = None,
    period: float = 0.05,
    check_every: float = 0.005,
) -> bool:
    """Drive ``executor`` with ``spin_once`` until ``done()`` or ``timeout`` s; True if done.

    ``spin_once`` handles one callback, i.e. runs thousands of times a second in a busy graph; the
    context, ``done()`` and the deadline are checked at most every ``check_every`` s, not after each
    callback (an idle ``spin_once`` waits ``period`` s, so an idle graph checks after each)."""
    deadline = None if timeout is None else time.monotonic() + timeout
    context = executor.context
    spin_once = executor.spin_once
    monotonic = time.monotonic
    next_check = 0.0
    while True:
        now = monotonic()
        if now >= next_check:
            if not context.ok() or done():
                break
            if deadline is not None and now > deadline:
                return False
            next_check = now + check_every
        spin_once(timeout_sec=period)
    return done()


def run_nodes(node_factories: Sequence[Callable[[Context], Node]], args: list[str] | None = None) -> int:
    """Console-script body: init rclpy with ``args`` (``--ros-args`` work), spin the nodes until
    Ctrl-C / SIGTERM, destroy them (each node's ``destroy_node`` closes its files) and shut down."""
    context = Context()
    rclpy.init(args=sys.argv if args is None else args, context=context)
    nodes: list[Node] = []
    executor = make_executor(context)
    try:
        for factory in node_factories:
            nodes.append(factory(context))
            executor.add_node(nodes[-1])
        spin_until(executor, lambda: False)
    except KeyboardInterrupt:
        pass
    finally:
        for node in nodes:
            node.destroy_node()
        executor.shutdown()
        if context.ok():
            rclpy.shutdown(context=context)
    return 0
