"""x-io x-IMU3 sensors through x-io's own SDK (PyPI ``ximu3``), one connection per device.

Each device of the ``devices`` parameter is named by its connection (x-IMU3 User Manual v1.7,
section 7 "Communication interfaces" and 10 "Network announcement message")::

    tcp:HOST:PORT                the device's TCP port (7000 by default)
    udp:HOST:SEND:RECEIVE        the device's UDP send port (it sends to this computer's SEND, 8000 by
                                 default) and receive port (where it listens, 9000 by default)
    serial:PATH[:BAUD]           USB (a virtual serial port; the baud rate is ignored) or the serial
                                 header (115200 Bd by default)
    SERIAL_NUMBER                e.g. 65577B49: found on the network by its announcements (section 10,
                                 UDP port 10000, once a second) and connected by TCP at the address
                                 it announces, found again if that changes (DHCP)

The SDK decodes the device's data messages (User Manual section 8.2, ASCII or binary): the inertial
message (``I``: timestamp µs, gyroscope °/s, accelerometer g) and the magnetometer message (``M``:
timestamp µs, magnetometer in a.u., where 1 a.u. is the magnitude of the ambient field during
calibration, about 50 µT: section 3.3.3, note 2). Here they are converted to SI at the edge: rad/s,
m/s² (standard gravity), tesla (:data:`TESLA_PER_AU`). A magnetometer reading rides on the next
inertial sample (the magnetometer samples at 20 Hz, the inertial sensors at 400 Hz). The device sends
no sample counter, so sequence numbers come from its timestamps
(:class:`~gait_biofeedback.io.vendors.timebase.SequenceFromTime`).

A device that cannot be connected at start, or whose connection drops (silent for
:attr:`XImu3Link.SILENT_S`: SDK 1.9.1 does not notice a TCP peer gone), is connected again in the SDK's
threads, tried every :attr:`XImu3Link.RETRY_S`; :attr:`XImu3Link.problem` names it meanwhile and
:attr:`XImu3Link.reconnects` counts the returns. Its numbering goes on across the gap, so the samples
missed meanwhile are counted as lost.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections import deque
from dataclasses import dataclass

from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.io.vendors.timebase import SequenceFromTime

STANDARD_GRAVITY = 9.80665
"""m/s² per g (the x-IMU3's accelerometer unit)."""
TESLA_PER_AU = 50e-6
"""T per a.u. of the x-IMU3's calibrated magnetometer (User Manual v1.7, 3.3.3 note 2: about 50 µT)."""
MAX_QUEUED = 100_000
"""Messages kept between two :meth:`XImu3Link.receive` calls (the oldest dropped beyond, counted)."""


@dataclass(frozen=True)
class XImu3Device:
    """One device's connection: ``kind`` tcp, udp or serial and its fields (module docstring)."""

    spec: str
    kind: str
    host: str = ""
    port: int = 0
    receive_port: int = 0
    path: str = ""
    baud: int = 115200


def parse_device(spec: str) -> XImu3Device:
    """``tcp:HOST:PORT``, ``udp:HOST:SEND:RECEIVE``, ``serial:PATH[:BAUD]`` or a serial number → the
    device; ValueError with the expected forms otherwise."""
    if re.fullmatch(r"[0-9A-Fa-f]{4,}(-[0-9A-Fa-f]{4})*", spec):
        return XImu3Device(spec, "announced")
    kind, _, rest = spec.partition(":")
    parts = rest.split(":")
    try:
        if kind == "tcp" and len(parts) == 2 and parts[0]:
            return XImu3Device(spec, kind, parts[0], _port(parts[1]))
        if kind == "udp" and len(parts) == 3 and parts[0]:
            return XImu3Device(spec, kind, parts[0], _port(parts[1]), _port(parts[2]))
        if kind == "serial" and parts[0] and len(parts) in (1, 2):
            return XImu3Device(spec, kind, path=parts[0], baud=int(parts[1]) if len(parts) == 2 else 115200)
    except ValueError:
        pass
    raise ValueError(f"x-IMU3 device {spec!r}: expected tcp:HOST:PORT, udp:HOST:SEND:RECEIVE (the "
                     "device's send and receive ports), serial:PATH[:BAUD] or its serial number")


def _port(text: str) -> int:
    value = int(text)
    if not 0 < value < 65536:
        raise ValueError(text)
    return value


def inertial_sample(sensor_id: int, sequence: int, timestamp_us: int, gyr_dps: tuple[float, float, float],
                    acc_g: tuple[float, float, float],
                    mag_au: tuple[float, float, float] | None = None) -> DeviceSample:
    """An x-IMU3 inertial message (and the magnetometer reading riding on it) in SI units."""
    mag = None if mag_au is None else tuple(v * TESLA_PER_AU for v in mag_au)
    acc = tuple(v * STANDARD_GRAVITY for v in acc_g)
    gyr = tuple(math.radians(v) for v in gyr_dps)
    return DeviceSample(sensor_id, sequence, int(timestamp_us), acc, gyr, mag)


class _Device:
    """One device's SDK connection, the messages its callbacks queued and its numbering."""

    def __init__(self, device: XImu3Device, sensor_id: int, wake: threading.Event) -> None:
        self.device, self.sensor_id = device, sensor_id
        self.queue: deque[tuple[str, int, tuple[float, ...], int]] = deque(maxlen=MAX_QUEUED)
        self.numbering = SequenceFromTime()
        self.mag: tuple[float, float, float] | None = None
        self.connection = None
        self.receive_errors = 0
        self.dropped = 0
        self.serial_number = ""
        self.opening = False
        self.was_lost = False
        self.heard_at = time.monotonic()
        self._wake = wake

    def open(self, blocking: bool = True, announced: tuple[str, int] | None = None) -> None:
        """Connect (``blocking``: now, OSError if it fails; else in the SDK's thread, :attr:`opening`
        until it has tried); a device known by its serial number at its ``announced`` (IP, TCP port)."""
        import ximu3

        d = self.device
        if d.kind == "announced":
            if announced is None:
                raise OSError("not heard on this network yet (its announcements on UDP port 10000)")
            config = ximu3.TcpConnectionConfig(*announced)
        elif d.kind == "tcp":
            config = ximu3.TcpConnectionConfig(d.host, d.port)
        elif d.kind == "udp":  # the SDK names the ports from this computer's side
            config = ximu3.UdpConnectionConfig(d.host, d.receive_port, d.port)
        else:
            config = ximu3.SerialConnectionConfig(d.path, d.baud, False)
        connection = ximu3.Connection(config)
        connection.add_inertial_callback(self._inertial)
        connection.add_magnetometer_callback(self._magnetometer)
        connection.add_receive_error_callback(self._error)
        self.mag = None  # the numbering goes on: a gap in the device's time is counted as lost
        self.queue.clear()
        if not blocking:
            self.opening = True
            self.connection = connection
            connection.open_async(self._opened)
            return
        try:
            connection.open()
        except RuntimeError as err:
            raise OSError(str(err)) from err
        self.connection = connection
        self._opened(ximu3.RESULT_OK)

    def _opened(self, result: int) -> None:
        import ximu3

        self.opening = False
        if result == ximu3.RESULT_OK and self.connection is not None:
            self.connection.ping_async(self._pinged)

    def _pinged(self, response) -> None:
        if response is not None:
            self.serial_number = response.serial_number

    def _put(self, item: tuple[str, int, tuple[float, ...], int]) -> None:
        if len(self.queue) == self.queue.maxlen:
            self.dropped += 1
        self.queue.append(item)
        self.heard_at = time.monotonic()
        self._wake.set()

    def _inertial(self, m) -> None:  # the SDK's thread
        self._put(("I", m.timestamp, (m.gyroscope_x, m.gyroscope_y, m.gyroscope_z, m.accelerometer_x,
                                      m.accelerometer_y, m.accelerometer_z), time.time_ns()))

    def _magnetometer(self, m) -> None:
        self._put(("M", m.timestamp, (m.x, m.y, m.z), time.time_ns()))

    def _error(self, _error: int) -> None:
        self.receive_errors += 1

    def connected(self, silent_s: float) -> bool:
        """Whether the connection is open and the device sent something in the last ``silent_s`` (the
        SDK 1.9.1 still says connected after a TCP peer has gone)."""
        if self.connection is None or time.monotonic() - self.heard_at > silent_s:
            return False
        import ximu3

        return self.connection.get_status() == ximu3.CONNECTION_STATUS_CONNECTED

    def close(self) -> None:
        if self.connection is not None:
            self.connection.close()
            self.connection = None


class XImu3Link:
    """x-IMU3 devices → samples (module docstring): ``devices`` maps each device's connection spec
    to its sensor id. ``source`` of a device's samples is its spec."""

    RETRY_S = 2.0
    SILENT_S = 3.0
    """s without a message after which a device's connection is opened anew."""

    def __init__(self, devices: dict[str, int]) -> None:
        try:
            import ximu3  # noqa: F401
        except ImportError as err:
            raise OSError("imu_driver: backend 'ximu3' needs x-io's SDK: pip install ximu3") from err
        if not devices:
            raise OSError("imu_driver: backend 'ximu3' has no devices: give imu_driver's 'devices' as "
                          "'tcp:HOST:PORT=SEGMENT', ... (docs/connecting_sensors.md)")
        self._wake = threading.Event()
        self.devices = [_Device(parse_device(spec), sid, self._wake) for spec, sid in devices.items()]
        self.description = f"x-IMU3 ({len(self.devices)} devices: {', '.join(devices)})"
        self.reconnects = 0
        self.problem: str | None = None
        self._retry_at = 0.0
        self.announced: dict[str, tuple[str, int]] = {}  # serial number → (IP, TCP port)
        self._announcements = None
        if any(d.device.kind == "announced" for d in self.devices):
            self._listen_for_announcements()
        self._connect(first=True)

    def _listen_for_announcements(self) -> None:
        import ximu3

        wanted = {d.device.spec.upper() for d in self.devices}

        def heard(message) -> None:  # the SDK's thread
            serial = message.serial_number.upper()
            if serial in wanted:
                self.announced[serial] = (message.ip_address, message.tcp_port)

        try:
            self._announcements = ximu3.NetworkAnnouncement()
        except RuntimeError as err:
            raise OSError(f"imu_driver: cannot hear x-IMU3 announcements on UDP port 10000 ({err}); give "
                          "the devices as tcp:HOST:PORT instead of serial numbers") from err
        self._announcements.add_callback(heard)

    def _connect(self, first: bool = False) -> None:
        """Connect every device that is not (at start: now; later in the SDK's threads, so that one
        device out of reach does not hold up the others' samples)."""
        failed = []
        for d in self.devices:
            if d.opening:
                failed.append(f"{d.device.spec} (connecting)")
                continue
            if d.connected(self.SILENT_S):
                if d.was_lost:
                    d.was_lost = False
                    self.reconnects += 1
                continue
            if d.connection is not None:
                d.close()
                d.was_lost = True
            d.heard_at = time.monotonic()  # a new connection has SILENT_S to send
            try:
                d.open(blocking=first, announced=self.announced.get(d.device.spec.upper()))
            except OSError as err:
                d.was_lost = True
                failed.append(f"{d.device.spec} ({err})")
                continue
            if not first:
                failed.append(f"{d.device.spec} (connection lost, connecting again)")
        self.problem = (None if not failed else
                        f"x-IMU3 not connected: {'; '.join(failed)}; trying again every {self.RETRY_S:g} s: "
                        "check that it is on, on this network (or plugged in), and its entry in 'devices'")
        self._retry_at = time.monotonic() + self.RETRY_S

    def receive(self, timeout_s: float) -> list[tuple[list[DeviceSample], int, str]]:
        if time.monotonic() > self._retry_at:
            self._retry_at = time.monotonic() + self.RETRY_S
            if self.problem is not None or any(not d.connected(self.SILENT_S) for d in self.devices):
                self._connect()
        if not any(d.queue for d in self.devices):
            self._wake.wait(timeout_s)
        self._wake.clear()
        out: list[tuple[list[DeviceSample], int, str]] = []
        for d in self.devices:
            while d.queue:
                kind, timestamp, values, arrival = d.queue.popleft()
                if kind == "M":
                    d.mag = values
                    continue
                mag, d.mag = d.mag, None
                for sample, at in d.numbering.push(timestamp, (timestamp, values, mag, arrival),
                                                   lambda seq, item, sid=d.sensor_id: (inertial_sample(
                                                       sid, seq, item[0], item[1][:3], item[1][3:], item[2]),
                                                       item[3])):
                    out.append(([sample], at, d.device.spec))
        return out

    @property
    def bad_frames(self) -> int:
        """Messages the SDK could not decode, and messages dropped for want of room."""
        return sum(d.receive_errors + d.dropped for d in self.devices)

    def close(self) -> None:
        for d in self.devices:
            d.close()
        self._announcements = None
