"""``imu_driver``'s ``dot`` backend: Movella DOT sensors over Bluetooth LE, through ``bleak``.

One asyncio loop (a thread of its own) holds a connection per sensor (``devices``: BLE address →
segment). Start (:mod:`~gait_biofeedback.io.vendors.dot_payload`, the BLE Services Specification):

1. connect every sensor and set its output rate (``device_rate_hz``);
2. with several sensors (those that answered within :attr:`DotLink.START_WAIT_S`), *sync*: StartSync
   to each (the first address is the root), disconnect, wait :attr:`DotLink.SYNC_WAIT_S` (the sensors
   sync among themselves, §5.3.5), connect again and read each one's acknowledge; a sensor whose sync
   failed is named in :attr:`DotLink.problem` and streams on its own clock (the driver maps each
   sensor's clock to ROS time anyway);
3. on each: enable notifications on the medium payload, then start measurement in *Rate quantities
   (with mag)* (the order the specification asks for).

Each notification becomes a :class:`~gait_biofeedback.core.driver.protocol.DeviceSample` (SI units;
the µs timestamp unwrapped; the sequence is the timestamp over the nominal period, so samples lost on
the air or while disconnected are counted). A dropped connection (bleak's disconnected callback)
is connected again after :attr:`DotLink.RETRY_S`, doubled after each failure up to
:attr:`DotLink.MAX_RETRY_S`, notifications enabled and measurement started again; the sensor's clock
ran on meanwhile, so the time away is a gap the driver counts as lost samples. Notifications that do
not decode are counted (:attr:`DotLink.bad_frames`), never raised.
"""

from __future__ import annotations

import asyncio
import contextlib
import queue
import threading
import time
from collections.abc import Callable

from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.io.vendors import Received, drain
from gait_biofeedback.io.vendors import dot_payload as dp

_MAX_QUEUED = 100_000
_DEG = 3.141592653589793 / 180.0


def bleak_client(address: str, disconnected_callback: Callable) -> object:
    """A ``bleak.BleakClient`` for ``address`` (imported here: the package imports without bleak)."""
    try:
        from bleak import BleakClient
    except ImportError as err:
        raise OSError("imu_driver: the dot backend needs bleak (pip install bleak==3.1.0)") from err
    return BleakClient(address, disconnected_callback, timeout=DotLink.CONNECT_TIMEOUT_S)


def _why(err: Exception) -> str:
    """What a failed connect means, for the dashboard."""
    if isinstance(err, (FileNotFoundError, ConnectionRefusedError)):  # no system D-Bus socket
        return (f"no Bluetooth service on this computer ({type(err).__name__}: {err}): start bluetoothd "
                "and check the adapter with 'bluetoothctl show'")
    return f"{type(err).__name__}: {err}: is it on, charged and near?"


class _Sensor:
    """One DOT: its client, clock and counts."""

    def __init__(self, address: str, sensor_id: int, period_us: float) -> None:
        self.address, self.sensor_id, self.period_us = address, sensor_id, period_us
        self.source = f"dot {address}"
        self.unwrap = dp.MicrosecondUnwrapper()
        self.client = None
        self.connected = asyncio.Event()
        self.lost_link = asyncio.Event()
        self.problem: str | None = None
        self.sync = "not synced"
        self.failures = 0
        self.streams = 0


