"""Recording under faults (issue 12): a full disk, SIGTERM / Ctrl-C, a stop and start from the dashboard.

The full disk is a write budget injected under the bag writer's file (no mount needed): every write
beyond it fails with ENOSPC, as on a full filesystem.
"""

from __future__ import annotations

import builtins
import errno
import io
import os
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
from conftest import simulated_bag, spinning, synthetic_imu, true_calibration

from gait_biofeedback.graph import replay_through_graph
from gait_biofeedback.io import bag_writer
from gait_biofeedback.io.bag import BagReader, BagRecoveryWarning, repair, write_imu_bag

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90)]


class SmallDisk:
    """``open`` for the bag writer with ``budget`` bytes of free space shared by every file."""

    def __init__(self, budget: int) -> None:
        self.budget = budget
        disk = self

        class File(io.FileIO):
            def write(self, data) -> int:
                if len(data) > disk.budget:
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                disk.budget -= len(data)
                return super().write(data)

        self._file = File

    def open(self, path, mode="r", *args, **kwargs):
        if "w" not in mode:
            return builtins.open(path, mode, *args, **kwargs)
        return io.BufferedWriter(self._file(path, "w"))


def test_full_disk_stops_recording_once_and_processing_goes_on(tmp_path, monkeypatch, capfd):
    segments = ["pelvis", "left_thigh", "left_shank", "left_foot"]
    bag = write_imu_bag(tmp_path / "in", synthetic_imu(segments, duration=4.0, with_mag=False))
    out = tmp_path / "out"
    disk = SmallDisk(120_000)
    monkeypatch.setattr(bag_writer, "open", disk.open, raising=False)
    seen = {}

    def keep_nodes(nodes):
        seen.update(nodes)

    result = replay_through_graph(bag, out, speed=1.0, nodes=["orientation_filter", "biofeedback"],
                                  timeout=60, node_parameters={"recorder": {"flush_period_s": 0.2}},
                                  actions=[(3.9, keep_nodes)])
    assert result.published == 4 * 400, "the replay and the processing went on to the end"
    assert result.write_error is not None
    assert "No space left on device" in result.write_error and "press Record" in result.write_error
    log = capfd.readouterr().err
    assert log.count("recording stopped") == 1, "one ERROR, not one per message"
    assert "Traceback" not in log
    recorder, dashboard = seen["recorder"], seen["biofeedback"]
    assert recorder.dropped_while_stopped > 0
    # /diagnostics carries the error, and the dashboard (which shows every status) has it
    status = dashboard._diag["recorder"]
    assert status["level"] == 2 and "No space left" in status["message"]

    # the file ends at its last complete chunk: read without loss of anything it holds
    with pytest.warns(BagRecoveryWarning):
        recovered = list(BagReader(out).raw_messages())
    assert 100 < len(recovered) < result.recorded + 1
    # on the still-full disk repair refuses in one line and changes nothing
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setattr("gait_biofeedback.io.bag.open", SmallDisk(0).open, raising=False)
    with pytest.raises(OSError, match="Nothing was changed in it: free some space"):
        repair(out)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    monkeypatch.undo()  # space freed
    report = repair(out)
    assert report["message_count"] == len(recovered)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BagRecoveryWarning)
        assert [m[:2] for m in BagReader(out).raw_messages()] == [m[:2] for m in recovered]


def test_record_again_after_a_write_error_opens_a_new_folder(tmp_path, monkeypatch):
    """After the clinician frees space, Record goes on in the next folder; the latched calibration
    (and every latched topic) opens it, as it opens a folder after a dashboard stop and start."""
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from gait_biofeedback.nodes.common import init_ros, spin_until
    from gait_biofeedback.nodes.recorder import Recorder

    context = Context()
    init_ros([], context)
    disk = SmallDisk(6_000)
    monkeypatch.setattr(bag_writer, "open", disk.open, raising=False)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    source = Node("clinician", context=context)
    calibration = source.create_publisher(String, "/calibration_note", latched)
    notes = source.create_publisher(String, "/note", 300)
    calibration.publish(String(data="calibration in force"))
    recorder = Recorder(context, output=str(tmp_path / "session"), flush_period_s=0.05,
                        topics=["/calibration_note", "/note"])
    try:
        with spinning(context, recorder, source) as executor:
            assert spin_until(executor, lambda: recorder.received >= 1, timeout=10)
            k = 0
            while recorder.write_error is None and k < 2000:
                notes.publish(String(data=f"note {k} " + "x" * 200))
                k += 1
                spin_until(executor, lambda: False, timeout=0.002)
            assert recorder.write_error is not None, "the budget ran out"
            monkeypatch.undo()
            recorder.start()
            for j in range(3):
                notes.publish(String(data=f"after {j}"))
            assert spin_until(executor, lambda: recorder.writer is not None
                              and recorder.writer.message_count >= 4, timeout=10)
    finally:
        context.try_shutdown()
    assert recorder.sessions == [tmp_path / "session", tmp_path / "session_1"]
    second = [m.data for _, m, _ in BagReader(tmp_path / "session_1").messages()]
    assert second == ["calibration in force", "after 0", "after 1", "after 2"]


