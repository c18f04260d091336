"""The dot backend without a radio: the Movella DOT payloads against hand-made bytes (and the
specification's own examples), and the connection logic against fake bleak clients (connect, rate,
sync, notifications, a dropped link and its recovery, a refused connect, a failed sync)."""

from __future__ import annotations

import asyncio
import math
import struct
import time

import numpy as np
import pytest

from gait_biofeedback.io.vendors import dot_payload as dp

pytestmark = pytest.mark.timeout(60)


def test_rate_quantities_payload_decodes_to_its_fields_and_bad_ones_are_refused():
    data = struct.pack("<I6f3h", 0xFFFFFFF0, 0.5, -9.75, 1.25, 90.0, -45.0, 0.0, 4096, -2048, 1) + b"\0" * 6
    stamp, acc, gyr, mag = dp.decode_rate_quantities(data)
    assert stamp == 0xFFFFFFF0 and acc == (0.5, -9.75, 1.25) and gyr == (90.0, -45.0, 0.0)
    assert mag == (1.0, -0.5, 1 / 4096)
    assert dp.encode_rate_quantities(stamp, acc, gyr, mag) == data
    with pytest.raises(dp.PayloadError, match="33 bytes"):
        dp.decode_rate_quantities(data[:33])
    with pytest.raises(dp.PayloadError, match="finite"):
        dp.decode_rate_quantities(struct.pack("<I6f3h", 0, math.nan, 0, 0, 0, 0, 0, 0, 0, 0))
    unwrap = dp.MicrosecondUnwrapper()
    assert [unwrap(s) for s in (0xFFFFFFF0, 0x10, 0x20)] == [0, 0x20, 0x30]  # across the 2³² µs wrap


def test_messages_are_the_specifications_examples():
    # BLE Services Specification §5.3.1: StartSync with root D4:22:CD:AA:BB:CC, and its acknowledge
    assert dp.start_sync("D4:22:CD:AA:BB:CC") == bytes.fromhex("020701CCBBAACD22D402")
    assert dp.sync_result(bytes.fromhex("02020300F9")) == "success"
    assert dp.sync_result(bytes.fromhex("02020307F2")) == "clock skew too large"
    assert dp.sync_result(bytes.fromhex("02020300F8")).startswith("no sync acknowledge")  # bad checksum
    control = dp.output_rate_control(60)
    assert len(control) == 32 and control[0] == 0x10 and control[24:26] == b"\x3c\x00"
    assert not any(control[1:24]) and not any(control[26:])
    assert dp.measurement_control(True) == b"\x01\x01\x14"
    assert dp.measurement_control(False) == b"\x01\x00\x14"
    with pytest.raises(ValueError, match="not 100"):
        dp.output_rate_control(100)


class FakeDot:
    """One sensor's side: its clock (µs, from ``clock_us``) runs from creation; measuring, it notifies
    sample k = its clock over the period, whether or not anyone hears it."""

    def __init__(self, address, rate_hz=60, clock_us=0xFFFFFFFF - 1_000_000, sync_code=0x00):
        self.address, self.period_us = address, 1e6 / rate_hz
        self.clock_us, self.t0 = clock_us, time.monotonic()
        self.sync_code, self.refuse = sync_code, 0
        self.gone_after_sync = False  # switched off once told to sync: never answers again
        self.log: list[tuple] = []
        self.client = None
        self.notified: list[int] = []  # sample numbers heard
        self.measuring = False
        self.rate = None
        self.k = None

    def sample(self, k):
        t = k * self.period_us * 1e-6
        return (np.array([math.sin(t), 0.5, 9.81]), np.array([30 * math.cos(t), 0.0, -10.0]),
                np.array([0.4, -0.1, 0.8]))

    def tick(self):
        """Notify the samples due by now (from the loop)."""
        now_k = int((time.monotonic() - self.t0) * 1e6 / self.period_us)
        if self.k is None:
            self.k = now_k
        while self.k < now_k:
            k, self.k = self.k, self.k + 1
            c = self.client
            if self.measuring and c is not None and c.is_connected and c.notify is not None:
                acc, gyr, mag = self.sample(k)
                c.notify(None, bytearray(dp.encode_rate_quantities(
                    round(self.clock_us + k * self.period_us), acc, gyr, mag)))
                self.notified.append(k)


