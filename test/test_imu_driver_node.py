"""imu_driver node: UDP, serial (a pseudo-terminal) and simulated sensors → raw topics, exactly;
``run --driver`` + ``stream-sim`` through the command line into a recording."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from conftest import spinning, stamp_ns, stamp_s, synthetic_imu

from gait_biofeedback.sim.sensor_link import FrameSchedule, LinkModel, send_udp

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90)]
SEGMENTS = ("left_foot", "right_foot")
IDS = {"left_foot": 3, "right_foot": 6}
SENSORS = [f"{sid}:{seg}" for seg, sid in IDS.items()]


class Listener:
    """Raw IMU, magnetometer and /diagnostics messages of a node set, as they come."""

    def __init__(self, context, segments=SEGMENTS):
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node
        from sensor_msgs.msg import Imu, MagneticField

        from gait_biofeedback.wire import topics

        self.node = Node("listener", context=context)
        self.imu = {s: [] for s in segments}
        self.mag = {s: [] for s in segments}
        self.diagnostics: dict[str, object] = {}
        for s in segments:
            self.node.create_subscription(Imu, f"{s}/imu/data_raw", self.imu[s].append, topics.SENSOR_QOS)
            self.node.create_subscription(MagneticField, f"{s}/imu/mag", self.mag[s].append,
                                          topics.SENSOR_QOS)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._diag, 100)

    def _diag(self, msg):
        for s in msg.status:
            self.diagnostics[s.name] = s

    def values(self, name):
        return {kv.key: kv.value for kv in self.diagnostics[name].values}


@contextlib.contextmanager
def _graph(context, **params):
    """The driver (``params``) and a :class:`Listener` spinning, the driver started once its raw topics
    are matched: (driver, listener, executor); both nodes destroyed on leaving."""
    from gait_biofeedback.nodes.imu_driver import ImuDriverNode

    listener = Listener(context)
    driver = ImuDriverNode(context, start=False, sensors=SENSORS, **params)
    with spinning(context, driver, listener.node) as executor:
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and not all(p.get_subscription_count() for p in driver.publishers
                                                      if p.topic_name.endswith("data_raw")):
            executor.spin_once(timeout_sec=0.05)
        for _ in range(10):
            executor.spin_once(timeout_sec=0.02)
        driver.start()
        yield driver, listener, executor


def _check_exact(schedule, listener, series):
    for seg in SEGMENTS:
        kept = ~schedule.truth[seg].dropped
        got = listener.imu[seg]
        assert len(got) == int(kept.sum()), f"{seg}: every sample not dropped by the link, once"
        stamps = np.array([stamp_ns(m.header.stamp) for m in got])
        assert (np.diff(stamps) > 0).all()
        acc = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
                        for m in got])
        np.testing.assert_allclose(acc, series[seg].acc[kept].astype(np.float32), rtol=0, atol=0)
        assert {m.header.frame_id for m in got} == {f"{seg}_imu"}
        assert all(m.orientation_covariance[0] == -1.0 for m in got)
        assert len(listener.mag[seg]) == len(got)
    return stamps


def test_udp_sensors_with_loss_reordering_and_drifting_clocks_come_out_exactly(ros_context):
    from gait_biofeedback.nodes.common import spin_until

    series = synthetic_imu(list(SEGMENTS), duration=3.0, rate_hz=100.0)
    link = LinkModel(offset_s=7.0, drift_ppm=200.0, jitter_ms=4.0, loss=0.03, reorder=0.05, seed=4)
    schedule = FrameSchedule(series, IDS, link)
    with _graph(ros_context, port=0) as (driver, listener, executor):
        sent = {}
        thread = threading.Thread(target=lambda: sent.update(
            r=send_udp(schedule, "127.0.0.1", driver.link.port)), daemon=True)
        thread.start()
        total = schedule.samples - schedule.samples_dropped
        def received():
            return sum(map(len, listener.imu.values())) >= total and not thread.is_alive()

        def reported():
            name = "imu_driver: left_foot"
            return name in listener.diagnostics and int(listener.values(name)["published"]) == len(
                listener.imu["left_foot"])

        spin_until(executor, received, timeout=20)
        spin_until(executor, reported, timeout=5)
        stamps = _check_exact(schedule, listener, series)
        assert schedule.samples_dropped > 0  # the test did lose samples
        # the stamps are the true sample times in host time, plus the link's least latency (here
        # mostly the sender's: a thread of this process, late by a few ms waiting for the GIL)
        truth = schedule.truth["right_foot"]
        true_ns = sent["r"].t0_ns + np.round(truth.t[~truth.dropped] * 1e9)
        error_ms = (stamps - true_ns) * 1e-6
        assert 0 <= np.median(error_ms) < 10.0
        # from the device clocks, not the arrivals: from one sample to the next the error stays put (90 %
        # of the steps within 0.1 ms; 0.002-0.005 ms beside two busy processes), where arrival stamps
        # would move by the link's 0-4 ms jitter (90 % of the steps within 2.7 ms), and half of the
        # stamps are within 0.5 ms of the median error (0.04-0.08 ms measured; arrival stamps: 1 ms).
        # How close all of them are (p95 under 1 ms on a quiet machine, up to 1.0 ms beside two busy
        # processes) is benchmarks/driver.py's figure (stamp error p50/p99/max at 100 and 200 Hz)
        assert np.percentile(np.abs(np.diff(error_ms)), 90) < 0.1
        assert np.median(np.abs(error_ms - np.median(error_ms))) < 0.5
        for seg in SEGMENTS:
            values = listener.values(f"imu_driver: {seg}")
            dropped = schedule.truth[seg].dropped
            inner = int(dropped[np.argmin(dropped):len(dropped) - np.argmin(dropped[::-1])].sum())
            assert int(values["lost"]) == inner  # losses before the first and after the last are unseen
            assert int(values["duplicates"]) == 0
            assert float(values["rate_hz"]) == pytest.approx(100.0, rel=0.01)
        assert "cpu_fraction" in listener.values("imu_driver: receiving")


def test_unmapped_and_missing_sensors_are_named_on_diagnostics_and_the_dashboard(ros_context, tmp_path):
    import socket

    from gait_biofeedback.core.driver.protocol import DeviceSample, encode_frame
    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.common import spin_until

    with _graph(ros_context, port=0) as (driver, listener, executor), \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        dashboard = BiofeedbackNode(ros_context, port=0)
        executor.add_node(dashboard)  # destroyed with the graph's nodes
        for k in range(20):  # in real time: a source is bound once its samples came as they were taken
            frame = encode_frame([DeviceSample(sid, k, 10_000 * k, (0.0, 0.0, 9.8), (0.0, 0.0, 0.0))
                                  for sid in (3, 11)])
            sock.sendto(frame, ("127.0.0.1", driver.link.port))
            time.sleep(0.01)
        sock.sendto(b"not a frame at all", ("127.0.0.1", driver.link.port))
        names = {"imu_driver: sensor 11", "imu_driver: link"}
        spin_until(executor, lambda: names <= set(listener.diagnostics), timeout=5)
        assert "add '11:SEGMENT'" in listener.diagnostics["imu_driver: sensor 11"].message
        right = listener.diagnostics["imu_driver: right_foot"]
        assert right.level == b"\x02" and "no data from sensor 6" in right.message
        assert listener.values("imu_driver: link")["bad_frames"] == "1"
        assert len(listener.imu["left_foot"]) == 20
        # the dashboard shows every status: the clinician sees which sensor is missing or unmapped
        spin_until(executor, lambda: "imu_driver: sensor 11" in dashboard._diag, timeout=5)
        assert dashboard._diag["imu_driver: right_foot"]["level"] == 2
        assert "no data from sensor 6" in dashboard._diag["imu_driver: right_foot"]["message"]


def _send_genuine_and_forged(port, key=None, forged_frames=()):
    """Sensor 3 (left_foot) sends 100 samples at 200 Hz from one socket, its device clock the wall
    clock; a second socket sends ``forged_frames`` interleaved. (genuine send ns, forger's port)."""
    import socket

    from gait_biofeedback.core.driver.protocol import DeviceSample, encode_frame

    genuine, forger = (socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2))
    sent = []
    try:
        forger.bind(("127.0.0.1", 0))
        start = time.time_ns()
        for k in range(100):
            now = time.time_ns()
            frame = encode_frame([DeviceSample(3, 7000 + k, (now - start) // 1000, (float(k), 0.0, 9.8),
                                               (0.0, 0.0, 0.0))], key)
            genuine.sendto(frame, ("127.0.0.1", port))
            sent.append(now)
            if k >= 10 and k - 10 < len(forged_frames):  # the id is bound to the genuine sender by now
                forger.sendto(forged_frames[k - 10], ("127.0.0.1", port))
            time.sleep(0.005)
        return np.array(sent), forger.getsockname()[1]
    finally:
        genuine.close()
        forger.close()


