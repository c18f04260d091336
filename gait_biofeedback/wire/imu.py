"""IMU messages ↔ the core: raw ``<segment>/imu/data_raw`` and ``imu/mag`` samples in, filtered
``<segment>/imu/data`` out, and whole :class:`~gait_biofeedback.core.segments.ImuSeries` as messages.

sensor_msgs/Imu stores the quaternion (x, y, z, w); the core uses (w, x, y, z) (``docs/conventions.md``):
:func:`quaternion` is the one place that reorders. A raw Imu has ``orientation_covariance[0] = -1``
(orientation unknown) and 0 elsewhere (unknown covariances).

A filtered sample whose orientation is being re-acquired after a dropout (``recovering``) carries
``RECOVERING_VARIANCE`` on the diagonal of ``orientation_covariance`` instead of the parameter
``orientation_variance`` (whose range stays below it): the standard field says "this orientation is
uncertain", and :func:`is_recovering` is how every consumer reads it. A sample filtered without a
magnetometer (6D: heading from the gyro only, not shared between sensors) carries
``HEADING_UNKNOWN_VARIANCE`` as its yaw variance (``orientation_covariance[8]``, ROS's
roll-pitch-yaw order), read by :func:`has_heading`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.core.orientation.stream import OrientationSample
from gait_biofeedback.core.segments import ImuSeries, sensor_frame
from gait_biofeedback.core.stamps import seconds_to_ns
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.cdr import (
    ANGULAR_VELOCITY,
    ANGULAR_VELOCITY_COV,
    IMU_DOUBLES,
    LINEAR_ACCELERATION,
    LINEAR_ACCELERATION_COV,
    MAGNETIC_FIELD,
    ORIENTATION,
    ORIENTATION_COV,
    Stamped,
    encode_stamped,
)
from gait_biofeedback.wire.stamps import ns_to_stamp

Vector = tuple[float, float, float]

RECOVERING_VARIANCE = math.radians(10.0) ** 2
"""rad², the orientation variance of a sample published while the attitude is re-acquired."""

HEADING_UNKNOWN_VARIANCE = math.pi ** 2
"""rad², the yaw variance of a sample filtered without a magnetometer (heading unknown)."""


def quaternion(imu: Stamped) -> tuple[float, float, float, float]:
    """The orientation (w, x, y, z) of a decoded Imu (stored x, y, z, w on the wire)."""
    x, y, z, w = imu.values[ORIENTATION]
    return w, x, y, z


def raw_sample(imu: Stamped) -> tuple[int, Vector, Vector]:
    """(stamp ns, angular velocity rad/s, specific force m/s²) of a raw Imu."""
    v = imu.values
    return imu.ns, v[ANGULAR_VELOCITY], v[LINEAR_ACCELERATION]


def mag_sample(mag: Stamped) -> tuple[int, Vector]:
    """(stamp ns, field T) of a MagneticField."""
    return mag.ns, mag.values[MAGNETIC_FIELD]


def orientation_sample(imu: Stamped) -> tuple[int, Vector, Vector, tuple[float, float, float, float]]:
    """(stamp ns, specific force, bias-corrected angular velocity, q (w, x, y, z)) of a filtered Imu."""
    v = imu.values
    return imu.ns, v[LINEAR_ACCELERATION], v[ANGULAR_VELOCITY], quaternion(imu)


def is_recovering(imu: Stamped) -> bool:
    """The filtered sample's orientation is being re-acquired after a dropout (module docstring)."""
    return imu.values[ORIENTATION_COV][0] >= RECOVERING_VARIANCE


def has_heading(imu: Stamped) -> bool:
    """The filtered sample's heading came from a magnetometer (module docstring)."""
    return imu.values[ORIENTATION_COV][8] < HEADING_UNKNOWN_VARIANCE


def angular_speed(imu: Stamped) -> float:
    """|ω| (rad/s) of a decoded Imu."""
    return math.hypot(*imu.values[ANGULAR_VELOCITY])


def orientation_fields(segment: str, sample: OrientationSample, raw: Stamped, variance: float
                       ) -> tuple[int, str, tuple[float, ...]]:
    """``<segment>/imu/data`` of one filtered sample as (stamp ns, frame_id, the 37 doubles): its one
    definition, the fields of :func:`~gait_biofeedback.wire.cdr.pack_imu` (the bytes the
    ``orientation_filter`` node publishes and ``analyze`` writes) and of :class:`Stamped` (what
    :func:`~gait_biofeedback.wire.cdr.decode_imu` of those bytes gives: float64 in and out of CDR is
    exact). The sample's stamp, the sensor frame, q, the bias-corrected gyro, the raw acceleration, a
    diagonal orientation covariance (``RECOVERING_VARIANCE`` while recovering, yaw
    ``HEADING_UNKNOWN_VARIANCE`` without a magnetometer) and the raw covariances of the message that
    released the sample."""
    w, x, y, z = sample.q.tolist()
    v = float(RECOVERING_VARIANCE if sample.recovering else variance)
    yaw = v if sample.heading else float(HEADING_UNKNOWN_VARIANCE)
    values = (x, y, z, w, v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, yaw, *sample.gyr.tolist(),
              *raw.values[ANGULAR_VELOCITY_COV], *sample.acc.tolist(), *raw.values[LINEAR_ACCELERATION_COV])
    return sample.stamp_ns, sensor_frame(segment), values


