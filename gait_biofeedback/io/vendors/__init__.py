"""Vendor backends of ``imu_driver``: links whose ``receive(timeout_s)`` gives
``[(list[DeviceSample], arrival ns, source), ...]`` in SI units (docs/connecting_sensors.md). Each
imports its vendor's library only when opened, so the package imports without it."""
