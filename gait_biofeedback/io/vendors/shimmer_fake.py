"""Fake Shimmer3 devices on pseudo-terminals, for tests, demos and ``stream-sim --as shimmer``.

Each :class:`FakeShimmer` is a pseudo-terminal (``os.openpty``) whose far end, :attr:`FakeShimmer.path`,
a Shimmer client (``pyshimmer``, the driver's ``shimmer`` backend) opens as it would a Bluetooth serial
port (``/dev/rfcomm0``). It answers the LogAndStream commands a client sends at connect (firmware
version, status acknowledgement, sampling rate, enabled sensors, calibration, inquiry, start and stop
streaming) and streams a recording's samples as data packets, written from the protocol as Shimmer
documents it (:mod:`~gait_biofeedback.io.vendors.shimmer_protocol`): its own 32768 Hz clock (offset,
drift), a sample every ``32768 / rate`` ticks, raw counts through the inverse of its calibration.
Packets may be delayed (jitter, order kept: a serial line does not reorder) or lost. Times are the
system clock's (ns), as the driver's arrival stamps.

:class:`FakeShimmers` serves several in one thread (``start``/``close``).
"""

from __future__ import annotations

import contextlib
import os
import select
import struct
import threading
import time
import tty

import numpy as np

from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.io.vendors import shimmer_protocol as sp

_LIMITS = {"low_noise": (0, 4095), "wide_range": (-32768, 32767), "gyro": (-32768, 32767),
           "mag": (-2048, 2047)}
"""Raw ranges: the 12-bit ADC, the 16-bit registers, the LSM303DLHC's 12-bit magnetometer."""


