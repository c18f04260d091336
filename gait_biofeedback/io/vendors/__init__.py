"""Vendor backends of ``imu_driver``: links whose ``receive`` gives decoded samples, not our frames.

Each module is ROS-free and imports its vendor's library (``ximu3``, ``python-osc``, ``pyshimmer``,
``bleak``) only when a link is opened, so the package imports without them. Items of
``receive(timeout_s)`` are ``(list[DeviceSample], arrival_ns, source)``
(:class:`~gait_biofeedback.core.driver.protocol.DeviceSample` in SI units), for
:meth:`~gait_biofeedback.core.driver.stream.DriverCore.feed_samples` (docs/connecting_sensors.md).
"""

from __future__ import annotations

import queue

from gait_biofeedback.core.driver.protocol import DeviceSample

Received = list[tuple[list[DeviceSample], int, str]]
"""What a vendor link's ``receive`` gives."""
DRAIN_MAX = 4096
"""Items one ``receive`` takes from a backend's queue at most."""


def drain(items: queue.Queue, timeout_s: float) -> Received:
    """What a backend's threads queued: waits up to ``timeout_s`` for the first item, then takes what
    is there without waiting, at most :data:`DRAIN_MAX` (a link's ``receive``)."""
    out: Received = []
    try:
        out.append(items.get(timeout=timeout_s))
        while len(out) < DRAIN_MAX:
            out.append(items.get_nowait())
    except queue.Empty:
        pass
    return out
