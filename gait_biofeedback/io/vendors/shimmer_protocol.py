"""The Shimmer3 serial protocol (LogAndStream / BtStream firmware) as far as the driver uses it.

Sources: *LogAndStream for Shimmer3, Firmware User Manual* rev 0.11a (Shimmer, 2017): §"Bluetooth
commands" (one command byte, then its arguments, little-endian; the device answers each command with
the acknowledgement byte 0xFF, then for a *get* command its response code and arguments) and §"Data
packet" (0x00, a 3-byte little-endian timestamp of the 32768 Hz clock, then the enabled channels in the
firmware's order); the *Shimmer3 User Manual* rev 3p §"Calibration" for the calibration model and
the factory defaults. Command and channel numbers are the firmware's (``shimmer_btsd.h`` of the
LogAndStream firmware).

Calibration (Shimmer3 User Manual, §Calibration; Ferraris et al., *Sensors and Materials* 7(5), 1995):
for each inertial sensor, ``c = R⁻¹ K⁻¹ (u - b)`` with ``u`` the raw counts, ``b`` the offset bias,
``K = diag(sensitivity)`` and ``R`` the alignment matrix. On the wire (21 bytes per sensor, the
``GET_ALL_CALIBRATION`` response: low-noise accelerometer, gyroscope, magnetometer, wide-range
accelerometer): bias int16 × 3, sensitivity int16 × 3 (big-endian), alignment int8 × 9 in hundredths;
the gyroscope's sensitivity is in hundredths of LSB per °/s. Units after calibration: m/s² for both
accelerometers, °/s for the gyroscope, gauss for the magnetometer (converted to SI here).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

CLOCK_HZ = 32768
"""Ticks per second of the Shimmer3's timestamp clock."""
TIMESTAMP_BITS = 24
"""The data packet's timestamp is the clock's low 24 bits: it wraps every 512 s."""

ACK = 0xFF
DATA_PACKET = 0x00
INSTREAM_RESPONSE = 0x8A
INQUIRY = 0x01
INQUIRY_RESPONSE = 0x02
GET_SAMPLING_RATE = 0x03
SAMPLING_RATE_RESPONSE = 0x04
SET_SAMPLING_RATE = 0x05
START_STREAMING = 0x07
SET_SENSORS = 0x08
STOP_STREAMING = 0x20
GET_ALL_CALIBRATION = 0x2C
ALL_CALIBRATION_RESPONSE = 0x2D
GET_FW_VERSION = 0x2E
FW_VERSION_RESPONSE = 0x2F
GET_STATUS = 0x72
STATUS_RESPONSE = 0x71
GET_SHIMMER_NAME = 0x7B
SHIMMER_NAME_RESPONSE = 0x7A
DUMMY = 0x96
ENABLE_STATUS_ACK = 0xA3
FIRMWARE_LOG_AND_STREAM = 3

ARGUMENT_BYTES = {SET_SAMPLING_RATE: 2, SET_SENSORS: 3, ENABLE_STATUS_ACK: 1}
"""Argument bytes after the command byte of the set commands the driver sends (the others take none)."""

SENSOR_BITS = {"low_noise": 0x80, "gyro": 0x40, "mag": 0x20, "wide_range": 0x10 << 8}
"""Bits of the 3-byte little-endian ``SET_SENSORS`` bitmap."""
CHANNEL_IDS = {"low_noise": (0x00, 0x01, 0x02), "wide_range": (0x04, 0x05, 0x06), "mag": (0x07, 0x08, 0x09),
               "gyro": (0x0A, 0x0B, 0x0C)}
"""Channel numbers of the inquiry response, x y z."""
CHANNEL_FORMAT = {"low_noise": "<3h", "wide_range": "<3h", "mag": "<3h", "gyro": ">3h"}
"""How each sensor's three channels are packed in a data packet: the low-noise accelerometer's 12-bit
ADC counts and the LSM303DLHC's registers little-endian, the MPU9150's registers big-endian."""
CHANNEL_ORDER = ("low_noise", "gyro", "wide_range", "mag")
"""The firmware's order of the sensors' channels in a data packet."""
CALIBRATION_ORDER = ("low_noise", "gyro", "mag", "wide_range")
"""Order of the sensors in the ``GET_ALL_CALIBRATION`` response."""
CALIBRATION_BYTES = 21
GAUSS_T = 1e-4


