"""x-io backends of imu_driver (issue 50): the x-IMU3 through x-io's real ``ximu3`` SDK and the NGIMU
through python-osc, against hand-made packets (x-IMU3 User Manual v1.7 8.2; NGIMU User Manual and OSC
1.0), the fake devices, and ``run --driver ximu3:/ngimu:`` + ``stream-sim --as`` into a recording that
``analyze`` reads."""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import synthetic_imu

from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.core.driver.stream import DriverCore, DriverParams
from gait_biofeedback.core.params import ParameterError
from gait_biofeedback.io.vendors.timebase import SequenceFromTime
from gait_biofeedback.sim import xio_devices

G = 9.80665
CLI = [sys.executable, "-m", "gait_biofeedback.cli"]


def _receive_until(link, n: int, timeout_s: float = 5.0) -> list:
    out, deadline = [], time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < deadline:
        out += link.receive(0.05)
    return out


# ------------------------------------------------------------------ numbering, parameters


def test_sequence_from_device_time_counts_losses_duplicates_and_reordering():
    numbering = SequenceFromTime()
    got = []
    for t in [0, 10_000, 20_000, 30_000, 40_000, 50_000, 60_000, 70_000, 90_000, 80_000, 90_000, 130_000]:
        got += numbering.push(1_000_000 + t, t, lambda seq, t: (seq, t))
    assert numbering.period_us == 10_000
    # 8 learnt, then one lost (80 ms comes after 90 ms: reordered), 90 ms again, 100-120 ms lost
    assert got == [(k, 10_000 * k) for k in range(8)] + [(9, 90_000), (8, 80_000), (9, 90_000), (13, 130_000)]
    # a period learnt 0.01 % off does not drift into a wrong count: 1000 samples later still exact
    drifting = SequenceFromTime()
    last = []
    for k in range(1000):
        last = drifting.push(round(k * 10_001), k, lambda seq, k: seq - k) or last
    assert last == [0]


def test_devices_map_to_the_sensor_ids_of_their_segments_and_mistakes_are_refused():
    p = DriverParams(backend="ngimu", devices=("192.168.1.20=left_foot", "192.168.1.21:8001=pelvis"))
    ids = {seg: sid for sid, seg in p.mapping().items()}
    assert p.device_ids() == {"192.168.1.20": ids["left_foot"], "192.168.1.21:8001": ids["pelvis"]}
    for devices, words in [(("a=left_fot",), "names no segment"), (("a=pelvis", "a=chest"), "twice"),
                           (("a=pelvis", "b=pelvis"), "twice"), (("pelvis",), "DEVICE_ID=SEGMENT")]:
        with pytest.raises(ParameterError, match=words):
            DriverParams(backend="ximu3", devices=devices)
    with pytest.raises(ParameterError, match="has no sensor id in 'sensors'"):
        DriverParams(backend="ximu3", sensors=("1:pelvis",), devices=("tcp:h:7000=chest",))
    with pytest.raises(ParameterError, match="backend 'ngimu' needs parameter 'devices'"):
        DriverParams(backend="ngimu")
    with pytest.raises(ParameterError, match="leave it empty"):
        DriverParams(backend="ximu3", devices=("tcp:h:7000=chest",), frame_key_file="/etc/key")


# ------------------------------------------------------------------ x-IMU3


def test_ximu3_fake_device_encodes_the_manuals_examples():
    # x-IMU3 User Manual v1.7 8.2.2 and 8.2.3: a timestamp of 1 s, accelerometer z 1 g; magnetometer x 1 a.u.
    inertial = bytes.fromhex("C9 40420F0000000000 00000000 00000000 00000000 00000000 00000000 0000803F 0A")
    assert xio_devices.ximu3_binary("I", 1_000_000, (0, 0, 0, 0, 0, 1)) == inertial
    assert xio_devices.ximu3_binary("M", 1_000_000, (1, 0, 0)) == bytes.fromhex(
        "CD 40420F0000000000 0000803F 00000000 00000000 0A")
    assert xio_devices.ximu3_ascii("I", 1_000_000, (0, 0, 0, 0, 0, 1)) == \
        b"I,1000000,0.0000,0.0000,0.0000,0.0000,0.0000,1.0000\r\n"
    # 8.2.1 byte stuffing: 0x0A → DB DC, 0xDB → DB DD (8.625 = 0x410A0000, 27.375 = 0x41DB0000)
    assert xio_devices.ximu3_binary("M", 0, (8.625, 27.375, 0)) == bytes.fromhex(
        "CD 0000000000000000 0000DBDC41 0000DBDD41 00000000 0A")