def test_a_replay_stopped_and_started_lists_every_folder_and_keeps_the_calibration(tmp_path):
    from gait_biofeedback.core.calibration.sensor_to_segment import (
        SegmentCalibrationResult,
        SessionCalibration,
    )
    from gait_biofeedback.core.calibration.stream import write_calibration_file

    segments = ["chest", "pelvis"]
    bag = write_imu_bag(tmp_path / "in", synthetic_imu(segments, duration=3.0, with_mag=False))
    identity = np.array([1.0, 0, 0, 0])
    results = {s: SegmentCalibrationResult(s, identity, True, 1.0, "x", 0.0) for s in segments}
    write_calibration_file(tmp_path / "session" / "calibration.yaml",
                           SessionCalibration("walking", results, True, ""), "2026-12-01T10:00:00")
    out = tmp_path / "rec"

    def stop(nodes):
        nodes["recorder"].stop()

    def start(nodes):
        nodes["recorder"].start()

    calibration = {"segments": segments, "session_dir": str(tmp_path / "session"), "reload_calibration": True}
    result = replay_through_graph(bag, out, speed=2.0, nodes=["orientation_filter", "calibration"],
                                  timeout=60, actions=[(1.0, stop), (1.5, start)],
                                  node_parameters={"calibration": calibration})
    assert result.outputs == [out, tmp_path / "rec_1"]
    for folder in result.outputs:
        counts = BagReader(folder).message_counts()
        assert counts.get("/calibration/sensor_to_segment") == 1, f"{folder} lacks the calibration in force"
        assert counts["/pelvis/imu/data_raw"] > 50


def _stopped_by(sig: int, command: list[str], bag, speed: float = 1.0) -> tuple[int, str, str]:
    """Start ``gait-biofeedback COMMAND``, replay ``bag`` to it from another process, send ``sig``;
    (exit status, stdout, stderr). A ``run`` is replayed to once it says it runs: its nodes subscribe
    before the replayer, which starts at its first subscriber, matches them (on a busy machine the
    recorder's subscriptions were matched first and the filter lost the first 5-156 of 200 samples)."""
    process = subprocess.Popen([sys.executable, "-m", "gait_biofeedback.cli", *command],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=dict(os.environ, PYTHONUNBUFFERED="1"))  # its lines as it prints them
    said = []
    try:
        if command[0] == "run":
            for line in process.stdout:
                said.append(line)
                if "Ctrl-C stops" in line:
                    break
        subprocess.run([sys.executable, "-m", "gait_biofeedback.nodes.imu_replayer", "--ros-args",
                        "-p", f"bag:={bag}", "-p", f"speed:={speed}", "-p", "wait_for_subscribers_s:=10.0"],
                       timeout=30, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        time.sleep(0.5)
        process.send_signal(sig)
        stdout, stderr = process.communicate(timeout=20)
        stdout = "".join(said) + stdout
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)
    return process.returncode, stdout, stderr


def test_run_record_closes_the_bag_on_sigterm(tmp_path):
    """`gait-biofeedback run` with the session parameter file: raw topics from another process in,
    orientations out and recorded. SIGTERM is a clean stop like Ctrl-C: metadata.yaml and a summary,
    exit 0, no traceback."""
    bag = write_imu_bag(tmp_path / "in", synthetic_imu(["chest"], duration=2.0, with_mag=False))
    out = tmp_path / "live"
    command = ["run", "--nodes", "orientation_filter", "--params", "config/session.yaml",
               "--record", str(out)]
    code, stdout, stderr = _stopped_by(signal.SIGTERM, command, bag, speed=4.0)
    assert code == 0, stderr
    assert "FATAL" not in stderr and "Traceback" not in stderr
    assert "running orientation_filter" in stdout and f"recorded to {out}" in stdout
    assert (out / "metadata.yaml").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("error", BagRecoveryWarning)  # complete: summary and index written
        counts = BagReader(out).message_counts()
    assert counts["/chest/imu/data_raw"] == 200 and counts["/chest/imu/data"] >= 190


