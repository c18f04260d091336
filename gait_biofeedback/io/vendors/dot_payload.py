"""Movella DOT Bluetooth LE payloads: what the ``dot`` backend writes and decodes.

Source: *Movella DOT BLE Services Specification*, document XD0506P (Movella, rev C, July 2023).

* UUIDs (§1.1): ``1517xxxx-4947-11e9-8646-d663bd873d93``; configuration service 0x1000 (device
  control 0x1002, §2.2: 32 bytes, the output rate a ``uint16`` at byte 24, written when bit 4 of the
  first byte, the visit index, is set), measurement service 0x2000 (control 0x2001, §3.1: type 1,
  action 1 start / 0 stop, payload mode; medium payload 0x2003, §3.3: notified, 40 bytes), message
  service 0x7000 (control 0x7001, acknowledge 0x7002, §5).
* Payload mode 20, *Rate quantities (with mag)* (Table 15, Table 17): timestamp ``uint32`` µs of the
  sensor's clock (wraps every 2³² µs, 71.6 min), acceleration ``float32`` × 3 in m/s² (calibrated,
  sensor frame, with gravity), angular velocity ``float32`` × 3 in °/s, magnetic field ``int16`` × 3
  fixed point with 12 fractional bits (÷ 2¹², as the vendor's DOT Server example decodes it) in
  arbitrary units, all little-endian (§1.3); 34 bytes, the rest of the 40 zero.
* Messages (§5.1): MID, LEN, DATA, CHECKSUM chosen so that all bytes sum to 0 mod 256. StartSync
  (§5.3.2.1): MID 0x02, SyID 0x01, the root sensor's MAC address least significant byte first; the
  acknowledge (§5.3.3) is MID 0x02, SyID 0x03, a result byte (0x00 success).

The magnetic field's unit is the field strength the sensor's magnetic field mapping was done in
(User Manual, §Magnetic field mapping): :data:`MAG_UNIT_T` turns it into tesla assuming a typical
mid-latitude Earth field; the orientation filters use its direction only.
"""

from __future__ import annotations

import math
import struct

BASE_UUID = "1517{:04x}-4947-11e9-8646-d663bd873d93"
DEVICE_CONTROL = BASE_UUID.format(0x1002)
MEASUREMENT_CONTROL = BASE_UUID.format(0x2001)
MEDIUM_PAYLOAD = BASE_UUID.format(0x2003)
MESSAGE_CONTROL = BASE_UUID.format(0x7001)
MESSAGE_ACK = BASE_UUID.format(0x7002)

RATE_QUANTITIES_WITH_MAG = 20
PAYLOAD_BYTES = 34
OUTPUT_RATES_HZ = (1, 4, 10, 12, 15, 20, 30, 60, 120)
"""Output rates a DOT accepts (§2.2); 120 Hz is for recording, not live streaming over BLE."""
STREAM_RATES_HZ = OUTPUT_RATES_HZ[:-1]
MAG_UNIT_T = 50e-6
"""Tesla per arbitrary unit of the DOT's magnetic field (module docstring)."""
TIMESTAMP_WRAP_US = 1 << 32
_PAYLOAD = struct.Struct("<I6f3h")
_MID_SYNC = 0x02
_SYNC_START, _SYNC_ACK = 0x01, 0x03
SYNC_RESULTS = {0x00: "success", 0x05: "not enough samples", 0x07: "clock skew too large",
                0x08: "start time error", 0x09: "sync not started"}


class PayloadError(ValueError):
    """A notification that is not a whole, sane payload of the mode asked for (the message says why)."""


Vector = tuple[float, float, float]


def decode_rate_quantities(data: bytes) -> tuple[int, Vector, Vector, Vector]:
    """A *Rate quantities (with mag)* notification → (timestamp µs, acc m/s², gyr °/s, mag a.u.)."""
    if len(data) < PAYLOAD_BYTES:
        raise PayloadError(f"{len(data)} bytes, a Rate quantities (with mag) payload has {PAYLOAD_BYTES}")
    stamp, ax, ay, az, gx, gy, gz, mx, my, mz = _PAYLOAD.unpack_from(data)
    acc, gyr = (ax, ay, az), (gx, gy, gz)
    if not all(math.isfinite(v) for v in (*acc, *gyr)):
        raise PayloadError("acceleration or angular velocity is not a finite number")
    return stamp, acc, gyr, (mx / 4096.0, my / 4096.0, mz / 4096.0)


def encode_rate_quantities(stamp_us: int, acc, gyr_dps, mag_au) -> bytes:
    """The inverse of :func:`decode_rate_quantities`, padded to the 40 bytes of the characteristic (for
    fake sensors)."""
    mag = (max(-32768, min(32767, round(v * 4096.0))) for v in mag_au)
    return _PAYLOAD.pack(stamp_us % TIMESTAMP_WRAP_US, *acc, *gyr_dps, *mag).ljust(40, b"\0")


def measurement_control(start: bool, mode: int = RATE_QUANTITIES_WITH_MAG) -> bytes:
    """Start or stop measurement in ``mode`` (§3.1)."""
    return bytes([1, 1 if start else 0, mode])


def output_rate_control(rate_hz: int) -> bytes:
    """The device control write that sets only the output rate (§2.2)."""
    if rate_hz not in OUTPUT_RATES_HZ:
        rates = ", ".join(map(str, OUTPUT_RATES_HZ))
        raise ValueError(f"a Movella DOT's output rate is one of {rates} Hz, not {rate_hz:g}")
    out = bytearray(32)
    out[0] = 0x10
    struct.pack_into("<H", out, 24, rate_hz)
    return bytes(out)


def message(mid: int, data: bytes) -> bytes:
    """A message-service message with its checksum (§5.1)."""
    body = bytes([mid, len(data)]) + data
    return body + bytes([-sum(body) % 256])


def start_sync(root_address: str) -> bytes:
    """StartSync with ``root_address`` (``"D4:22:CD:AA:BB:CC"``) as the root sensor (§5.3.2.1)."""
    mac = bytes.fromhex(root_address.replace(":", ""))
    if len(mac) != 6:
        raise ValueError(f"{root_address!r} is not a Bluetooth address")
    return message(_MID_SYNC, bytes([_SYNC_START]) + mac[::-1])


def sync_result(ack: bytes) -> str:
    """The acknowledge read after StartSync → ``"success"`` or what failed (§5.3.3)."""
    if len(ack) < 4 or ack[0] != _MID_SYNC or ack[2] != _SYNC_ACK or sum(ack[:ack[1] + 3]) % 256:
        return f"no sync acknowledge (read {ack[:8].hex()})"
    return SYNC_RESULTS.get(ack[3], f"result 0x{ack[3]:02x}")


class MicrosecondUnwrapper:
    """``uint32`` µs timestamps → µs since the first, unwrapped (gaps shorter than 71.6 min)."""

    def __init__(self) -> None:
        self._last: int | None = None
        self.us = 0

    def __call__(self, stamp: int) -> int:
        if self._last is not None:
            self.us += (stamp - self._last) % TIMESTAMP_WRAP_US
        self._last = stamp
        return self.us
