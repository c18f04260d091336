"""builtin_interfaces/Time ↔ the core's stamps (int ns, ``gait_biofeedback.core.stamps``)."""

from __future__ import annotations

from builtin_interfaces.msg import Time

from gait_biofeedback.core.stamps import NS_PER_S, s_to_ns


def stamp_to_ns(stamp: Time) -> int:
    """builtin_interfaces/Time → integer nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """Integer nanoseconds → builtin_interfaces/Time (floor division keeps nanosec in range)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return Time(sec=sec, nanosec=nanosec)


def stamp_to_s(stamp: Time) -> float:
    """builtin_interfaces/Time → the float nearest to its exact value in seconds (display, tests)."""
    return stamp_to_ns(stamp) / NS_PER_S


def s_to_stamp(t: float) -> Time:
    """Float seconds → builtin_interfaces/Time, rounded to the nanosecond (tests, hand-made messages)."""
    return ns_to_stamp(s_to_ns(t))
