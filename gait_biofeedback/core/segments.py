"""Body segments, frame names and the in-memory form of one IMU's recording.

Segment and frame names follow ``docs/conventions.md`` (Segments and frames): sensor frame
``<segment>_imu``, anatomical frame
``<segment>`` (ISB: x anterior, y superior/proximal, z right-lateral), world ``world`` (ENU).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SEGMENTS: tuple[str, ...] = (
    "pelvis",
    "left_thigh",
    "left_shank",
    "left_foot",
    "right_thigh",
    "right_shank",
    "right_foot",
    "chest",
)
SIDES: tuple[str, ...] = ("left", "right")
WORLD_FRAME = "world"
GRAVITY = 9.81  # m/s², the simulator's and the filters' nominal value
STANDARD_GRAVITY = 9.80665  # m/s² per g, for unit conversion (CGPM 1901)


def sensor_frame(segment: str) -> str:
    """Frame id of the IMU strapped to ``segment`` (header.frame_id of its raw data)."""
    return f"{segment}_imu"


def raw_topic(segment: str) -> str:
    """Relative topic of the raw IMU stream of ``segment``."""
    return f"{segment}/imu/data_raw"


def mag_topic(segment: str) -> str:
    """Relative topic of the magnetometer stream of ``segment``."""
    return f"{segment}/imu/mag"


def orientation_topic(segment: str) -> str:
    """Relative topic of the filtered IMU stream (with orientation) of ``segment``."""
    return f"{segment}/imu/data"


@dataclass
class ImuSeries:
    """One IMU's samples in SI units.

    ``t`` (N,) s, strictly the sample times; ``acc`` (N, 3) m/s² specific force; ``gyr`` (N, 3)
    rad/s; ``mag`` (N, 3) tesla or ``None`` when the sensor has no magnetometer. All vectors in the
    sensor frame ``frame_id``.
    """

    segment: str
    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    mag: np.ndarray | None = None
    frame_id: str = field(default="")

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        n = self.t.shape[0]
        self.acc = _as_vectors(self.acc, n, "acc", self.segment)
        self.gyr = _as_vectors(self.gyr, n, "gyr", self.segment)
        if self.mag is not None:
            self.mag = _as_vectors(self.mag, n, "mag", self.segment)
        if not self.frame_id:
            self.frame_id = sensor_frame(self.segment)

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def rate_hz(self) -> float:
        """Median sampling rate (Hz) from the time stamps."""
        if len(self) < 2:
            raise ValueError(f"{self.segment}: need at least two samples to know the rate")
        return float(1.0 / np.median(np.diff(self.t)))


def _as_vectors(a: np.ndarray, n: int, name: str, segment: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.shape != (n, 3):
        raise ValueError(f"{segment}: {name} has shape {a.shape}, expected ({n}, 3) to match t")
    return a
