"""The sensor wire format of ``imu_driver``: the frame a small microcontroller IMU node sends.

One frame per UDP datagram; over a serial line the same frames back to back (:class:`FrameReader`
finds them again after noise). Little-endian, packed (no padding)::

    header   8 B   magic "GBI1" (unsigned) or "GBI2" (signed), n_samples u8 (1-255), flags u8,
                   reserved u16 = 0
    sample   40 B  sensor_id u16, reserved u16 = 0, sequence u32, device_time_us u64,
                   acc f32 x3 (m/s², specific force), gyr f32 x3 (rad/s),
                   [mag f32 x3 (T), only if flags bit 0 is set: 52 B]
    tag      16 B  GBI2 only: the first 16 bytes of HMAC-SHA256(session key, header and samples)
    trailer  4 B   CRC-32 (IEEE 802.3, as zlib.crc32) of every byte before it

``sequence`` counts the sensor's samples (+1 per sample, wraps at 2³²): it gives exact loss and
duplicate counts. ``device_time_us`` is the sensor's own clock at the sample (any origin, e.g. µs
since boot): the driver maps it to ROS time. A frame may carry samples of several sensors (a hub).
A reserved field that is not 0 makes the frame corrupt.

The CRC tells a frame damaged on the way from one not signed with the session key (the tag), and
lets :class:`FrameReader` find signed frames without knowing the key; the tag is checked by
:func:`decode_frame` given the key (:func:`load_frame_key`).
"""

from __future__ import annotations

import hashlib
import hmac
import os
import stat
import struct
import zlib
from typing import NamedTuple

MAGIC = b"GBI1"
MAGIC_SIGNED = b"GBI2"
FLAG_MAG = 0x01
MAX_SAMPLES = 255
TAG_SIZE = 16
MIN_KEY_BYTES = 16
_HEADER = struct.Struct("<4sBBH")
_SAMPLE = struct.Struct("<HHIQ6f")
_SAMPLE_MAG = struct.Struct("<HHIQ9f")
_CRC = struct.Struct("<I")
HEADER_SIZE = _HEADER.size
SAMPLE_SIZE = _SAMPLE.size
SAMPLE_MAG_SIZE = _SAMPLE_MAG.size


class FrameError(ValueError):
    """Bytes that are not a whole, intact frame (the message says what is wrong)."""


class SignatureError(FrameError):
    """An intact frame refused for its signature: ``reason`` is ``"unsigned"`` (a GBI1 frame while a
    session key is set), ``"wrong key"`` (a GBI2 frame whose tag the key does not give) or
    ``"no key"`` (a GBI2 frame while no key is set)."""

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


class DeviceSample(NamedTuple):
    """One sample as a sensor sent it: its id, sequence number, device time (µs), specific force
    (m/s²), angular velocity (rad/s) and magnetic field (T, None without magnetometer)."""

    sensor_id: int
    sequence: int
    device_time_us: int
    acc: tuple[float, float, float]
    gyr: tuple[float, float, float]
    mag: tuple[float, float, float] | None = None


def frame_size(n_samples: int, with_mag: bool, signed: bool = False) -> int:
    """Bytes of a frame of ``n_samples`` samples (``signed``: a GBI2 frame, with its tag)."""
    return (HEADER_SIZE + n_samples * (SAMPLE_MAG_SIZE if with_mag else SAMPLE_SIZE)
            + (TAG_SIZE if signed else 0) + _CRC.size)


def frame_tag(key: bytes, body: bytes | memoryview) -> bytes:
    """The 16-byte tag of a GBI2 frame whose header and samples are ``body``."""
    return hmac.new(key, body, hashlib.sha256).digest()[:TAG_SIZE]


