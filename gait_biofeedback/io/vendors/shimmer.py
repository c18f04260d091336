"""``imu_driver``'s ``shimmer`` backend: Shimmer3 devices over their serial link, through ``pyshimmer``.

Each device is a serial port: a Bluetooth SPP link bound to ``/dev/rfcommN`` (``rfcomm bind``) or the
dock's USB serial port. At connect the link asks the device its firmware (LogAndStream), sets the
sampling rate (``device_rate_hz``: 32768 Hz over a whole number of ticks), enables the accelerometer
chosen by ``shimmer_accelerometer``, the gyroscope and the magnetometer, reads the device's own
calibration (:func:`~gait_biofeedback.io.vendors.shimmer_protocol.parse_calibration`: offset,
sensitivity, alignment per sensor; Shimmer's defaults where none is stored) and starts streaming.
Each data packet becomes a :class:`~gait_biofeedback.core.driver.protocol.DeviceSample` in SI units;
its 24-bit timestamp of the 32768 Hz clock is unwrapped to µs and, as packets carry no counter, the
sequence is the sample's tick count over the sampling period (a packet lost on the air leaves a gap
the driver counts).

A device that cannot be opened, does not answer within :attr:`ShimmerLink.CONNECT_TIMEOUT_S`, or goes
silent for :attr:`ShimmerLink.SILENT_S` while streaming is closed and connected again, waiting
:attr:`ShimmerLink.RETRY_S` doubled after each failure (at most :attr:`ShimmerLink.MAX_RETRY_S`);
:attr:`ShimmerLink.problem` says which and why meanwhile, :attr:`ShimmerLink.reconnects` counts the
returns. Its clock keeps running meanwhile, so the samples it did not send count as lost.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time

import numpy as np

from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.io.vendors import Received, drain
from gait_biofeedback.io.vendors import shimmer_protocol as sp

BAUD = 115200
_MAX_QUEUED = 100_000
"""Samples waiting for the driver at most (8 devices at 200 Hz for a minute); more are dropped, counted."""


def _import_pyshimmer():
    try:
        import pyshimmer
        import serial
    except ImportError as err:
        raise OSError("imu_driver: the shimmer backend needs pyshimmer "
                      "(pip install pyshimmer==1.0.0)") from err
    return pyshimmer, serial


class _Device:
    """One Shimmer: its connection (a thread while connecting), calibration and clock."""

    def __init__(self, link: ShimmerLink, port: str, sensor_id: int) -> None:
        self.link, self.port, self.sensor_id = link, port, sensor_id
        self.source = f"shimmer {port}"
        self.unwrap = sp.TickUnwrapper()
        self.shimmer = None
        self.state = "waiting"
        self.problem: str | None = None
        self.failures = 0
        self.connected_once = False
        self.retry_at = 0.0
        self.since = time.monotonic()
        self.last_sample = 0.0
        self.divider = sp.rate_divider(link.rate_hz)
        self._matrices: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._channels: dict[str, list] = {}
        self._lock = threading.RLock()
        self._attempt = 0

    def connect(self) -> None:
        with self._lock:
            self._attempt += 1
            self.state, self.since = "connecting", time.monotonic()
            threading.Thread(target=self._connect, args=(self._attempt,), name=f"shimmer {self.port}",
                             daemon=True).start()

    def _current(self, attempt: int) -> bool:
        """Whether ``attempt`` is the connect under way (the watchdog may have given up on it)."""
        return attempt == self._attempt and self.state == "connecting"

    def _connect(self, attempt: int) -> None:
        pyshimmer, serial = _import_pyshimmer()
        from pyshimmer.dev.channels import ESensorGroup

        try:
            port = serial.Serial(self.port, BAUD)  # pyshimmer reads without a timeout (it cancels reads)
        except (serial.SerialException, OSError) as err:
            with self._lock:
                if self._current(attempt):
                    self._failed(f"cannot open {self.port} ({err}): is the Shimmer on and its rfcomm bound?")
            return
        port.reset_input_buffer()  # nothing of an earlier connection
        shimmer = pyshimmer.ShimmerBluetooth(port)
        with self._lock:
            if not self._current(attempt):
                port.close()
                return
            self.shimmer = shimmer
        try:
            shimmer.initialize()
            shimmer.set_sampling_rate(self.link.rate_hz)
            wide = self.link.accelerometer == "wide_range"
            accel = ESensorGroup.ACCEL_WR if wide else ESensorGroup.ACCEL_LN
            shimmer.set_sensors([accel, ESensorGroup.GYRO, ESensorGroup.MAG])
            calibration = sp.parse_calibration(shimmer.get_all_calibration().binary)
            rate = shimmer.get_sampling_rate()
            self.divider = round(sp.CLOCK_HZ / rate)
            self._prepare(calibration)
            shimmer.add_stream_callback(self._on_packet)
            shimmer.start_streaming()
        except Exception as err:  # a device that answers nonsense, or the watchdog cancelled the reads
            with self._lock:
                if self._current(attempt):
                    self._failed(f"{self.port} did not answer as a Shimmer3 with LogAndStream firmware "
                                 f"({type(err).__name__}: {err})")
            return
        with self._lock:
            if not self._current(attempt):  # the watchdog gave up on it meanwhile: it must not stream
                with contextlib.suppress(Exception):
                    shimmer.shutdown()
                return
            if self.connected_once:
                self.link.reconnects += 1
            self.connected_once = True
            self.failures, self.problem = 0, None
            self.state, self.since, self.last_sample = "streaming", time.monotonic(), time.monotonic()

    def _prepare(self, calibration: dict[str, sp.Calibration]) -> None:
        from pyshimmer import EChannelType as C

        self._channels = {
            "wide_range": [C.ACCEL_LSM303DLHC_X, C.ACCEL_LSM303DLHC_Y, C.ACCEL_LSM303DLHC_Z],
            "low_noise": [C.ACCEL_LN_X, C.ACCEL_LN_Y, C.ACCEL_LN_Z],
            "gyro": [C.GYRO_MPU9150_X, C.GYRO_MPU9150_Y, C.GYRO_MPU9150_Z],
            "mag": [C.MAG_LSM303DLHC_X, C.MAG_LSM303DLHC_Y, C.MAG_LSM303DLHC_Z]}
        scale = {"gyro": np.pi / 180.0, "mag": sp.GAUSS_T}
        self._matrices = {name: (c.matrix() * scale.get(name, 1.0), np.asarray(c.offset, float))
                          for name, c in calibration.items()}
        self._timestamp = C.TIMESTAMP

    def _si(self, packet, name: str) -> tuple[float, float, float]:
        matrix, offset = self._matrices[name]
        v = matrix @ (np.array([packet[c] for c in self._channels[name]], float) - offset)
        return float(v[0]), float(v[1]), float(v[2])

    def _on_packet(self, packet) -> None:
        """pyshimmer's read thread: one data packet → a sample for the driver (a packet without the
        channels asked for is counted in ``bad_frames``: an exception here would end the thread)."""
        arrival = time.time_ns()
        try:
            ticks = self.unwrap(packet[self._timestamp])
            sample = DeviceSample(self.sensor_id, sp.sequence_of(ticks, self.divider), sp.ticks_to_us(ticks),
                                  self._si(packet, self.link.accelerometer), self._si(packet, "gyro"),
                                  self._si(packet, "mag"))
        except (KeyError, AttributeError, ValueError):
            self.link.bad_frames += 1
            return
        self.last_sample = time.monotonic()
        self.link.put(sample, arrival, self.source)

    def _failed(self, why: str) -> None:
        self.close()
        self.failures += 1
        wait = min(ShimmerLink.MAX_RETRY_S, ShimmerLink.RETRY_S * 2 ** (self.failures - 1))
        self.problem = f"{why}; trying again in {wait:g} s"
        self.state, self.retry_at = "waiting", time.monotonic() + wait

    def watch(self, now: float) -> None:
        """Connect when due; give up on a connect that hangs and on a stream that went silent."""
        with self._lock:
            self._watch(now)

    def _watch(self, now: float) -> None:
        if self.state == "waiting" and now >= self.retry_at:
            self.connect()
        elif self.state == "connecting" and now - self.since > ShimmerLink.CONNECT_TIMEOUT_S:
            self._failed(f"{self.port} did not answer within {ShimmerLink.CONNECT_TIMEOUT_S:g} s")
        elif self.state == "streaming" and now - self.last_sample > ShimmerLink.SILENT_S:
            self._failed(f"no data from {self.port} for {ShimmerLink.SILENT_S:g} s (out of range, or "
                         "its battery is flat)")

    def close(self, stop: bool = False) -> None:
        shimmer, self.shimmer = self.shimmer, None
        self.state = "closed" if stop else self.state
        if shimmer is None:
            return
        if stop:  # stop the device streaming, without waiting long for one that does not answer
            stopper = threading.Thread(target=shimmer.stop_streaming, daemon=True)
            stopper.start()
            stopper.join(0.5)
        with contextlib.suppress(Exception):  # the port went away already
            shimmer.shutdown()


class ShimmerLink:
    """Shimmer3 devices (``port`` → sensor id) as one link of ``imu_driver`` (module docstring)."""

    CONNECT_TIMEOUT_S = 10.0
    SILENT_S = 2.0
    RETRY_S = 1.0
    MAX_RETRY_S = 30.0

    def __init__(self, devices: dict[str, int], rate_hz: float = 100.0,
                 accelerometer: str = "wide_range") -> None:
        if not devices:
            raise ValueError("imu_driver: the shimmer backend needs the 'devices' parameter "
                             "('/dev/rfcomm0=left_shank', ...) or --driver shimmer:PORT=SEGMENT,...")
        _import_pyshimmer()
        self.rate_hz, self.accelerometer = rate_hz, accelerometer
        self.reconnects = 0
        self.overflow = 0
        self.bad_frames = 0
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self.devices = [_Device(self, port, sid) for port, sid in devices.items()]
        self.description = (f"shimmer: {len(self.devices)} device(s) at "
                            f"{sp.CLOCK_HZ / sp.rate_divider(rate_hz):.2f} Hz")
        for d in self.devices:
            d.connect()

    def put(self, sample: DeviceSample, arrival_ns: int, source: str) -> None:
        if self._queue.qsize() >= _MAX_QUEUED:
            self.overflow += 1
            return
        self._queue.put(([sample], arrival_ns, source))

    def receive(self, timeout_s: float) -> Received:
        now = time.monotonic()
        for d in self.devices:
            d.watch(now)
        return drain(self._queue, timeout_s)

    @property
    def problem(self) -> str | None:
        """What is wrong with the devices not streaming, or None."""
        problems = [d.problem for d in self.devices if d.problem and d.state != "streaming"]
        if self.overflow:
            problems.append(f"{self.overflow} samples dropped: the driver fell {_MAX_QUEUED} samples behind")
        return "; ".join(problems) or None

    def close(self) -> None:
        for d in self.devices:
            d.close(stop=True)
