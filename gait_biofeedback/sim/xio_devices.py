"""Fake x-io devices for tests, demos and the benchmark, written from x-io's published documents:
an x-IMU3 that a host connects to over TCP, and NGIMUs sending OSC bundles over UDP.

* x-IMU3 (User Manual v1.7, sections 8.1 and 8.2): data messages in binary (first byte 0x80 + the
  ASCII id, timestamp u64 µs, float32 arguments, little-endian, SLIP-like byte stuffing with 0x0A as
  the end byte, 8.2.1) or ASCII (``I,timestamp,v1,...\\r\\n``, four decimals); commands are one JSON
  object a line, and the ping command gets the ping response (8.1.8-8.1.9). The manual names its
  keys ``deviceName`` and ``serialNumber``; x-io's SDK 1.9 reads ``name`` and ``sn`` (the keys of the
  network announcement, section 10), so the response carries both.
* NGIMU (User Manual v1.6, "Sensors message"; OSC 1.0 specification for the encoding): one
  ``/sensors`` message (gyroscope °/s, accelerometer g, magnetometer µT, barometer hPa, ten float32)
  in a bundle whose time tag is the sample's device time (NTP format), sent from the device's own
  address and port.

:func:`play` sends a :class:`~gait_biofeedback.sim.sensor_link.FrameSchedule` (its timing, loss,
jitter and device clocks) through them in real time: ``stream-sim --as x-imu3|ngimu`` and
``benchmarks/driver.py --backend ximu3|ngimu``.
"""

from __future__ import annotations

import json
import math
import socket
import struct
import threading
from collections.abc import Callable, Mapping

from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.sim.sensor_link import FrameSchedule, SendReport, play_frames

STANDARD_GRAVITY = 9.80665
TESLA_PER_AU = 50e-6
NTP_TO_UNIX_S = 2_208_988_800
_END, _ESC, _ESC_END, _ESC_ESC = b"\x0a", b"\xdb", b"\xdb\xdc", b"\xdb\xdd"


def ximu3_binary(message_id: str, timestamp_us: int, values: tuple[float, ...]) -> bytes:
    """An x-IMU3 binary data message (User Manual 8.2: id byte, timestamp, float32s, stuffed, 0x0A)."""
    body = bytes([0x80 + ord(message_id)]) + struct.pack(f"<Q{len(values)}f", timestamp_us, *values)
    return body.replace(_ESC, _ESC_ESC).replace(_END, _ESC_END) + _END


def ximu3_ascii(message_id: str, timestamp_us: int, values: tuple[float, ...]) -> bytes:
    """An x-IMU3 ASCII data message (User Manual 8.2: comma-separated, four decimals, CR LF)."""
    return (",".join([message_id, str(timestamp_us), *(f"{v:.4f}" for v in values)]) + "\r\n").encode()


def ximu3_messages(sample: DeviceSample, ascii_mode: bool = False) -> bytes:
    """One sample (SI units) as the x-IMU3 sends it: a magnetometer message (if it has one) and an
    inertial message with the same timestamp."""
    encode = ximu3_ascii if ascii_mode else ximu3_binary
    out = b""
    if sample.mag is not None:
        out += encode("M", sample.device_time_us, tuple(v / TESLA_PER_AU for v in sample.mag))
    gyr = tuple(math.degrees(v) for v in sample.gyr)
    acc = tuple(v / STANDARD_GRAVITY for v in sample.acc)
    return out + encode("I", sample.device_time_us, gyr + acc)


def _osc_string(text: str) -> bytes:
    raw = text.encode() + b"\0"
    return raw + b"\0" * (-len(raw) % 4)


