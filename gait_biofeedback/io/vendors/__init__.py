"""Vendor backends of ``imu_driver``: links whose ``receive`` gives decoded samples, not our frames.

Each module is ROS-free and imports its vendor's library (``ximu3``, ``python-osc``, ``pyshimmer``,
``bleak``) only when a link is opened, so the package imports without them. Items of
``receive(timeout_s)`` are ``(list[DeviceSample], arrival_ns, source)``
(:class:`~gait_biofeedback.core.driver.protocol.DeviceSample` in SI units), for
:meth:`~gait_biofeedback.core.driver.stream.DriverCore.feed_samples` (docs/connecting_sensors.md).
"""