@pytest.mark.timeout(60)
def test_ximu3_messages_through_the_real_sdk_in_si_units_and_bad_ones_counted():
    from gait_biofeedback.io.vendors.ximu3 import XImu3Link

    device = xio_devices.FakeXImu3("0123ABCD")
    link = XImu3Link({device.spec: 7})
    try:
        assert link.problem is None
        assert device.wait_connected(5)
        deadline = time.monotonic() + 5
        while not link.devices[0].serial_number and time.monotonic() < deadline:
            time.sleep(0.01)
        assert "ping" in device.commands
        assert link.devices[0].serial_number == "0123ABCD"  # the ping response, read by the SDK
        manual = bytes.fromhex("C9 40420F0000000000 00000000 00000000 00000000 00000000 00000000 0000803F 0A")
        device.send(manual)  # the manual's example: 1 s, accelerometer z 1 g
        for k in range(1, 10):
            device.send(xio_devices.ximu3_binary("I", 1_000_000 + 10_000 * k, (0, 0, 0, 0, 0, 1)))
        # stuffed: gyroscope x 8.625 °/s (0x410A0000), y 27.375 °/s (0x41DB0000), at 1.1 s (0x10C8E0)
        device.send(bytes.fromhex("C9 E0C8100000000000 0000DBDC41 0000DBDD41 00000000"
                                  "00000000 00000000 00000000 0A"))
        device.send(b"I,notanumber\r\n")  # unparsable ASCII
        device.send(bytes.fromhex("C9 0102 0A"))  # a binary message too short
        device.send(b"M,1110000,1.0000,0.0000,-0.5000\r\nI,1110000,0.0000,0.0000,180.0000,0.0000,-1.0000,0.0000\r\n")
        got = _receive_until(link, 12)
    finally:
        link.close()
        device.close()
    samples = [s for batch, _, source in got for s in batch if source == device.spec]
    assert [s.sequence for s in samples] == list(range(12))
    assert samples[0].device_time_us == 1_000_000 and samples[0].acc == pytest.approx((0, 0, G), abs=1e-6)
    assert samples[10].device_time_us == 1_100_000
    assert samples[10].gyr == pytest.approx((math.radians(8.625), math.radians(27.375), 0), abs=1e-9)
    assert samples[10].mag is None
    last = samples[11]
    assert last.gyr == pytest.approx((0, 0, math.pi), abs=1e-6) and last.acc == pytest.approx((0, -G, 0))
    assert last.mag == pytest.approx((50e-6, 0, -25e-6), abs=1e-12)  # 1 a.u. ≈ 50 µT (manual 3.3.3)
    assert link.bad_frames == 2


@pytest.mark.timeout(60)
def test_ximu3_over_udp_through_the_real_sdk_with_the_manuals_port_names():
    from gait_biofeedback.io.vendors.ximu3 import XImu3Link

    device = xio_devices.FakeXImu3Udp("UDP1")  # 'udp:HOST:SEND:RECEIVE': the device's send, receive ports
    link = XImu3Link({device.spec: 2})
    try:
        assert device.wait_connected(5)  # the SDK's ping reached the device's receive port
        for k in range(10):
            device.send_sample(DeviceSample(2, 0, 2_000_000 + 5_000 * k, (0.0, G, 0.0), (0.0, 0.0, -math.pi),
                                            (0.0, 0.0, 25e-6)))
        got = _receive_until(link, 10)
    finally:
        link.close()
        device.close()
    samples = [batch[0] for batch, _, source in got if source == device.spec]
    assert [s.sequence for s in samples] == list(range(10))
    assert samples[9].device_time_us == 2_045_000 and samples[9].acc == pytest.approx((0, G, 0))
    assert samples[9].gyr == pytest.approx((0, 0, -math.pi))
    assert samples[9].mag == pytest.approx((0, 0, 25e-6))