def _forged(seq, t_us, key=None):
    from gait_biofeedback.core.driver.protocol import DeviceSample, encode_frame

    return encode_frame([DeviceSample(3, seq, t_us, (-1.0, 0.0, 0.0), (0.0, 0.0, 0.0))], key)


def _send_while_spinning(executor, *args):
    """:func:`_send_genuine_and_forged` in a thread while the graph spins (the topics' depth is 100)."""
    from gait_biofeedback.nodes.common import spin_until

    result = []
    thread = threading.Thread(target=lambda: result.append(_send_genuine_and_forged(*args)), daemon=True)
    thread.start()
    spin_until(executor, lambda: not thread.is_alive(), timeout=10)
    assert result, "the senders finished"
    return result[0]


def _genuine_only(listener, sent):
    got = listener.imu["left_foot"]
    assert [m.linear_acceleration.x for m in got] == [float(k) for k in range(100)]
    stamps = np.array([stamp_ns(m.header.stamp) for m in got])
    assert (np.diff(stamps) > 0).all()
    assert np.abs(stamps - sent).max() < 50e6  # a forged sample taken would move them seconds


def test_udp_a_second_sender_claiming_a_sensors_id_is_dropped_and_named(ros_context):
    from gait_biofeedback.nodes.common import spin_until

    with _graph(ros_context, port=0, diagnostics_period_s=0.2) as (driver, listener, executor):
        # the hostile probe: sequence 123 at device time 1 µs, then a stream of its own (a second sensor 3)
        forged = [_forged(123, 1)] + [_forged(k, 5_000 * k) for k in range(50)]
        sent, forger_port = _send_while_spinning(executor, driver.link.port, None, forged)
        name = "imu_driver: left_foot"
        spin_until(executor, lambda: name in listener.diagnostics and listener.values(name)["foreign_samples"]
                   == "51" and len(listener.imu["left_foot"]) >= 100, timeout=10)
        _genuine_only(listener, sent)
        values = listener.values(name)
        assert (values["foreign_samples"], values["lost"], values["reboots"], values["rejected"]) == (
            "51", "0", "0", "0")
        status = listener.diagnostics[name]
        assert status.level == b"\x01"
        assert f"sensor 3 also sent from 127.0.0.1:{forger_port}: two sources claim one id" in status.message