class FakeClient:
    """What the backend sees of bleak's BleakClient for one FakeDot."""

    def __init__(self, dot, disconnected_callback):
        self.dot, self.on_disconnect = dot, disconnected_callback
        self.is_connected, self.notify = False, None

    async def connect(self):
        self.dot.log.append(("connect",))
        if self.dot.refuse:
            self.dot.refuse -= 1
            raise OSError("device not found")
        self.dot.client, self.is_connected = self, True

    async def disconnect(self):
        self.dot.log.append(("disconnect",))
        self.is_connected = False

    async def write_gatt_char(self, uuid, data, response=None):
        self.dot.log.append(("write", uuid, bytes(data)))
        if uuid == dp.MESSAGE_CONTROL and self.dot.gone_after_sync:
            self.dot.refuse = 1 << 30
        if uuid == dp.MEASUREMENT_CONTROL:
            self.dot.measuring = data[1] == 1
        elif uuid == dp.DEVICE_CONTROL and data[0] & 0x10:
            self.dot.rate = struct.unpack_from("<H", data, 24)[0]

    async def read_gatt_char(self, uuid):
        self.dot.log.append(("read", uuid))
        return bytearray(dp.message(0x02, bytes([0x03, self.dot.sync_code, 0x01])))

    async def start_notify(self, uuid, callback):
        self.dot.log.append(("notify", uuid))
        self.notify = callback

    def drop(self):
        """The radio link is lost (bleak calls the disconnected callback)."""
        self.is_connected = False
        self.on_disconnect(self)


def _link(dots, monkeypatch, **kwargs):
    from gait_biofeedback.io.vendors.dot import DotLink

    monkeypatch.setattr(DotLink, "SYNC_WAIT_S", 0.1)
    monkeypatch.setattr(DotLink, "RETRY_S", 0.1)
    by_address = {d.address: d for d in dots}
    link = DotLink({d.address: k for k, d in enumerate(dots)}, 60,
                   lambda a, cb: FakeClient(by_address[a], cb), **kwargs)

    async def ticking():
        while True:
            for d in dots:
                d.tick()
            await asyncio.sleep(0.005)

    link._loop.call_soon_threadsafe(lambda: link._loop.create_task(ticking()))
    return link


def _collect(link, seconds, until=None):
    """What ``link`` gives for ``seconds``, or until ``until()`` is true (a loaded machine is slower:
    the test waits for what it checks, not for a set time)."""
    got, end = [], time.monotonic() + seconds
    while time.monotonic() < end and not (until is not None and until()):
        got.extend(link.receive(0.05))
    return got


def test_two_dots_are_synced_streamed_in_si_and_a_dropped_one_comes_back_with_its_gap_counted(monkeypatch):
    dots = [FakeDot("D4:22:CD:00:00:01"), FakeDot("D4:22:CD:00:00:02")]
    link = _link(dots, monkeypatch)
    try:
        got = _collect(link, 10.0, lambda: all(len(d.notified) > 60 for d in dots))
        dots[1].refuse = 1  # one connect refused after the drop: the back-off
        link._loop.call_soon_threadsafe(dots[1].client.drop)
        got += _collect(link, 5.0, lambda: link.problem is not None)
        away = link.problem or ""
        got += _collect(link, 10.0, lambda: link.problem is None)
        got += _collect(link, 0.5)
        assert link.problem is None and link.reconnects == 1
    finally:
        link.close()
    assert "D4:22:CD:00:00:02 disconnected" in away or "cannot connect to D4:22:CD:00:00:02" in away
    for sid, dot in enumerate(dots):
        kinds = [e[0] if e[0] != "write" else ("write", e[1]) for e in dot.log]
        # rate first, StartSync (root: the first sensor) then disconnect, the result read after reconnecting,
        # notifications enabled before measurement starts, stopped at the end
        assert dot.rate == 60 and kinds[:4] == ["connect", ("write", dp.DEVICE_CONTROL),
                                                ("write", dp.MESSAGE_CONTROL), "disconnect"]
        assert dot.log[2][2] == dp.start_sync(dots[0].address)
        assert kinds[4:8] == ["connect", "read", "notify", ("write", dp.MEASUREMENT_CONTROL)]
        assert not dot.measuring
        samples = [item[0][0] for item in got if item[0][0].sensor_id == sid]
        assert {item[2] for item in got if item[0][0].sensor_id == sid} == {f"dot {dot.address}"}
        assert len(samples) == len(dot.notified) > 60
        seq = np.array([s.sequence for s in samples])
        # gaps = samples unheard
        assert np.array_equal(seq - seq[0], np.array(dot.notified) - dot.notified[0])
        k = np.array(dot.notified)
        acc, gyr, mag = (np.array([dot.sample(i)[j] for i in k]) for j in range(3))
        np.testing.assert_allclose([s.acc for s in samples], acc, atol=1e-6)
        np.testing.assert_allclose([s.gyr for s in samples], np.radians(gyr), atol=1e-7)
        np.testing.assert_allclose([s.mag for s in samples], mag * dp.MAG_UNIT_T, atol=dp.MAG_UNIT_T / 4096)
        dt = np.diff([s.device_time_us for s in samples])
        assert np.abs(dt - np.diff(k) * 1e6 / 60).max() <= 1.0  # across the 2³² µs wrap too
    assert np.diff(dots[1].notified).max() > 0.15 * 60  # the time away (2 retries of 0.1 s): one gap
    assert np.diff(dots[0].notified).max() == 1