@pytest.mark.timeout(60)
def test_ximu3_a_connection_that_drops_is_opened_again_and_the_gap_counted_as_lost(monkeypatch):
    from gait_biofeedback.io.vendors.ximu3 import XImu3Link

    monkeypatch.setattr(XImu3Link, "RETRY_S", 0.2)
    monkeypatch.setattr(XImu3Link, "SILENT_S", 0.5)
    device = xio_devices.FakeXImu3("A1")
    link = XImu3Link({device.spec: 1})

    def send(ks):
        for k in ks:
            device.send_sample(DeviceSample(1, 0, 1_000_000 + 10_000 * k, (0.0, 0.0, G), (0.0, 0.0, 0.0)))

    try:
        assert device.wait_connected(5)
        send(range(10))
        assert len(_receive_until(link, 10)) == 10
        device.drop_host()  # Wi-Fi out of range: the SDK still says connected
        deadline = time.monotonic() + 5
        while link.problem is None and time.monotonic() < deadline:
            link.receive(0.05)
        assert "connecting again" in link.problem
        assert device.wait_connected(5)
        while link.problem is not None and time.monotonic() < deadline + 5:
            link.receive(0.05)
        assert link.problem is None and link.reconnects == 1
        send(range(15, 20))
        got = _receive_until(link, 5)
    finally:
        link.close()
        device.close()
    assert [batch[0].sequence for batch, _, _ in got] == [15, 16, 17, 18, 19]  # 10-14 lost meanwhile


@pytest.mark.timeout(60)
def test_ximu3_a_device_named_by_its_serial_number_is_found_by_its_announcements(monkeypatch):
    from gait_biofeedback.io.vendors.ximu3 import XImu3Link

    monkeypatch.setattr(XImu3Link, "RETRY_S", 0.1)
    device = xio_devices.FakeXImu3("65577B49")
    try:
        link = XImu3Link({"65577b49": 4})  # as a clinician may type it
    except OSError as err:  # port 10000 is another program's
        device.close()
        pytest.skip(str(err))
    try:
        assert "not heard on this network yet" in link.problem
        deadline = time.monotonic() + 10
        while not device.wait_connected(0.05) and time.monotonic() < deadline:
            device.announce()  # once a second on a real device; a new source port each time
            link.receive(0.05)
        assert device.wait_connected(0)
        for k in range(8):
            device.send_sample(DeviceSample(4, 0, 1_000_000 + 10_000 * k, (0.0, 0.0, G), (0.0, 0.0, 0.0)))
        got = _receive_until(link, 8)
    finally:
        link.close()
        device.close()
    assert link.announced == {"65577B49": ("127.0.0.1", device.port)}
    assert len(got) == 8 and {source for _, _, source in got} == {"65577b49"}


def test_ximu3_a_device_that_is_not_there_is_named_and_tried_again():
    from gait_biofeedback.io.vendors.ximu3 import XImu3Link

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nobody listens on it once closed
    link = XImu3Link({f"tcp:127.0.0.1:{port}": 1})
    try:
        assert f"tcp:127.0.0.1:{port}" in link.problem and "trying again" in link.problem
        assert link.receive(0.01) == []
    finally:
        link.close()
    with pytest.raises(ValueError, match="tcp:HOST:PORT"):
        XImu3Link({"tcp:127.0.0.1": 1})


# ------------------------------------------------------------------ NGIMU


def _osc_sensors_bundle(seconds: int, fraction: int, args: tuple[float, ...],
                        address: bytes = b"/sensors\0\0\0\0") -> bytes:
    """Written out from the OSC 1.0 specification: '#bundle', NTP time tag, size, message."""
    message = address + b"," + b"f" * len(args) + b"\0" * (4 - (1 + len(args)) % 4) + struct.pack(
        f">{len(args)}f", *args)
    return b"#bundle\0" + struct.pack(">IIi", seconds, fraction, len(message)) + message