def ngimu_sensors_bundle(device_us: int, gyr_dps, acc_g, mag_ut, barometer_hpa: float = 1013.25) -> bytes:
    """An OSC bundle (OSC 1.0: ``#bundle``, 64-bit NTP time tag, size-prefixed elements) holding one
    NGIMU ``/sensors`` message taken at ``device_us`` (µs since the NTP epoch)."""
    args = (*gyr_dps, *acc_g, *mag_ut, barometer_hpa)
    message = (_osc_string("/sensors") + _osc_string("," + "f" * len(args))
               + struct.pack(f">{len(args)}f", *args))
    seconds, micros = divmod(int(device_us), 1_000_000)
    fraction = (micros << 32) // 1_000_000
    time_tag = struct.pack(">II", seconds, fraction)
    return _osc_string("#bundle") + time_tag + struct.pack(">I", len(message)) + message


def ngimu_datagram(sample: DeviceSample) -> bytes:
    """One sample (SI units) as an NGIMU sends it: its ``/sensors`` bundle (a sample without
    magnetometer with 0 µT on every axis, which the backend reads as no reading)."""
    mag = (0.0, 0.0, 0.0) if sample.mag is None else tuple(v * 1e6 for v in sample.mag)
    return ngimu_sensors_bundle(sample.device_time_us, tuple(math.degrees(v) for v in sample.gyr),
                                tuple(v / STANDARD_GRAVITY for v in sample.acc), mag)


class FakeXImu3:
    """One x-IMU3 listening on TCP ``127.0.0.1:port`` (0: any free port, see :attr:`port`): it takes
    one host at a time, answers the ping command, and :meth:`send` writes data messages to it."""

    def __init__(self, serial_number: str, port: int = 0, ascii_mode: bool = False) -> None:
        self.serial_number, self.ascii_mode = serial_number, ascii_mode
        self.server = socket.create_server(("127.0.0.1", port))
        self.port = self.server.getsockname()[1]
        self.spec = f"tcp:127.0.0.1:{self.port}"
        self.commands: list[str] = []
        self._client: socket.socket | None = None
        self._connected = threading.Event()
        self._lock = threading.Lock()
        self._closed = False
        threading.Thread(target=self._serve, name=f"fake x-IMU3 {serial_number}", daemon=True).start()

    def _serve(self) -> None:
        while not self._closed:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            with self._lock:
                self._client = client
            self._connected.set()
            pending = b""
            while not self._closed:
                try:
                    data = client.recv(4096)
                except OSError:
                    break
                if not data:
                    break
                pending = (pending + data)[-65536:]
                while b"\n" in pending:
                    line, pending = pending.split(b"\n", 1)
                    self._command(line.strip())
            with self._lock:
                self._client = None
            self._connected.clear()
            client.close()

    def _command(self, line: bytes) -> None:
        try:
            command = json.loads(line)
        except ValueError:
            return
        if not isinstance(command, dict):
            return
        self.commands.extend(command)
        if "ping" in command:
            response = {"interface": "TCP", "deviceName": "x-IMU3", "serialNumber": self.serial_number,
                        "name": "x-IMU3", "sn": self.serial_number}
            self.send(json.dumps({"ping": response}, separators=(",", ":")).encode() + b"\n")

    def announce(self, port: int = 10000) -> None:
        """One network announcement (User Manual v1.7, section 10: a JSON object on UDP port 10000), to
        127.0.0.1 from a new source port each time."""
        message = {"sync": 0, "name": "x-IMU3", "sn": self.serial_number, "ip": "127.0.0.1",
                   "port": self.port, "send": 8000, "receive": 9000, "rssi": 100, "battery": 100, "status": 2}
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.sendto(json.dumps(message, separators=(",", ":")).encode() + b"\n", ("127.0.0.1", port))

    def drop_host(self) -> None:
        """Cut the host's connection (as Wi-Fi out of range does); the next host is accepted."""
        with self._lock:
            if self._client is not None:
                self._client.shutdown(socket.SHUT_RDWR)

    def wait_connected(self, timeout_s: float) -> bool:
        return self._connected.wait(timeout_s)

    def send(self, data: bytes) -> bool:
        """Write ``data`` to the connected host; False if none is connected."""
        with self._lock:
            client = self._client
            if client is None:
                return False
            try:
                client.sendall(data)
            except OSError:
                return False
        return True

    def send_sample(self, sample: DeviceSample) -> bool:
        return self.send(ximu3_messages(sample, self.ascii_mode))

    def close(self) -> None:
        self._closed = True
        self.server.close()
        with self._lock:
            if self._client is not None:
                self._client.close()


