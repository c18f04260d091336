"""Where ``imu_driver``'s frames come from: a UDP socket, a serial line, or the simulator.

Every link has ``receive(timeout_s) -> [(frame bytes, arrival ns, source), ...]`` (what came within
the timeout, possibly nothing) and ``close()``. ``source`` names where a frame came from, for the
driver to bind each sensor id to one source: a UDP sender's ``address:port``, ``serial DEVICE``, or
``simulator``. Arrival times are host (ROS) time: the kernel's receive
timestamp of a datagram (``SO_TIMESTAMPNS``, else ``SO_TIMESTAMP``; unaffected by a busy Python
process), else the time the bytes were read: :attr:`UdpLink.arrival_clock` says which, and the driver
names it on ``/diagnostics``. Sandboxed kernels (gVisor, some containers) accept the options and deliver
no stamp; then the link reads at once instead of gathering, so each stamp is late by the wake-up only.
Frames are in :mod:`gait_biofeedback.core.driver.protocol`'s format.
"""

from __future__ import annotations

import select
import socket
import struct
import sys
import time
from collections.abc import Iterator

from gait_biofeedback.core.driver.protocol import FrameReader

Received = list[tuple[bytes, int, str]]
_TIMESPEC = struct.Struct("@qq")
_LINUX = sys.platform.startswith("linux")
_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35 if _LINUX else None)
_SO_TIMESTAMP = getattr(socket, "SO_TIMESTAMP", 29 if _LINUX else None)
"""Linux's SO_TIMESTAMP(NS) (= SCM_TIMESTAMP(NS), asm-generic/socket.h; struct timespec / timeval), which
Python 3.11 does not name."""
_UNIT_NS = {_SO_TIMESTAMPNS: 1, _SO_TIMESTAMP: 1000}


class UdpLink:
    """Datagrams on ``address:port`` (port 0: any free port, see :attr:`port`), one frame each.

    After the first datagram it waits :attr:`GATHER_S` and takes all that came meanwhile: one wake-up
    per few datagrams instead of one each (8 sensors at 100 Hz: a third of the CPU); the arrival
    times are the kernel's, so the wait costs latency, not accuracy."""

    RECEIVE_BUFFER = 4 << 20
    GATHER_S = 0.005
    arrival_clock: str | None = None
    """``"kernel"`` once a datagram came with a receive timestamp, ``"read"`` once one came without
    (from then on: stamped when read, no gathering wait), ``None`` before the first datagram."""

    def __init__(self, address: str = "127.0.0.1", port: int = 5600) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self.RECEIVE_BUFFER)
            self._stamp_options = [o for o in (_SO_TIMESTAMPNS, _SO_TIMESTAMP) if o is not None]
            self._ask_kernel_for_stamps()
            self.sock.bind((address, port))
        except OSError as err:
            self.sock.close()
            raise OSError(f"imu_driver: cannot listen on udp {address}:{port} ({err.strerror}); is another "
                          "driver running? choose another port with the 'port' parameter") from err
        self.sock.setblocking(False)
        self.port = self.sock.getsockname()[1]
        self.description = f"udp {address}:{self.port}"

    def receive(self, timeout_s: float) -> Received:
        ready, _, _ = select.select([self.sock], [], [], timeout_s)
        out: Received = []
        if not ready:
            return out
        if self.arrival_clock != "read":
            time.sleep(self.GATHER_S)
        while True:
            try:
                data, ancillary, _, sender = self.sock.recvmsg(65536, 64)
            except BlockingIOError:
                return out
            read_ns = time.time_ns()
            arrival = None
            for level, kind, value in ancillary:
                if level == socket.SOL_SOCKET and kind in _UNIT_NS and len(value) >= _TIMESPEC.size:
                    sec, fraction = _TIMESPEC.unpack_from(value)
                    arrival = sec * 1_000_000_000 + fraction * _UNIT_NS[kind]
            if arrival is not None:
                self.arrival_clock = "kernel"
            elif self.arrival_clock != "kernel":
                self._ask_kernel_for_stamps()
            out.append((data, arrival if arrival is not None else read_ns, f"{sender[0]}:{sender[1]}"))

    def _ask_kernel_for_stamps(self) -> None:
        """Enable the next timestamp option this kernel accepts; none left: stamp when read."""
        while self._stamp_options:
            try:
                self.sock.setsockopt(socket.SOL_SOCKET, self._stamp_options.pop(0), 1)
                return
            except OSError:
                continue
        self.arrival_clock = "read"

    def close(self) -> None:
        self.sock.close()