def test_ngimu_sensors_bundles_decoded_in_si_units_and_bad_datagrams_counted():
    from gait_biofeedback.io.vendors.ngimu import NgimuLink, OscError, sensors_messages, sensors_sample

    link = NgimuLink("127.0.0.1", 0, {"127.0.0.1": 5})
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        target = ("127.0.0.1", link.port)
        sender.bind(("127.0.0.1", 0))
        source = f"127.0.0.1:{sender.getsockname()[1]}"
        args = (90.0, 0.0, -180.0, 0.0, 0.0, 1.0, 10.0, 20.0, -30.0, 1013.25)
        first = _osc_sensors_bundle(3_900_000_000, 1 << 31, args)  # 3.9e9 s after 1900 and a half
        fake = xio_devices.ngimu_sensors_bundle(3_900_000_000_500_000, args[:3], args[3:6], args[6:9])
        assert first == fake
        sender.sendto(first, target)
        for k in range(1, 8):  # 100 Hz: fraction steps of 2^32 / 100
            sender.sendto(_osc_sensors_bundle(3_900_000_000, (1 << 31) + k * 42_949_673, args), target)
        sender.sendto(b"not OSC", target)
        sender.sendto(first[:30], target)  # truncated
        sender.sendto(_osc_sensors_bundle(3_900_000_001, 0, (1.0, 2.0, 3.0)), target)  # 3 arguments
        sender.sendto(first[20:], target)  # the /sensors message outside a bundle: no time tag
        sender.sendto(_osc_sensors_bundle(3_900_000_001, 0, (99.0,), b"/battery\0\0\0\0"), target)  # ignored
        no_mag = (*args[:6], 0.0, 0.0, 0.0, args[9])  # a magnetometer reading 0 on every axis: none
        sender.sendto(_osc_sensors_bundle(3_900_000_000, (1 << 31) + 8 * 42_949_673, no_mag), target)
        stranger.sendto(first, target)  # from another port of the mapped address: its own source
        got = _receive_until(link, 9)
        time.sleep(0.05)
        got += link.receive(0.05)
    finally:
        sender.close()
        stranger.close()
        link.close()
    ours = [s for batch, _, src in got for s in batch if src == source]
    assert [s.sequence for s in ours] == list(range(9))
    assert ours[8].mag is None and ours[8].acc == pytest.approx((0, 0, G))
    s = ours[0]
    assert s.sensor_id == 5 and s.device_time_us == 3_900_000_000_500_000
    assert s.gyr == pytest.approx((math.pi / 2, 0, -math.pi)) and s.acc == pytest.approx((0, 0, G))
    assert s.mag == pytest.approx((10e-6, 20e-6, -30e-6))
    assert ours[7].device_time_us - s.device_time_us == 70_000
    assert link.bad_frames == 4
    for cut in range(len(first)):  # every truncation of a bundle: no sample, an OscError, never a crash
        with contextlib.suppress(OscError):
            assert [sensors_sample(5, 0, t, args) for t, args in sensors_messages(first[:cut])] == []
    [notice] = link.notices.pop()  # the first named, the others counted
    assert notice.level == "warn" and "not an OSC packet" in notice.text