def load_frame_key(path: str | os.PathLike) -> bytes:
    """The session key in the file ``path``: its bytes without surrounding whitespace (a final newline),
    at least :data:`MIN_KEY_BYTES`. ValueError (naming the file, never the key) if it cannot be read,
    is not a regular file, is too short, or other users may read it (it must be mode 0600 or 0400).
    The checks are made on the opened file (no swap between a check and the read)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise ValueError(f"cannot read frame key file {path} ({err.strerror})") from err
    with os.fdopen(fd, "rb") as f:
        try:
            info = os.fstat(fd)
            if not stat.S_ISREG(info.st_mode):
                raise ValueError(f"frame key file {path} is not a regular file")
            if info.st_mode & 0o077:
                raise ValueError(f"frame key file {path} may be read by other users (mode "
                                 f"{stat.S_IMODE(info.st_mode):04o}): anyone who reads it can forge sensor "
                                 f"frames; restrict it with 'chmod 600 {path}'")
            key = f.read().strip()
        except OSError as err:
            raise ValueError(f"cannot read frame key file {path} ({err.strerror})") from err
    if len(key) < MIN_KEY_BYTES:
        raise ValueError(f"frame key file {path} holds {len(key)} bytes; a session key has at least "
                         f"{MIN_KEY_BYTES} (e.g. 'openssl rand -hex 32 > {path}')")
    return key


def encode_frame(samples: list[DeviceSample] | tuple[DeviceSample, ...], key: bytes | None = None) -> bytes:
    """One frame of 1-255 samples, all with a magnetometer or all without; signed (GBI2) with
    ``key``, else GBI1."""
    if not 1 <= len(samples) <= MAX_SAMPLES:
        raise ValueError(f"a frame carries 1-{MAX_SAMPLES} samples, got {len(samples)}")
    with_mag = samples[0].mag is not None
    if any((s.mag is not None) != with_mag for s in samples):
        raise ValueError("a frame's samples all have a magnetometer or none has")
    magic = MAGIC if key is None else MAGIC_SIGNED
    parts = [_HEADER.pack(magic, len(samples), FLAG_MAG if with_mag else 0, 0)]
    for s in samples:
        head = (s.sensor_id, 0, s.sequence & 0xFFFFFFFF, s.device_time_us)
        if with_mag:
            parts.append(_SAMPLE_MAG.pack(*head, *s.acc, *s.gyr, *s.mag))
        else:
            parts.append(_SAMPLE.pack(*head, *s.acc, *s.gyr))
    body = b"".join(parts)
    if key is not None:
        body += frame_tag(key, body)
    return body + _CRC.pack(zlib.crc32(body))


def _header(data: bytes | memoryview, offset: int = 0) -> tuple[int, bool, bool]:
    """(n_samples, with magnetometer, signed) of the header at ``offset``; FrameError if it is none."""
    magic, n, flags, reserved = _HEADER.unpack_from(data, offset)
    if magic not in (MAGIC, MAGIC_SIGNED):
        raise FrameError(f"not a sensor frame (starts {bytes(magic)!r}, expected {MAGIC!r} or "
                         f"{MAGIC_SIGNED!r})")
    if n == 0:
        raise FrameError("a frame with 0 samples")
    if reserved:
        raise FrameError(f"the header's reserved field is {reserved:#06x}, not 0")
    return n, bool(flags & FLAG_MAG), magic == MAGIC_SIGNED


def decode_frame(data: bytes | memoryview, key: bytes | None = None) -> list[DeviceSample]:
    """The samples of one whole frame. FrameError if it is short, long, of another format, its CRC
    does not match (a corrupted datagram) or a reserved field is not 0; SignatureError if it is
    intact but unsigned while ``key`` is set, signed with another key, or signed while no key is set."""
    if len(data) < HEADER_SIZE:
        raise FrameError(f"a frame of {len(data)} bytes is shorter than its header ({HEADER_SIZE} B)")
    n, with_mag, signed = _header(data)
    size = frame_size(n, with_mag, signed)
    if len(data) != size:
        raise FrameError(f"a {'signed ' if signed else ''}frame of {n} samples"
                         f"{' with magnetometer' if with_mag else ''} has {size} bytes, got {len(data)}")
    end = size - _CRC.size
    (crc,) = _CRC.unpack_from(data, end)
    if zlib.crc32(data[:end]) != crc:
        raise FrameError("CRC mismatch: the frame was corrupted on the way")
    if signed:
        end -= TAG_SIZE
        if key is None:
            raise SignatureError("a signed frame (GBI2) but no session key is set (parameter "
                                 "'frame_key_file')", "no key")
        if not hmac.compare_digest(frame_tag(key, data[:end]), bytes(data[end:end + TAG_SIZE])):
            raise SignatureError("not signed with the session key", "wrong key")
    elif key is not None:
        raise SignatureError("not signed with the session key (an unsigned GBI1 frame)", "unsigned")
    layout = _SAMPLE_MAG if with_mag else _SAMPLE
    out = []
    for i, v in enumerate(layout.iter_unpack(data[HEADER_SIZE:end])):
        if v[1]:
            raise FrameError(f"sample {i + 1}'s reserved field is {v[1]:#06x}, not 0")
        out.append(DeviceSample(v[0], v[2], v[3], v[4:7], v[7:10], v[10:13] if with_mag else None))
    return out


class FrameReader:
    """Frames out of a byte stream (a serial line): :meth:`feed` bytes as they come, get the whole,
    CRC-checked frames, signed or not (bytes, for :func:`decode_frame`, which checks the tag) that
    completed. Bytes that are not a frame (noise, a frame cut off or with a bad CRC) are skipped up
    to the next magic and counted in :attr:`skipped_bytes` / :attr:`bad_frames`."""

    MAX_BUFFER = 1 << 20

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.skipped_bytes = 0
        self.bad_frames = 0

    def _find_magic(self) -> int:
        found = [i for i in (self._buffer.find(MAGIC), self._buffer.find(MAGIC_SIGNED)) if i >= 0]
        return min(found) if found else -1

    def feed(self, data: bytes) -> list[bytes]:
        buf = self._buffer
        buf += data
        frames: list[bytes] = []
        while True:
            start = self._find_magic()
            if start < 0:
                keep = len(MAGIC) - 1  # the tail may be the start of a magic
                self._skip(max(0, len(buf) - keep))
                break
            self._skip(start)
            if len(buf) < HEADER_SIZE:
                break
            try:
                n, with_mag, signed = _header(buf)
            except FrameError:
                self.bad_frames += 1
                self._skip(1)
                continue
            size = frame_size(n, with_mag, signed)
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