def test_udp_with_a_session_key_only_signed_frames_are_taken(ros_context, tmp_path):
    from gait_biofeedback.nodes.common import spin_until

    key = b"a session key of the clinic, 0123"
    key_file = tmp_path / "frame.key"
    key_file.write_bytes(key + b"\n")
    key_file.chmod(0o600)
    with _graph(ros_context, port=0, diagnostics_period_s=0.2,
                frame_key_file=str(key_file)) as (driver, listener, executor):
        forged = [_forged(7000 + k, 1, None) for k in range(20)]  # unsigned, with sequences ahead
        forged += [_forged(7100 + k, 1, b"guessed key 0123456789") for k in range(10)]
        sent, _ = _send_while_spinning(executor, driver.link.port, key, forged)
        name = "imu_driver: link"
        spin_until(executor, lambda: name in listener.diagnostics and len(listener.imu["left_foot"]) >= 100
                   and listener.values(name)["wrongly_signed_frames"] == "10", timeout=10)
        _genuine_only(listener, sent)
        assert listener.values(name)["unsigned_frames"] == "20"
        assert "30 frames refused: not signed with the session key" in listener.diagnostics[name].message
        assert listener.values("imu_driver: left_foot")["foreign_samples"] == "0"  # refused, not foreign


def _pty():
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    return master, slave