def test_ngimu_a_second_sender_claiming_a_device_is_refused_and_an_unmapped_one_named():
    from gait_biofeedback.io.vendors.ngimu import NgimuLink

    p = DriverParams(backend="ngimu", port=0, devices=("127.0.0.1=left_foot",))
    core, link = DriverCore(p), NgimuLink("127.0.0.1", 0, {"127.0.0.1": p.device_ids()["127.0.0.1"]})
    owner = xio_devices.FakeNgimus([1], "127.0.0.1", link.port)
    claimer = xio_devices.FakeNgimus([1], "127.0.0.1", link.port)
    try:
        def sample(k, t0):
            return DeviceSample(1, 0, t0 + 10_000 * k, (0.0, 0.0, G), (0.0, 0.0, 0.0), (2e-5, 0.0, 0.0))

        published = 0
        for k in range(41):  # the owner sends last: the claims held meanwhile are refused
            owner.send_sample(sample(k, 5_000_000))
            if 20 <= k < 40:
                claimer.send_sample(sample(k, 9_000_000))
            time.sleep(0.01)
            for batch, arrival, source in link.receive(0.0):
                published += len(core.feed_samples(batch, arrival, source))
        for batch, arrival, source in _receive_until(link, 1, 0.3):
            published += len(core.feed_samples(batch, arrival, source))
        published += len(core.expire(time.time_ns() + 10**9))
    finally:
        owner.close()
        claimer.close()
        link.close()
    stream = core.sensors[p.device_ids()["127.0.0.1"]]
    assert stream.source == f"127.0.0.1:{owner.ports[1]}" and published == 41
    assert stream.foreign == {f"127.0.0.1:{claimer.ports[1]}": 20}  # every claimed sample, refused
    report = next(r for r in core.reports(time.time_ns()) if r.name == "imu_driver: left_foot")
    assert report.level == 1 and "two sources claim one id" in report.message


def test_ngimu_an_unmapped_sender_is_counted_and_named_with_what_to_do():
    from gait_biofeedback.io.vendors.ngimu import NgimuLink

    link = NgimuLink("127.0.0.1", 0, {"10.0.0.9": 1})
    fake = xio_devices.FakeNgimus([1], "127.0.0.1", link.port)
    try:
        for k in range(3):
            fake.send_sample(DeviceSample(1, 0, 10_000 * k, (0.0, 0.0, G), (0.0, 0.0, 0.0), None))
        assert _receive_until(link, 1, 0.3) == []
    finally:
        fake.close()
        link.close()
    [(_name, level, message, values)] = link.reports()
    assert values == {"source": f"127.0.0.1:{fake.ports[1]}", "datagrams": 3} and level == 1
    assert "add '127.0.0.1=SEGMENT' to imu_driver's 'devices'" in message
    assert [n.level for n in link.notices.pop()] == ["warn"]  # said once


# ------------------------------------------------------------------ the command line, end to end


