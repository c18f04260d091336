"""The sensor wire format of ``imu_driver``: the frame a small microcontroller IMU node sends.

One frame per UDP datagram; over a serial line the same frames back to back (:class:`FrameReader`
finds them again after noise). Little-endian, packed (no padding)::

    header   8 B   magic "GBI1" (4 ASCII bytes), n_samples u8 (1-255), flags u8, reserved u16 = 0
    sample   40 B  sensor_id u16, reserved u16 = 0, sequence u32, device_time_us u64,
                   acc f32 x3 (m/s², specific force), gyr f32 x3 (rad/s),
                   [mag f32 x3 (T), only if flags bit 0 is set: 52 B]
    trailer  4 B   CRC-32 (IEEE 802.3, as zlib.crc32) of header and samples

``sequence`` counts the sensor's samples (+1 per sample, wraps at 2³²): it gives exact loss and
duplicate counts. ``device_time_us`` is the sensor's own clock at the sample (any origin, e.g. µs
since boot): the driver maps it to ROS time. A frame may carry samples of several sensors (a hub).
"""

from __future__ import annotations

import struct
import zlib
from typing import NamedTuple

MAGIC = b"GBI1"
FLAG_MAG = 0x01
MAX_SAMPLES = 255
_HEADER = struct.Struct("<4sBBH")
_SAMPLE = struct.Struct("<HHIQ6f")
_SAMPLE_MAG = struct.Struct("<HHIQ9f")
_CRC = struct.Struct("<I")
HEADER_SIZE = _HEADER.size
SAMPLE_SIZE = _SAMPLE.size
SAMPLE_MAG_SIZE = _SAMPLE_MAG.size


class FrameError(ValueError):
    """Bytes that are not a whole, intact frame (the message says what is wrong)."""


class DeviceSample(NamedTuple):
    """One sample as a sensor sent it: its id, sequence number, device time (µs), specific force
    (m/s²), angular velocity (rad/s) and magnetic field (T, None without magnetometer)."""

    sensor_id: int
    sequence: int
    device_time_us: int
    acc: tuple[float, float, float]
    gyr: tuple[float, float, float]
    mag: tuple[float, float, float] | None = None


def frame_size(n_samples: int, with_mag: bool) -> int:
    """Bytes of a frame of ``n_samples`` samples."""
    return HEADER_SIZE + n_samples * (SAMPLE_MAG_SIZE if with_mag else SAMPLE_SIZE) + _CRC.size


def encode_frame(samples: list[DeviceSample] | tuple[DeviceSample, ...]) -> bytes:
    """One frame of 1-255 samples; all with a magnetometer or all without."""
    if not 1 <= len(samples) <= MAX_SAMPLES:
        raise ValueError(f"a frame carries 1-{MAX_SAMPLES} samples, got {len(samples)}")
    with_mag = samples[0].mag is not None
    if any((s.mag is not None) != with_mag for s in samples):
        raise ValueError("a frame's samples all have a magnetometer or none has")
    parts = [_HEADER.pack(MAGIC, len(samples), FLAG_MAG if with_mag else 0, 0)]
    for s in samples:
        head = (s.sensor_id, 0, s.sequence & 0xFFFFFFFF, s.device_time_us)
        if with_mag:
            parts.append(_SAMPLE_MAG.pack(*head, *s.acc, *s.gyr, *s.mag))
        else:
            parts.append(_SAMPLE.pack(*head, *s.acc, *s.gyr))
    body = b"".join(parts)
    return body + _CRC.pack(zlib.crc32(body))


def _header(data: bytes | memoryview, offset: int = 0) -> tuple[int, bool]:
    magic, n, flags, _ = _HEADER.unpack_from(data, offset)
    if magic != MAGIC:
        raise FrameError(f"not a sensor frame (starts {bytes(magic)!r}, expected {MAGIC!r})")
    if n == 0:
        raise FrameError("a frame with 0 samples")
    return n, bool(flags & FLAG_MAG)


def decode_frame(data: bytes | memoryview) -> list[DeviceSample]:
    """The samples of one whole frame; FrameError if it is short, long, of another format or its
    CRC does not match (a corrupted datagram)."""
    if len(data) < HEADER_SIZE:
        raise FrameError(f"a frame of {len(data)} bytes is shorter than its header ({HEADER_SIZE} B)")
    n, with_mag = _header(data)
    size = frame_size(n, with_mag)
    if len(data) != size:
        raise FrameError(f"a frame of {n} samples{' with magnetometer' if with_mag else ''} has {size} "
                         f"bytes, got {len(data)}")
    (crc,) = _CRC.unpack_from(data, size - _CRC.size)
    if zlib.crc32(data[:size - _CRC.size]) != crc:
        raise FrameError("CRC mismatch: the frame was corrupted on the way")
    layout = _SAMPLE_MAG if with_mag else _SAMPLE
    out = []
    for v in layout.iter_unpack(data[HEADER_SIZE:size - _CRC.size]):
        out.append(DeviceSample(v[0], v[2], v[3], v[4:7], v[7:10], v[10:13] if with_mag else None))
    return out


class FrameReader:
    """Frames out of a byte stream (a serial line): :meth:`feed` bytes as they come, get the whole,
    CRC-checked frames (bytes, for :func:`decode_frame`) that completed. Bytes that are not a frame
    (noise, a frame cut off or with a bad CRC) are
    skipped up to the next magic and counted in :attr:`skipped_bytes` / :attr:`bad_frames`."""

    MAX_BUFFER = 1 << 20

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.skipped_bytes = 0
        self.bad_frames = 0

    def feed(self, data: bytes) -> list[bytes]:
        buf = self._buffer
        buf += data
        frames: list[bytes] = []
        while True:
            start = buf.find(MAGIC)
            if start < 0:
                keep = len(MAGIC) - 1  # the tail may be the start of a magic
                self._skip(max(0, len(buf) - keep))
                break
            self._skip(start)
            if len(buf) < HEADER_SIZE:
                break
            try:
                n, with_mag = _header(buf)
            except FrameError:
                self.bad_frames += 1
                self._skip(1)
                continue
            size = frame_size(n, with_mag)
            if len(buf) < size:
                if len(buf) > self.MAX_BUFFER:
                    self._skip(len(buf))
                break
            frame = bytes(buf[:size])
            (crc,) = _CRC.unpack_from(frame, size - _CRC.size)
            if zlib.crc32(frame[:size - _CRC.size]) != crc:
                self.bad_frames += 1
                self._skip(1)  # a false magic or a damaged frame: look for the next one
                continue
            frames.append(frame)
            del buf[:size]
        return frames

    def _skip(self, n: int) -> None:
        if n:
            del self._buffer[:n]
            self.skipped_bytes += n