def test_a_failed_sync_and_a_bad_notification_are_named_not_raised(monkeypatch):
    dots = [FakeDot("D4:22:CD:00:00:01"), FakeDot("D4:22:CD:00:00:02", sync_code=0x07)]
    link = _link(dots, monkeypatch)
    try:
        got = _collect(link, 10.0, lambda: link.problem is not None and len(dots[0].notified) > 40)
        link._loop.call_soon_threadsafe(dots[0].client.notify, None, bytearray(b"\x01\x02"))
        got += _collect(link, 5.0, lambda: link.bad_frames > 0)
    finally:
        link.close()
    assert link.bad_frames == 1 and len(got) > 40
    assert link.problem == "D4:22:CD:00:00:02 not synced (clock skew too large)"


def test_a_dot_that_does_not_come_back_after_sync_is_named_and_the_others_stream(monkeypatch):
    from gait_biofeedback.io.vendors.dot import DotLink

    monkeypatch.setattr(DotLink, "START_WAIT_S", 0.3)
    dots = [FakeDot("D4:22:CD:00:00:01"), FakeDot("D4:22:CD:00:00:02"), FakeDot("D4:22:CD:00:00:03")]
    dots[2].gone_after_sync = True
    link = _link(dots, monkeypatch)
    try:
        got = _collect(link, 10.0, lambda: all(len(d.notified) > 30 for d in dots[:2]))
    finally:
        link.close()
    assert {item[0][0].sensor_id for item in got} == {0, 1} and not dots[2].notified
    assert "cannot connect to D4:22:CD:00:00:03" in link.problem
    assert "D4:22:CD:00:00:03 not synced (no acknowledge" in link.problem
    assert "00:01" not in link.problem and "00:02" not in link.problem


def test_a_rate_a_dot_cannot_stream_is_refused_with_the_rates_it_can():
    from gait_biofeedback.io.vendors.dot import DotLink

    with pytest.raises(ValueError, match="1, 4, 10, 12, 15, 20, 30, 60 Hz"):
        DotLink({"D4:22:CD:00:00:01": 0}, 100.0, client_factory=lambda a, cb: None)


@pytest.mark.skipif(__import__("os").path.exists("/run/dbus/system_bus_socket"),
                    reason="this computer has a system D-Bus (BlueZ may answer): the test is for one without")
def test_without_bluetooth_the_real_bleak_path_names_what_is_missing_and_closes():
    pytest.importorskip("bleak", reason="the dot backend's bleak")
    from gait_biofeedback.core.driver.stream import DriverParams
    from gait_biofeedback.nodes.imu_driver import open_link

    link = open_link(DriverParams(backend="dot", device_rate_hz=60, devices=("D4:22:CD:00:00:01=left_foot",)))
    try:
        end = time.monotonic() + 5
        while link.problem is None and time.monotonic() < end:
            assert link.receive(0.05) == []
    finally:
        link.close()
    assert "cannot connect to D4:22:CD:00:00:01 (no Bluetooth service on this computer" in link.problem