class FakeShimmer:
    """One fake Shimmer3 playing ``series`` (module docstring). ``offset_s``: its clock at connect,
    ``drift_ppm``: how fast its clock runs; ``jitter_s``: each packet written up to this late;
    ``loss``: fraction of packets not sent (the radio lost them: their ticks still pass)."""

    def __init__(self, series: ImuSeries, name: str = "Shimmer3-fake", *, offset_s: float = 0.0,
                 drift_ppm: float = 0.0, jitter_s: float = 0.0, loss: float = 0.0, seed: int = 0,
                 calibration: dict[str, sp.Calibration] | None = None) -> None:
        self.series, self.name = series, name
        self.calibration = calibration or dict(sp.DEFAULT_CALIBRATION)
        self.offset_ticks = round(offset_s * sp.CLOCK_HZ)
        self.drift = drift_ppm * 1e-6
        self.jitter_s, self.loss = jitter_s, loss
        self._rng = np.random.default_rng(seed)
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self._slave)
        self.divider = sp.rate_divider(100.0)
        self.sensors = sp.SENSOR_BITS["wide_range"] | sp.SENSOR_BITS["gyro"] | sp.SENSOR_BITS["mag"]
        self.streaming = False
        self.started = False
        """Whether a client has started it streaming (once at least)."""
        self.sent = 0
        """Data packets written."""
        self.dropped = 0
        """Samples not sent (``loss``)."""
        self.due_ns: list[int] = []
        """Each sample's host time (ns) when the device measured it, lost ones too: the truth."""
        self.kept: list[bool] = []
        """Per sample of :attr:`due_ns`: whether it was sent."""
        self.out_of_range_until_ns = 0
        """Until then (system clock, ns) nothing gets through either way: :meth:`go_out_of_range`."""
        self._in = bytearray()
        self._out = bytearray()
        self._k = 0
        self._t0_ns = 0
        self._last_write_ns = 0
        self._raw: dict[str, np.ndarray] = {}

    @property
    def enabled(self) -> list[str]:
        """Sensors streamed, in the packet's order."""
        return [s for s in sp.CHANNEL_ORDER if self.sensors & sp.SENSOR_BITS[s]]

    @property
    def finished(self) -> bool:
        return self._k >= len(self.series.t)

    def go_out_of_range(self, seconds: float) -> None:
        """The Bluetooth link drops for ``seconds``, as when the wearer walks out of radio range: the
        device stops streaming and hears nothing meanwhile; its clock runs on, so when a client starts
        it again the samples of the time away are missing (counted in :attr:`dropped`)."""
        self.out_of_range_until_ns = time.time_ns() + round(seconds * 1e9)
        self.streaming = False
        self._out.clear()

    def feed(self, data: bytes, now_ns: int) -> None:
        """Commands from the client: each answered (acknowledgement, then its response)."""
        if now_ns < self.out_of_range_until_ns:
            return
        self._in += data
        while self._in:
            command = self._in[0]
            need = 1 + sp.ARGUMENT_BYTES.get(command, 0)
            if len(self._in) < need:
                return
            args = bytes(self._in[1:need])
            del self._in[:need]
            self._out += bytes([sp.ACK]) + self._answer(command, args, now_ns)

    def _answer(self, command: int, args: bytes, now_ns: int) -> bytes:
        if command == sp.GET_FW_VERSION:
            return struct.pack("<BHHBB", sp.FW_VERSION_RESPONSE, sp.FIRMWARE_LOG_AND_STREAM, 0, 16, 0)
        if command == sp.GET_SAMPLING_RATE:
            return struct.pack("<BH", sp.SAMPLING_RATE_RESPONSE, self.divider)
        if command == sp.SET_SAMPLING_RATE:
            self.divider = max(1, struct.unpack("<H", args)[0])
        elif command == sp.SET_SENSORS:
            self.sensors = int.from_bytes(args, "little")
        elif command == sp.GET_ALL_CALIBRATION:
            return bytes([sp.ALL_CALIBRATION_RESPONSE]) + sp.calibration_bytes(self.calibration)
        elif command == sp.INQUIRY:
            channels = [c for s in self.enabled for c in sp.CHANNEL_IDS[s]]
            head = struct.pack("<BHIBB", sp.INQUIRY_RESPONSE, self.divider, 0, len(channels), 1)
            return head + bytes(channels)
        elif command == sp.GET_STATUS:
            return bytes([sp.INSTREAM_RESPONSE, sp.STATUS_RESPONSE, 0x12 if self.streaming else 0x02])
        elif command == sp.GET_SHIMMER_NAME:
            name = self.name.encode()[:255]
            return bytes([sp.SHIMMER_NAME_RESPONSE, len(name)]) + name
        elif command == sp.START_STREAMING and not self.streaming:
            self._start(now_ns)
        elif command == sp.STOP_STREAMING:
            self.streaming = False
        return b""

    def _start(self, now_ns: int) -> None:
        if self.started:  # started again: from the sample its clock is at now
            self.streaming = True
            while not self.finished and self.sample_due_ns(self._k) < now_ns:
                self.due_ns.append(self.sample_due_ns(self._k))
                self.kept.append(False)
                self.dropped += 1
                self._k += 1
            return
        self.streaming = self.started = True
        self._t0_ns = now_ns
        s = self.series
        values = {"low_noise": s.acc, "wide_range": s.acc, "gyro": np.degrees(s.gyr),
                  "mag": (s.mag if s.mag is not None else np.zeros_like(s.acc)) / sp.GAUSS_T}
        self._raw = {name: np.clip(self.calibration[name].counts(values[name]), *_LIMITS[name])
                     for name in sp.CHANNEL_ORDER}

    def sample_due_ns(self, k: int) -> int:
        """Host time (ns) of sample ``k`` since streaming started, by the device's drifting clock."""
        return self._t0_ns + round(k * self.divider / sp.CLOCK_HZ / (1.0 + self.drift) * 1e9)

    def next_due_ns(self) -> int | None:
        return self.sample_due_ns(self._k) if self.streaming and not self.finished else None

    def produce(self, now_ns: int) -> None:
        """Data packets of the samples due by ``now_ns`` (their jitter drawn, written in order)."""
        while self.streaming and not self.finished and self.sample_due_ns(self._k) <= now_ns:
            k = self._k
            self._k += 1
            self.due_ns.append(self.sample_due_ns(k))
            lost = now_ns < self.out_of_range_until_ns or (self.loss and self._rng.random() < self.loss)
            self.kept.append(not lost)
            if lost:
                self.dropped += 1
                continue
            if self.jitter_s:  # a late packet holds the ones after it back: the line keeps order
                late = self.due_ns[-1] + round(self._rng.uniform(0.0, self.jitter_s) * 1e9)
                self._last_write_ns = max(self._last_write_ns, late)
            self._out += self.packet(k)
            self.sent += 1

    def packet(self, k: int) -> bytes:
        ticks = (self.offset_ticks + k * self.divider) % (1 << sp.TIMESTAMP_BITS)
        body = bytearray([sp.DATA_PACKET]) + ticks.to_bytes(3, "little")
        for name in self.enabled:
            body += struct.pack(sp.CHANNEL_FORMAT[name], *(int(v) for v in self._raw[name][k]))
        return bytes(body)

    def flush(self, now_ns: int) -> None:
        """Write what is pending (a full terminal buffer keeps the rest for later)."""
        if self._out and now_ns >= self._last_write_ns:
            try:
                n = os.write(self.master, self._out)
            except (BlockingIOError, OSError):
                return
            del self._out[:n]

    def close(self) -> None:
        for fd in (self.master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class FakeShimmers:
    """Several fake Shimmers served by one thread, in real time."""

    def __init__(self, devices: list[FakeShimmer]) -> None:
        self.devices = devices
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fake shimmers", daemon=True)

    def start(self) -> FakeShimmers:
        self._thread.start()
        return self

    @property
    def finished(self) -> bool:
        """Every device has streamed its whole recording."""
        return all(d.finished and not d._out for d in self.devices)

    def _run(self) -> None:
        by_fd = {d.master: d for d in self.devices}
        while not self._stop.is_set():
            now = time.time_ns()
            dues = [t for d in self.devices if (t := d.next_due_ns()) is not None]
            pending = [d._last_write_ns for d in self.devices if d._out]
            wait_ns = min([*dues, *pending, now + 20_000_000]) - now
            ready, _, _ = select.select(list(by_fd), [], [], max(0.0, wait_ns * 1e-9))
            now = time.time_ns()
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except (BlockingIOError, OSError):
                    continue
                by_fd[fd].feed(data, now)
            for d in self.devices:
                d.produce(now)
                d.flush(now)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        for d in self.devices:
            d.close()


_AXES = {name: c.alignment for name, c in sp.DEFAULT_CALIBRATION.items()}
WIDE_RANGES = {**sp.DEFAULT_CALIBRATION,
               "wide_range": sp.Calibration((0.0, 0.0, 0.0), (408.0, 408.0, 408.0), _AXES["wide_range"]),
               "gyro": sp.Calibration((0.0, 0.0, 0.0), (16.4, 16.4, 16.4), _AXES["gyro"])}
"""A Shimmer3 set to the ranges gait needs, as Consensys configures it: wide-range accelerometer ±8 g
(408 LSB per m/s²), gyroscope ±2000 °/s (16.4 LSB per °/s)."""


def fakes_for_recording(series: dict[str, ImuSeries], *, offset_s: float = 0.0, drift_ppm: float = 0.0,
                        jitter_s: float = 0.0, loss: float = 0.0, seed: int = 0,
                        calibration: dict[str, sp.Calibration] | None = None) -> dict[str, FakeShimmer]:
    """One fake Shimmer per segment of a recording, as ``stream-sim`` makes them: device ``k``'s clock
    offset by ``offset_s + 0.1 k`` s and drifting ``+drift_ppm`` (even ``k``) or ``-drift_ppm`` (odd);
    ranges :data:`WIDE_RANGES` unless ``calibration`` says otherwise."""
    return {segment: FakeShimmer(s, f"Shimmer3-{segment}", offset_s=offset_s + 0.1 * k,
                                 drift_ppm=drift_ppm if k % 2 == 0 else -drift_ppm, jitter_s=jitter_s,
                                 loss=loss, seed=seed + k, calibration=calibration or WIDE_RANGES)
            for k, (segment, s) in enumerate(series.items())}