def orientation_messages(segment: str, stamp_ns: np.ndarray, q: np.ndarray, gyr: np.ndarray, acc: np.ndarray,
                         recovering: np.ndarray, heading: np.ndarray, raw_cov: np.ndarray, variance: float
                         ) -> list[tuple[bytes, Stamped]]:
    """:func:`orientation_fields` of many samples (arrays: stamps (n,), q (n, 4) w, x, y, z, gyr, acc (n, 3),
    flags (n,), ``raw_cov`` (n, 37) the doubles of the raw message that released each), encoded in bulk
    (:func:`~gait_biofeedback.wire.cdr.encode_stamped`): [(the bytes
    :func:`~gait_biofeedback.wire.cdr.pack_imu` gives, the
    :class:`Stamped` they decode to)]."""
    n = len(stamp_ns)
    if not n:
        return []
    values = np.zeros((n, IMU_DOUBLES))
    values[:, ORIENTATION] = q[:, [1, 2, 3, 0]]
    v = np.where(recovering, RECOVERING_VARIANCE, float(variance))
    values[:, 4] = values[:, 8] = v
    values[:, 12] = np.where(heading, v, float(HEADING_UNKNOWN_VARIANCE))
    values[:, ANGULAR_VELOCITY], values[:, LINEAR_ACCELERATION] = gyr, acc
    values[:, ANGULAR_VELOCITY_COV] = raw_cov[:, ANGULAR_VELOCITY_COV]
    values[:, LINEAR_ACCELERATION_COV] = raw_cov[:, LINEAR_ACCELERATION_COV]
    frame = sensor_frame(segment)
    payloads = encode_stamped(stamp_ns, frame, values)
    return [(data, Stamped(ns, frame, tuple(row)))
            for data, ns, row in zip(payloads, stamp_ns.tolist(), values.tolist(), strict=True)]


def raw_imu_values(gyr: Vector, acc: Vector) -> tuple[float, ...]:
    """The 37 doubles of a raw ``<segment>/imu/data_raw`` (for :func:`~gait_biofeedback.wire.cdr.pack_imu`):
    orientation unknown (identity, covariance[0] = -1), ``gyr`` rad/s, ``acc`` m/s², covariances 0."""
    return (0.0, 0.0, 0.0, 1.0, -1.0, *_ZEROS[:8], *gyr, *_ZEROS, *acc, *_ZEROS)


_ZEROS = (0.0,) * 9


def series_topics(segment: str) -> tuple[str, str]:
    """Absolute (raw Imu topic, MagneticField topic) of ``segment`` in a recording."""
    return topics.raw_imu(segment).absolute(), topics.magnetometer(segment).absolute()


def encode_series(series: ImuSeries) -> tuple[np.ndarray, list[bytes], list[bytes] | None]:
    """``(stamps ns, raw Imu payloads, MagneticField payloads or None)`` of a whole series, the bytes
    ``serialize_message`` gives (with the padding zeroed)."""
    ns = seconds_to_ns(series.t)
    doubles = np.zeros((len(ns), IMU_DOUBLES))
    doubles[:, 3], doubles[:, 4] = 1.0, -1.0  # orientation w = 1, orientation_covariance[0] = -1
    doubles[:, ANGULAR_VELOCITY], doubles[:, LINEAR_ACCELERATION] = series.gyr, series.acc
    imu = encode_stamped(ns, series.frame_id, doubles)
    mag = None
    if series.mag is not None:
        mag = encode_stamped(ns, series.frame_id, np.hstack([series.mag, np.zeros((len(ns), 9))]))
    return ns, imu, mag


def series_messages(series: ImuSeries) -> Iterator[tuple[str, Any, int]]:
    """``(topic, rclpy message, stamp ns)`` for every sample: an Imu, then a MagneticField if the
    series has a magnetometer (the slow path of :func:`encode_series`, for tests and peers)."""
    imu_topic, mag_name = series_topics(series.segment)
    for i, ns in enumerate(seconds_to_ns(series.t).tolist()):
        imu = Imu()
        imu.header.stamp, imu.header.frame_id = ns_to_stamp(ns), series.frame_id
        imu.orientation_covariance[0] = -1.0
        gx, gy, gz = series.gyr[i].tolist()
        ax, ay, az = series.acc[i].tolist()
        imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = gx, gy, gz
        imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = ax, ay, az
        yield imu_topic, imu, ns
        if series.mag is not None:
            mag = MagneticField()
            mag.header.stamp, mag.header.frame_id = ns_to_stamp(ns), series.frame_id
            mag.magnetic_field.x, mag.magnetic_field.y, mag.magnetic_field.z = series.mag[i].tolist()
            yield mag_name, mag, ns