def test_serial_sensors_with_line_noise_and_a_receiver_plugged_out_and_in(ros_context, tmp_path):
    from gait_biofeedback.core.driver.protocol import decode_frame
    from gait_biofeedback.nodes.common import spin_until

    series = synthetic_imu(list(SEGMENTS), duration=2.0, rate_hz=100.0)
    schedule = FrameSchedule(series, IDS, LinkModel(samples_per_frame=5))
    frames = [schedule.frame(i) for i in range(len(schedule.send_ns))]
    half = len(frames) // 2
    device = tmp_path / "ttyIMU"  # a stable name, as udev gives a receiver
    master, slave = _pty()
    os.symlink(os.ttyname(slave), device)
    rng = np.random.default_rng(0)
    opened = [master, slave]

    def write_in_real_time(part, fd):  # as the receiver sends them: a burst of 1 s of frames is no sensor
        start = time.monotonic() - schedule.send_ns[part.start] * 1e-9
        for i in range(part.start, part.stop):
            time.sleep(max(0.0, start + schedule.send_ns[i] * 1e-9 - time.monotonic()))
            os.write(fd, rng.bytes(3) + frames[i])  # noise before every frame

    def written(part, fd):
        thread = threading.Thread(target=write_in_real_time, args=(part, fd), daemon=True)
        thread.start()
        return lambda: not thread.is_alive()

    try:
        with _graph(ros_context, backend="serial", device=str(device),
                    baud=115200) as (driver, listener, executor):
            done = written(range(0, half), master)
            first = sum(len(decode_frame(f)) for f in frames[:half])
            spin_until(executor, lambda: done() and sum(map(len, listener.imu.values())) >= first, timeout=10)
            os.close(opened.pop(0))  # plugged out: reading the device fails
            spin_until(executor, lambda: driver.link.problem is not None, timeout=5)
            assert "went away" in driver.link.problem
            master, slave = _pty()
            opened += [master, slave]
            device.unlink()
            device.symlink_to(os.ttyname(slave))  # plugged in again
            spin_until(executor, lambda: driver.link.reconnects == 1, timeout=5)
            done = written(range(half, len(frames)), master)
            spin_until(executor, done, timeout=10)
            spin_until(executor, lambda: sum(map(len, listener.imu.values())) >= schedule.samples, timeout=10)
            _check_exact(schedule, listener, series)
            name = "imu_driver: receiving"
            assert spin_until(executor, lambda: name in listener.diagnostics
                              and listener.values(name)["reconnects"] == "1", timeout=5)
    finally:
        for fd in opened:
            os.close(fd)


def test_simulated_sensors_run_live_at_their_rate(ros_context):
    from gait_biofeedback.core.segments import SEGMENTS as ALL
    from gait_biofeedback.nodes.common import spin_until

    listener = Listener(ros_context, ALL)
    from gait_biofeedback.nodes.imu_driver import ImuDriverNode

    driver = ImuDriverNode(ros_context, backend="simulated", scenario="walk")
    with spinning(ros_context, driver, listener.node) as executor:
        spin_until(executor, lambda: len(listener.imu["chest"]) > 0, timeout=20)
        t0 = time.monotonic()
        n0 = len(listener.imu["chest"])
        spin_until(executor, lambda: time.monotonic() - t0 > 2.0)
        rate = (len(listener.imu["chest"]) - n0) / (time.monotonic() - t0)
        # live, not as fast as it can: 99-101 Hz beside two busy processes, so ±15 % holds there
        assert rate == pytest.approx(100.0, rel=0.15)
        assert all(len(listener.imu[s]) > 0 for s in ALL)
        # live: ROS time, now (13-29 ms behind beside two busy processes; a recording's time would be off
        # by years)
        assert abs(stamp_s(listener.imu["chest"][-1].header.stamp) - time.time()) < 0.5