class SerialLink:
    """Frames back to back on a serial line (``pyserial``): found again after noise or a cut. A
    device that goes away (a receiver unplugged) is opened again every :attr:`RETRY_S` until it is
    back; :attr:`problem` says what is wrong meanwhile, :attr:`reconnects` counts the returns."""

    RETRY_S = 1.0

    def __init__(self, device: str, baud: int = 921600) -> None:
        self.device, self.baud = device, baud
        self.reader = FrameReader()
        self.description = f"serial {device} at {baud} Bd"
        self.source = f"serial {device}"
        self.reconnects = 0
        self.problem: str | None = None
        self._retry_at = 0.0
        self.port = self._open()

    def _open(self):
        import serial

        try:
            return serial.Serial(self.device, self.baud, timeout=0)
        except (serial.SerialException, OSError) as err:
            raise OSError(f"imu_driver: cannot open serial device {self.device} ({err}); check the cable "
                          "and the 'device' parameter, and that you may read it (group dialout)") from err

    def receive(self, timeout_s: float) -> Received:
        if self.port is None:
            if time.monotonic() < self._retry_at:
                time.sleep(timeout_s)
                return []
            try:
                self.port = self._open()
            except OSError:
                self._retry_at = time.monotonic() + self.RETRY_S
                time.sleep(timeout_s)
                return []
            self.reconnects += 1
            self.problem = None
        try:
            ready, _, _ = select.select([self.port.fileno()], [], [], timeout_s)
            if not ready:
                return []
            data = self.port.read(self.port.in_waiting or 1)
        except (OSError, ValueError, TypeError) as err:  # pyserial's SerialException is an OSError
            self.port.close()
            self.port = None
            self._retry_at = time.monotonic() + self.RETRY_S
            self.problem = (f"{self.device} went away ({err}); opening it again every {self.RETRY_S:g} s: "
                            "check the receiver's cable")
            return []
        arrival = time.time_ns()
        return [(frame, arrival, self.source) for frame in self.reader.feed(data)]

    @property
    def bad_frames(self) -> int:
        return self.reader.bad_frames

    def close(self) -> None:
        if self.port is not None:
            self.port.close()


class PacedLink:
    """Frames of a :class:`~gait_biofeedback.sim.sensor_link.FrameSchedule` handed over at their send
    times (real time from the first :meth:`receive`): the simulator as live sensors, in process; every
    frame's source is :attr:`SOURCE`."""

    SOURCE = "simulator"

    def __init__(self, schedules: Iterator, description: str = "simulated sensors") -> None:
        self._schedules = schedules
        self._schedule = next(schedules)
        self._i = 0
        self._t0: int | None = None
        self.description = description

    def receive(self, timeout_s: float) -> Received:
        now = time.time_ns()
        if self._t0 is None:
            self._t0 = now
        if self._i >= len(self._schedule.send_ns):
            nxt = next(self._schedules, None)
            if nxt is None:
                time.sleep(timeout_s)
                return []
            self._schedule, self._i, self._t0 = nxt, 0, now
        due = self._t0 + int(self._schedule.send_ns[self._i])
        if due > now:
            time.sleep(min(timeout_s, (due - now) * 1e-9))
            now = time.time_ns()
        out: Received = []
        send_ns = self._schedule.send_ns
        while self._i < len(send_ns) and self._t0 + int(send_ns[self._i]) <= now:
            if not self._schedule.dropped[self._i]:
                out.append((self._schedule.frame(self._i), now, self.SOURCE))
            self._i += 1
        return out

    def close(self) -> None:
        pass