@dataclass(frozen=True)
class Calibration:
    """One sensor's calibration: raw counts ``u`` → ``R⁻¹ K⁻¹ (u - b)`` in the sensor's unit (module
    docstring). ``sensitivity`` in LSB per unit, ``alignment`` row-major."""

    offset: tuple[float, float, float]
    sensitivity: tuple[float, float, float]
    alignment: tuple[float, ...]

    def matrix(self) -> np.ndarray:
        """``R⁻¹ K⁻¹``: raw counts less the offset → calibrated values."""
        align = np.asarray(self.alignment, float).reshape(3, 3)
        return np.linalg.inv(align) @ np.diag(1.0 / np.asarray(self.sensitivity, float))

    def apply(self, raw: tuple[int, int, int]) -> tuple[float, float, float]:
        out = self.matrix() @ (np.asarray(raw, float) - np.asarray(self.offset, float))
        return float(out[0]), float(out[1]), float(out[2])

    def counts(self, value: np.ndarray) -> np.ndarray:
        """Calibrated values (..., 3) → raw counts ``K R c + b``, rounded (what a device would send)."""
        align = np.asarray(self.alignment, float).reshape(3, 3)
        raw = (np.diag(np.asarray(self.sensitivity, float)) @ align @ np.asarray(value, float).T).T
        return np.rint(raw + np.asarray(self.offset, float)).astype(np.int64)


_SHIMMER_AXES = (0, -1, 0, -1, 0, 0, 0, 0, -1)
_LSM303_AXES = (-1, 0, 0, 0, 1, 0, 0, 0, -1)
DEFAULT_CALIBRATION = {
    "low_noise": Calibration((2047.0, 2047.0, 2047.0), (83.0, 83.0, 83.0), _SHIMMER_AXES),
    "gyro": Calibration((0.0, 0.0, 0.0), (65.5, 65.5, 65.5), _SHIMMER_AXES),
    "mag": Calibration((0.0, 0.0, 0.0), (1100.0, 1100.0, 980.0), _LSM303_AXES),
    "wide_range": Calibration((0.0, 0.0, 0.0), (1631.0, 1631.0, 1631.0), _LSM303_AXES),
}
"""The Shimmer3's factory defaults (Shimmer3 User Manual, §Calibration: low-noise accelerometer ±2 g,
gyroscope ±500 °/s, magnetometer ±1.3 Ga, wide-range accelerometer ±2 g), used for a sensor whose
calibration bytes are unset (all 0xFF)."""


def parse_calibration(data: bytes) -> dict[str, Calibration]:
    """The 84 bytes of a ``GET_ALL_CALIBRATION`` response → each sensor's calibration (its default where
    the device holds none). ValueError if the bytes are too few or a sensitivity is 0."""
    if len(data) < CALIBRATION_BYTES * len(CALIBRATION_ORDER):
        raise ValueError(f"Shimmer calibration: {len(data)} bytes, expected "
                         f"{CALIBRATION_BYTES * len(CALIBRATION_ORDER)}")
    out = {}
    for k, name in enumerate(CALIBRATION_ORDER):
        block = data[k * CALIBRATION_BYTES:(k + 1) * CALIBRATION_BYTES]
        if block == b"\xff" * CALIBRATION_BYTES:
            out[name] = DEFAULT_CALIBRATION[name]
            continue
        values = struct.unpack(">3h3h9b", block)
        sensitivity = tuple(v / 100.0 if name == "gyro" else float(v) for v in values[3:6])
        if 0 in sensitivity:
            raise ValueError(f"Shimmer calibration: the {name} sensitivity is 0 (corrupt calibration: "
                             "calibrate the device again with Shimmer's Consensys)")
        alignment = tuple(v / 100.0 for v in values[6:])
        if abs(np.linalg.det(np.reshape(alignment, (3, 3)))) < 1e-3:
            raise ValueError(f"Shimmer calibration: the {name} alignment matrix is singular")
        out[name] = Calibration(tuple(float(v) for v in values[:3]), sensitivity, alignment)
    return out


def calibration_bytes(calibrations: dict[str, Calibration]) -> bytes:
    """Each sensor's calibration → the 84 bytes a device sends (for the fake device)."""
    out = b""
    for name in CALIBRATION_ORDER:
        c = calibrations[name]
        sensitivity = [round(v * 100) if name == "gyro" else round(v) for v in c.sensitivity]
        out += struct.pack(">3h3h9b", *(round(v) for v in c.offset), *sensitivity,
                           *(round(v * 100) for v in c.alignment))
    return out


def rate_divider(rate_hz: float) -> int:
    """Clock ticks between samples for ``rate_hz`` (the device samples at 32768 Hz / this)."""
    return max(1, min(0xFFFF, round(CLOCK_HZ / rate_hz)))


class TickUnwrapper:
    """24-bit timestamps → ticks since the first one, unwrapped (a gap shorter than 512 s is one lap)."""

    def __init__(self) -> None:
        self._last: int | None = None
        self.ticks = 0

    def __call__(self, raw: int) -> int:
        if self._last is not None:
            self.ticks += (raw - self._last) % (1 << TIMESTAMP_BITS)
        self._last = raw
        return self.ticks

    def reset(self) -> None:
        self._last = None


def ticks_to_us(ticks: int) -> int:
    """Clock ticks → µs (integer, exact to 1 µs)."""
    return ticks * 1_000_000 // CLOCK_HZ


def sequence_of(ticks: int, divider: int) -> int:
    """A sample's sequence number from its unwrapped ticks: samples are ``divider`` ticks apart."""
    return math.floor(ticks / divider + 0.5) % (1 << 32)