class FakeXImu3Udp(FakeXImu3):
    """One x-IMU3 on UDP (User Manual v1.7, section 7.3): it listens for commands on its receive port
    of 127.0.0.1 and sends data messages and responses to the host's port (its send port), each
    message a datagram; the host counts as connected once it has sent a command."""

    def __init__(self, serial_number: str, ascii_mode: bool = False) -> None:
        self.serial_number, self.ascii_mode = serial_number, ascii_mode
        self.server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.server.bind(("127.0.0.1", 0))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:  # a free port for the host
            probe.bind(("127.0.0.1", 0))
            self.send_port = probe.getsockname()[1]
        self.port = self.server.getsockname()[1]
        self.spec = f"udp:127.0.0.1:{self.send_port}:{self.port}"
        self.commands = []
        self._connected = threading.Event()
        self._lock = threading.Lock()
        self._closed = False
        self._client = None
        threading.Thread(target=self._serve_udp, name=f"fake x-IMU3 {serial_number}", daemon=True).start()

    def _serve_udp(self) -> None:
        while not self._closed:
            try:
                data = self.server.recv(65536)
            except OSError:
                return
            with self._lock:
                self._client = ("127.0.0.1", self.send_port)
            self._connected.set()
            for line in data.split(b"\n"):
                if line.strip():
                    self._command(line.strip())

    def drop_host(self) -> None:
        with self._lock:
            self._client = None
        self._connected.clear()

    def send(self, data: bytes) -> bool:
        with self._lock:
            client = self._client
        if client is None:
            return False
        for message in data.split(_END)[:-1]:  # one datagram per message (0x0A ends each, 8.2)
            self.server.sendto(message + _END, client)
        return True

    def close(self) -> None:
        self._closed = True
        self.server.close()


class FakeNgimus:
    """NGIMUs, one UDP socket each on ``127.0.0.1`` (its own source port: :attr:`ports`, from
    ``first_port`` on if not 0), sending to ``host:port``."""

    def __init__(self, sensor_ids: list[int], host: str, port: int, first_port: int = 0) -> None:
        self.target = (host, port)
        self.sockets = {}
        for k, sid in enumerate(sensor_ids):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.bind(("127.0.0.1", first_port + k if first_port else 0))
            self.sockets[sid] = sock
        self.ports = {sid: s.getsockname()[1] for sid, s in self.sockets.items()}

    def send_sample(self, sample: DeviceSample) -> bool:
        self.sockets[sample.sensor_id].sendto(ngimu_datagram(sample), self.target)
        return True

    def close(self) -> None:
        for sock in self.sockets.values():
            sock.close()


def play(schedule: FrameSchedule, send: Callable[[DeviceSample], bool], lead_s: float = 0.2,
         stop: Callable[[], bool] | None = None) -> SendReport:
    """Send ``schedule``'s samples through ``send`` in real time, frame by frame at its send times
    (:func:`~gait_biofeedback.sim.sensor_link.play_frames`; dropped frames not sent)."""

    def send_frame(i: int) -> None:
        for sample in schedule.frame_samples(i):
            send(sample)

    return play_frames(schedule, send_frame, lead_s, stop=stop)


def ximu3_devices(sensor_ids: list[int], ascii_mode: bool = False) -> dict[int, FakeXImu3]:
    """One fake x-IMU3 per sensor id, serial numbers ``XIO0000k``."""
    return {sid: FakeXImu3(f"XIO{k:05d}", ascii_mode=ascii_mode) for k, sid in enumerate(sensor_ids)}


def device_entries(specs: Mapping[int, str], ids: Mapping[str, int]) -> list[str]:
    """``devices`` parameter entries ``DEVICE_ID=SEGMENT`` for fake devices named ``specs[sensor id]``."""
    segment_of = {sid: seg for seg, sid in ids.items()}
    return [f"{spec}={segment_of[sid]}" for sid, spec in specs.items()]