class DotLink:
    """Movella DOT sensors (BLE address → sensor id) as one link of ``imu_driver`` (module docstring).
    ``client_factory(address, disconnected_callback)`` makes the BLE clients (tests pass fakes)."""

    CONNECT_TIMEOUT_S = 10.0
    START_WAIT_S = 30.0
    """s the start waits for every sensor to answer; those that answer later stream unsynced."""
    SYNC_WAIT_S = 14.0
    RETRY_S = 1.0
    MAX_RETRY_S = 30.0

    def __init__(self, devices: dict[str, int], rate_hz: float = 60.0,
                 client_factory: Callable | None = None, sync: bool = True) -> None:
        if not devices:
            raise ValueError("imu_driver: the dot backend needs the 'devices' parameter "
                             "('D4:22:CD:00:12:34=left_foot', ...) or --driver dot:ADDRESS=SEGMENT,...")
        if rate_hz not in dp.STREAM_RATES_HZ:
            rates = ", ".join(map(str, dp.STREAM_RATES_HZ))
            raise ValueError(f"imu_driver: a Movella DOT streams at {rates} "
                             f"Hz; set imu_driver's 'device_rate_hz' to one of them in the --params file, "
                             f"e.g. 60 (not {rate_hz:g})")
        if client_factory is None:
            client_factory = bleak_client
        self.rate_hz = int(rate_hz)
        self._factory = client_factory
        self._sync = sync and len(devices) > 1
        self.sensors = [_Sensor(a, sid, 1e6 / self.rate_hz) for a, sid in devices.items()]
        self.reconnects = 0
        self.bad_frames = 0
        self.overflow = 0
        self.description = f"dot: {len(self.sensors)} Movella DOT(s) at {self.rate_hz} Hz over Bluetooth LE"
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._loop = asyncio.new_event_loop()
        self._stopping = False
        self._failure: str | None = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dot", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._main = self._loop.create_task(self._session())
        self._ready.set()
        try:
            self._loop.run_until_complete(self._main)
        except asyncio.CancelledError:
            pass
        except Exception as err:  # a bug here must not pass silently: the driver shows it
            self._failure = f"the dot backend stopped ({type(err).__name__}: {err})"
        finally:  # the connects still trying, and anything else begun on the loop, end with it
            pending = asyncio.all_tasks(self._loop)
            for task in pending:
                task.cancel()
            self._loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            self._loop.close()

    async def _session(self) -> None:
        connecting = {s.address: asyncio.create_task(self._connect(s, set_rate=True)) for s in self.sensors}
        await asyncio.wait(connecting.values(), timeout=self.START_WAIT_S)
        ready = [s for s in self.sensors if connecting[s.address].done()]
        if self._sync and len(ready) > 1:
            await self._synchronize(ready)
        await asyncio.gather(*(self._keep_streaming(s, connecting[s.address]) for s in self.sensors))

    async def _connect(self, s: _Sensor, set_rate: bool = False) -> None:
        """Connect ``s`` (again and again, with back-off, until it answers)."""
        while not self._stopping:
            s.lost_link.clear()
            try:
                s.client = self._factory(s.address, lambda _client, s=s: self._on_disconnect(s))
                await asyncio.wait_for(s.client.connect(), self.CONNECT_TIMEOUT_S)
                if set_rate:
                    await s.client.write_gatt_char(dp.DEVICE_CONTROL, dp.output_rate_control(self.rate_hz),
                                                   response=True)
            except Exception as err:  # bleak's errors, a timeout, a sensor that went away meanwhile
                s.failures += 1
                wait = min(self.MAX_RETRY_S, self.RETRY_S * 2 ** (s.failures - 1))
                s.problem = f"cannot connect to {s.address} ({_why(err)}); trying again in {wait:g} s"
                await self._disconnect(s)
                await asyncio.sleep(wait)
                continue
            s.failures = 0
            s.connected.set()
            return

    async def _synchronize(self, sensors: list[_Sensor]) -> None:
        """StartSync to ``sensors``, then wait while they sync and read each result (§5.3.5)."""
        root = sensors[0].address
        for s in sensors:
            try:
                await s.client.write_gatt_char(dp.MESSAGE_CONTROL, dp.start_sync(root), response=True)
            except Exception as err:
                s.sync = f"StartSync not written ({type(err).__name__}: {err})"
            await self._disconnect(s)
        await asyncio.sleep(self.SYNC_WAIT_S)
        back = [asyncio.create_task(self._connect(s)) for s in sensors]
        await asyncio.wait(back, timeout=self.START_WAIT_S)
        for task in back:  # one not back by then is connected again by its stream's loop
            task.cancel()
        for s in sensors:
            try:
                s.sync = dp.sync_result(bytes(await s.client.read_gatt_char(dp.MESSAGE_ACK)))
            except Exception as err:
                s.sync = f"no acknowledge ({type(err).__name__}: {err})"

    async def _keep_streaming(self, s: _Sensor, connecting: asyncio.Task) -> None:
        """Stream from ``s`` once connected; after a dropped link, connect and start it again."""
        await connecting
        while not self._stopping:
            try:
                await s.client.start_notify(dp.MEDIUM_PAYLOAD,
                                            lambda _c, data, s=s: self._on_payload(s, data))
                await s.client.write_gatt_char(dp.MEASUREMENT_CONTROL, dp.measurement_control(True),
                                               response=True)
            except Exception as err:
                s.problem = f"{s.address} did not start measuring ({type(err).__name__}: {err})"
                await self._disconnect(s)
                await asyncio.sleep(self.RETRY_S)
                await self._connect(s)
                continue
            s.problem = None
            s.streams += 1
            if s.streams > 1:
                self.reconnects += 1
            await s.lost_link.wait()
            if self._stopping:
                return
            s.problem = f"{s.address} disconnected (out of range?): connecting again"
            await self._disconnect(s)
            await asyncio.sleep(self.RETRY_S)
            await self._connect(s)

    def _on_disconnect(self, s: _Sensor) -> None:
        s.connected.clear()
        s.lost_link.set()

    async def _disconnect(self, s: _Sensor) -> None:
        client, s.client = s.client, None
        s.connected.clear()
        if client is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(client.disconnect(), 5.0)

    def _on_payload(self, s: _Sensor, data: bytearray) -> None:
        arrival = time.time_ns()
        try:
            stamp, acc, gyr, mag = dp.decode_rate_quantities(bytes(data))
        except dp.PayloadError:
            self.bad_frames += 1
            return
        us = s.unwrap(stamp)
        sample = DeviceSample(s.sensor_id, round(us / s.period_us) % (1 << 32), us, acc,
                              (gyr[0] * _DEG, gyr[1] * _DEG, gyr[2] * _DEG),
                              (mag[0] * dp.MAG_UNIT_T, mag[1] * dp.MAG_UNIT_T, mag[2] * dp.MAG_UNIT_T))
        if self._queue.qsize() >= _MAX_QUEUED:
            self.overflow += 1
            return
        self._queue.put(([sample], arrival, s.source))

    def receive(self, timeout_s: float) -> Received:
        return drain(self._queue, timeout_s)

    @property
    def problem(self) -> str | None:
        """Sensors not streaming and why, and failed syncs; None when all is well."""
        parts = [self._failure] if self._failure else []
        parts += [s.problem for s in self.sensors if s.problem]
        if self._sync:
            parts += [f"{s.address} not synced ({s.sync})" for s in self.sensors
                      if s.sync not in ("success", "not synced")]
        if self.overflow:
            parts.append(f"{self.overflow} samples dropped: the driver fell {_MAX_QUEUED} samples behind")
        return "; ".join(parts) or None

    def close(self) -> None:
        """Stop measuring and disconnect every sensor; end the loop."""
        if not self._thread.is_alive():
            return
        self._ready.wait(1.0)

        async def stop() -> None:
            self._stopping = True
            for s in self.sensors:
                if s.client is not None:
                    with contextlib.suppress(Exception):
                        await asyncio.wait_for(s.client.write_gatt_char(
                            dp.MEASUREMENT_CONTROL, dp.measurement_control(False), response=True), 2.0)
                await self._disconnect(s)
            self._main.cancel()  # ends the loop: last

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(stop(), self._loop).result(10.0)
        self._thread.join(5.0)