def test_simulated_sensors_sign_with_the_key_the_driver_read_once(ros_context, tmp_path, monkeypatch):
    from gait_biofeedback.core.driver import protocol, stream
    from gait_biofeedback.nodes.imu_driver import ImuDriverNode

    key = b"a session key of the clinic, 0123"
    key_file = tmp_path / "frame.key"
    key_file.write_bytes(key + b"\n")
    key_file.chmod(0o600)
    reads = []

    def counted(path):
        reads.append(path)
        return load(path)

    load = protocol.load_frame_key
    monkeypatch.setattr(protocol, "load_frame_key", counted)
    monkeypatch.setattr(stream, "load_frame_key", counted)
    driver = ImuDriverNode(ros_context, start=False, backend="simulated", scenario="walk",
                           frame_key_file=str(key_file))
    try:
        assert reads == [str(key_file)]  # read once, by the core; the simulator is given the key
        frames = driver.link.receive(0.05)
        assert frames and all(f[:4] == b"GBI2" for f, _, _ in frames)
        assert protocol.decode_frame(frames[0][0], key)[0].sensor_id in driver.core.sensors
    finally:
        driver.destroy_node()


def test_run_driver_and_stream_sim_record_every_sample_through_the_command_line(tmp_path):
    from gait_biofeedback.io.bag import read_imu_bag, write_imu_bag

    series = synthetic_imu(["pelvis", "left_foot"], duration=2.0, rate_hz=100.0)
    bag = write_imu_bag(tmp_path / "in", series)
    out = tmp_path / "rec"
    cli = [sys.executable, "-m", "gait_biofeedback.cli"]
    port = 5600 + os.getpid() % 300
    run = subprocess.Popen([*cli, "run", "--driver", f"udp:{port}", "--nodes", "", "--record", str(out),
                            "--duration", "30"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           env=dict(os.environ, PYTHONUNBUFFERED="1"))  # "Ctrl-C stops" as it is printed
    try:
        for line in run.stdout:
            if "Ctrl-C stops" in line:
                break
        sent = subprocess.run([*cli, "stream-sim", str(bag), "--to", f"udp:127.0.0.1:{port}", "--loss",
                               "0.02", "--jitter-ms", "3", "--seed", "2"], capture_output=True, text=True,
                              timeout=30)
        assert sent.returncode == 0, sent.stderr
        time.sleep(0.5)  # the last datagrams reach the recorder
        run.send_signal(signal.SIGINT)  # Ctrl-C: the recording is closed
        rest = run.communicate(timeout=30)[0]
    finally:
        run.kill()
    assert run.returncode == 0, rest
    text = sent.stdout.splitlines()[-1]
    n_sent, n_dropped = int(text.split()[1]), int(text.split("dropped ")[1].split()[0])
    assert n_sent + n_dropped == 400 and n_dropped > 0
    recorded = read_imu_bag(out)
    assert sum(len(s) for s in recorded.values()) == n_sent


def test_a_malformed_driver_is_refused_naming_the_forms(capsys):
    from gait_biofeedback.cli import main, parse_driver

    assert main(["run", "--driver", "udp:notaport"]) == 2
    assert "expected udp:PORT, udp:ADDRESS:PORT, serial:DEVICE[:BAUD]" in capsys.readouterr().err
    assert parse_driver("udp:0.0.0.0:5601") == {"backend": "udp", "port": 5601, "address": "0.0.0.0"}
    assert parse_driver("serial:/dev/ttyACM0:115200") == {"backend": "serial", "device": "/dev/ttyACM0",
                                                          "baud": 115200}
    assert parse_driver("simulated:walk") == {"backend": "simulated", "scenario": "walk"}