def _diagnostics(bag) -> dict[str, list[tuple[int, dict[str, str], str]]]:
    """Every imu_driver status of each name in ``bag``, in order: (level, values, message)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    from gait_biofeedback.io.bag import BagReader

    last = {}
    with BagReader(bag) as reader:
        for _topic, _type, data, _ns in reader.raw_messages(["/diagnostics"]):
            for s in deserialize_message(data, DiagnosticArray).status:
                if s.name.startswith("imu_driver"):
                    last.setdefault(s.name, []).append((s.level[0] if isinstance(s.level, bytes) else s.level,
                                                        {kv.key: kv.value for kv in s.values}, s.message))
    return last


def _record_through_fake_devices(tmp_path, kind: str, report: bool = False) -> None:
    """An 8-sensor session (3 s at 100 Hz, 2 % loss, jitter, drifting clocks) sent by fake devices of
    ``kind`` into ``run --driver`` with ``--record``: every sample sent recorded with its values; then
    ``analyze`` takes the recording (and ``report`` its analysis)."""
    from gait_biofeedback.core.segments import SEGMENTS
    from gait_biofeedback.io.bag import read_imu_bag, write_imu_bag
    from gait_biofeedback.sim.sensor_link import FrameSchedule, LinkModel

    series = synthetic_imu(list(SEGMENTS), duration=3.0, rate_hz=100.0)
    bag = write_imu_bag(tmp_path / "in", series)
    out = tmp_path / "rec"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    link = ["--loss", "0.02", "--jitter-ms", "3", "--drift-ppm", "100", "--offset-s", "5", "--seed", "3"]
    run_args = ["--nodes", "", "--record", str(out), "--duration", "40"]
    sim = run = None
    try:
        if kind == "ximu3":
            sim = subprocess.Popen([*CLI, "stream-sim", str(bag), "--as", "x-imu3", *link],
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
            spec = next(re.search(r"--driver '([^']+)'", line).group(1) for line in sim.stdout
                        if "connect with" in line)
            run = subprocess.Popen([*CLI, "run", "--driver", spec, *run_args], stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, text=True, env=env)
        else:
            port, first = 6000 + os.getpid() % 500, 6600 + os.getpid() % 500
            devices = ",".join(f"127.0.0.1:{first + k}={seg}" for k, seg in enumerate(SEGMENTS))
            run = subprocess.Popen([*CLI, "run", "--driver", f"ngimu:{port},{devices}", *run_args],
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
            next(line for line in run.stdout if "Ctrl-C stops" in line)
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger:  # an NGIMU not mapped
                for k in range(3):
                    sample = DeviceSample(0, 0, 10_000 * k, (0.0, 0.0, G), (0.0, 0.0, 0.0), None)
                    stranger.sendto(xio_devices.ngimu_datagram(sample), ("127.0.0.1", port))
                unmapped = f"imu_driver: NGIMU 127.0.0.1:{stranger.getsockname()[1]}"
            sim = subprocess.Popen([*CLI, "stream-sim", str(bag), "--as", "ngimu", "--to",
                                    f"udp:127.0.0.1:{port}", "--source-port", str(first), *link],
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        sent_text = sim.communicate(timeout=60)[0]
        assert sim.returncode == 0, sent_text
        time.sleep(0.5)  # the last samples reach the recorder
        run.send_signal(signal.SIGINT)
        rest = run.communicate(timeout=30)[0]
        assert run.returncode == 0, rest
    finally:
        for process in (sim, run):
            if process is not None:
                process.kill()
    n_sent = int(sent_text.split("sent ")[-1].split()[0])
    ids = {seg: sid for sid, seg in DriverParams().mapping().items()}
    schedule = FrameSchedule(series, ids, LinkModel(5.0, 100.0, 3.0, 0.02, seed=3))
    assert n_sent == schedule.samples - schedule.samples_dropped and schedule.samples_dropped > 0
    recorded = read_imu_bag(out)
    for seg, truth in schedule.truth.items():
        kept = ~truth.dropped
        assert len(recorded[seg]) == int(kept.sum()), seg
        # float32 on the wire, in °/s and g: values equal to float32 rounding
        np.testing.assert_allclose(recorded[seg].acc, series[seg].acc[kept], rtol=2e-7, atol=2e-6)
        np.testing.assert_allclose(recorded[seg].gyr, series[seg].gyr[kept], rtol=2e-7, atol=2e-7)
        assert recorded[seg].mag is not None
    statuses = _diagnostics(out)
    # while it sent: its rate and losses, and its source (once it stops, it is reported silent)
    sending = [(level, values, message) for level, values, message in statuses["imu_driver: left_foot"]
               if "Hz" in message and "lost" in message]
    assert sending and all(level <= 1 for level, _, _ in sending)
    assert sending[-1][1]["source"].startswith("tcp:127.0.0.1:" if kind == "ximu3" else "127.0.0.1:")
    if kind == "ngimu":
        level, values, message = statuses[unmapped][-1]
        assert level == 1 and values["datagrams"] == "3" and "add '127.0.0.1=SEGMENT'" in message
    analyzed = subprocess.run([*CLI, "analyze", str(out), "-o", str(tmp_path / "analysis")],
                              capture_output=True, text=True, timeout=120)
    assert analyzed.returncode == 0, analyzed.stderr
    assert "orientations and activity only" in analyzed.stdout
    if report:
        reported = subprocess.run([*CLI, "report", str(tmp_path / "analysis"), "-o",
                                   str(tmp_path / "report")], capture_output=True, text=True, timeout=120)
        assert reported.returncode == 0, reported.stderr
        assert (tmp_path / "report" / "report.pdf").stat().st_size > 0


@pytest.mark.ros
@pytest.mark.timeout(150)
def test_run_driver_ximu3_records_a_fake_8_sensor_session_that_analyze_and_report_take(tmp_path):
    _record_through_fake_devices(tmp_path, "ximu3", report=True)


@pytest.mark.ros
@pytest.mark.timeout(150)
def test_run_driver_ngimu_records_a_fake_8_sensor_session_that_analyze_reads(tmp_path):
    _record_through_fake_devices(tmp_path, "ngimu")