def test_record_command_closes_the_bag_on_ctrl_c(tmp_path):
    """Ctrl-C closes the bag, and no longer prints "[FATAL] Exception in 'timers' callback" (rclpy's
    handler raised KeyboardInterrupt inside whichever callback ran)."""
    bag = write_imu_bag(tmp_path / "in", synthetic_imu(["left_foot"], duration=1.0, with_mag=False))
    out = tmp_path / "raw"
    code, _, stderr = _stopped_by(signal.SIGINT, ["record", "-o", str(out)], bag)
    assert code == 0 and "Traceback" not in stderr and "FATAL" not in stderr
    with warnings.catch_warnings():
        warnings.simplefilter("error", BagRecoveryWarning)
        log = [m[-1] for m in BagReader(out).raw_messages() if m[0] == "/left_foot/imu/data_raw"]
    assert (out / "metadata.yaml").exists() and len(log) == 100
    assert np.all(np.diff(log) >= 0)


def test_a_recording_that_cannot_start_leaves_nothing_and_can_be_retried(tmp_path, monkeypatch):
    """Record pressed on a full disk: the reply says why, no folder is left to block the next try;
    the calibration latched while stopped opens the first bag too. A graph that a node refuses to
    start (an unusable calibration_file) leaves no recording folder behind."""
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from gait_biofeedback.nodes.common import init_ros, spin_until
    from gait_biofeedback.nodes.recorder import Recorder

    context = Context()
    init_ros([], context)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    source = Node("clinician", context=context)
    source.create_publisher(String, "/calibration_note", latched).publish(String(data="in force"))
    recorder = Recorder(context, output=str(tmp_path / "session"), autostart=False,
                        topics=["/calibration_note"])
    try:
        with spinning(context, recorder, source) as executor:
            assert spin_until(executor, lambda: recorder.received >= 1, timeout=10)
            monkeypatch.setattr(bag_writer, "open", SmallDisk(0).open, raising=False)
            response = recorder._on_start(None, type("R", (), {})())
            assert not response.success and "could not start recording" in response.message
            assert not (tmp_path / "session").exists() and recorder.sessions == []
            monkeypatch.undo()
            assert recorder.start() == tmp_path / "session"
            assert spin_until(executor, lambda: recorder.written >= 1, timeout=10)
    finally:
        context.try_shutdown()
    assert [m.data for _, m, _ in BagReader(tmp_path / "session").messages()] == ["in force"]

    bag = write_imu_bag(tmp_path / "in", synthetic_imu(["chest"], duration=0.5, with_mag=False))
    (tmp_path / "bad.yaml").write_text("protocol: walking\n")
    refused = {"calibration": {"calibration_file": str(tmp_path / "bad.yaml")}}
    with pytest.raises(ValueError, match="not a usable calibration file"):
        replay_through_graph(bag, tmp_path / "out", nodes=["calibration"], timeout=30,
                             node_parameters=refused)
    assert not (tmp_path / "out").exists()


@pytest.mark.timeout(120)
def test_run_stopped_by_sigterm_publishes_the_strides_it_held(tmp_path):
    """A live session ended by SIGTERM: the strides the gait_events node held for their spatial values
    (the last one of each foot, its next stance never came) go out and are recorded, as at the end of
    a replay; before, they were lost. The feet of a simulated walk, calibrated from a saved file."""
    from gait_biofeedback.core.calibration.stream import write_calibration_file
    from gait_biofeedback.sim.simulator import Phase, SimulationConfig

    feet = ("left_foot", "right_foot")
    bag, session = simulated_bag(tmp_path / "in", SimulationConfig(
        seed=4, segments=feet, phases=[Phase("stand", 2.0), Phase("walk", 8.0)]))
    write_calibration_file(tmp_path / "session" / "calibration.yaml", true_calibration(session),
                           "2026-12-05T10:00:00")
    params = tmp_path / "params.yaml"
    params.write_text(f"orientation_filter:\n  ros__parameters:\n    segments: [{', '.join(feet)}]\n"
                      f"calibration:\n  ros__parameters:\n    segments: [{', '.join(feet)}]\n"
                      f"    session_dir: {tmp_path / 'session'}\n    reload_calibration: true\n")
    out = tmp_path / "live"
    command = ["run", "--nodes", "orientation_filter,calibration,gait_events", "--params", str(params),
               "--record", str(out)]
    code, _, stderr = _stopped_by(signal.SIGTERM, command, bag)
    assert code == 0 and "Traceback" not in stderr, stderr
    reader = BagReader(out)
    last_ic = {}
    for _, m, _ in reader.messages(["/gait/events"]):
        if m.type == m.INITIAL_CONTACT:
            last_ic[m.side] = m.header.stamp
    closed = {m.side: m.header.stamp for _, m, _ in reader.messages(["/gait/cycles"])}
    assert len(last_ic) == 2 and closed == last_ic  # each foot's last heel strike closed a recorded stride
