"""orientation_filter node: raw topics in → orientations out; same numbers as the offline path;
NaN samples, duplicates and time going backwards handled as issue 3 says."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import simulated_bag, spinning, stamp_ns

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.orientation.stream import SegmentOrientationTracker, track_orientation
from gait_biofeedback.graph import replay_through_graph
from gait_biofeedback.io.bag import BagReader, read_imu_bag
from gait_biofeedback.sim.simulator import SCENARIOS

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90)]
SEGMENTS = ["left_foot", "pelvis"]


@pytest.fixture(scope="module")
def walk_bag(tmp_path_factory):
    return simulated_bag(tmp_path_factory.mktemp("walk") / "in",
                         SCENARIOS["walk"](duration=4.0, segments=tuple(SEGMENTS)))


def _recorded_orientations(path, segment):
    stamps, quats = [], []
    for _, msg, _ in BagReader(path).messages([f"/{segment}/imu/data"]):
        stamps.append(stamp_ns(msg.header.stamp))
        o = msg.orientation
        quats.append((o.w, o.x, o.y, o.z))
    return np.array(stamps), np.array(quats)


def test_live_graph_equals_offline_tracker(walk_bag, tmp_path):
    bag, session = walk_bag
    out = tmp_path / "out"
    replay_through_graph(bag, out, speed=2.0, nodes=["orientation_filter"], timeout=60,
                         node_parameters={"orientation_filter": {"segments": SEGMENTS}})
    recorded = read_imu_bag(bag)
    for segment in SEGMENTS:
        stamps, live = _recorded_orientations(out, segment)
        _, offline, _ = track_orientation(recorded[segment])
        assert len(live) == len(recorded[segment].t), "one orientation per raw sample"
        np.testing.assert_array_equal(stamps, np.round(recorded[segment].t * 1e9).astype(np.int64))
        # same core object, same samples, same pairing, same nominal rate: the same numbers, bit for bit
        np.testing.assert_array_equal(live, offline)
        # and it is the right attitude: within 5 deg of the truth after the start-up second
        err = np.degrees(quat.angle_between(live, session.truth.sensor_orientation[segment]))
        assert np.median(err[100:]) < 5.0, f"{segment}: median error {np.median(err[100:]):.1f} deg"


def test_tracker_skips_nan_duplicates_and_bad_stamps_and_resets_only_on_a_real_restart():
    tracker = SegmentOrientationTracker("chest", rate_hz=100.0, startup_s=0.5)
    still = ((0.0, 0.0, 0.0), (0.0, 0.0, 9.81))
    out = []
    ms = 1_000_000
    for k in range(100):
        out += tracker.update(10_000 * ms + k * 10 * ms, *still)
    assert len(out) == 97 and tracker.startup_quiet, "30 ms (3 samples) held by the reorder window"
    assert tracker.update(11_000 * ms, (np.nan, 0.0, 0.0), (0.0, 0.0, 9.81)) == []
    assert tracker.update(10_990 * ms, *still) == [], "same stamp as a sample before: a duplicate"
    assert tracker.update(11_000 * ms, (0.0, 0.0, 0.0), (0.0, 0.0, 1e6)) == [], "out of range: a glitch"
    assert tracker.counts["nan_skipped"] == 1 and tracker.counts["duplicates"] == 1
    assert tracker.counts["out_of_range"] == 1
    tracker.notices.pop()
    # one stamp 6 s back (5.99 s behind the newest sample), the stream goes on: dropped, nothing reset
    assert tracker.update(5_000 * ms, *still) == []
    assert len(tracker.update(11_000 * ms, *still)) == 1
    assert tracker.counts["bad_stamps"] == 1 and tracker.counts["time_resets"] == 0
    (notice,) = tracker.notices.pop()
    assert "dropped 1 sample(s) stamped 5.990 s behind the stream (a clock glitch)" in notice.text
    # the stream goes on from 5 s (a recording replayed again): a reset, once 3 samples confirm it
    more = []
    for k in range(60):
        more += tracker.update(5_000 * ms + k * 10 * ms, *still)
    assert tracker.counts["time_resets"] == 1
    assert any("time went back 6.000 s and went on from there" in n.text for n in tracker.notices.pop())
    more += tracker.flush(end=True)
    assert len(more) == 3 + 60, "the 3 held before the restart, then every sample after it"
    assert not any(s.recovering for s in more[:3]) and all(s.recovering for s in more[3:]), \
        "after the restart the attitude is re-acquired, its samples marked"
    for k in range(4):
        more += tracker.update(8_000 * ms + k * 10 * ms, *still)
    assert tracker.counts["gaps"] == 1, "2.4 s without data, confirmed by the samples after it"


def test_node_counts_bad_samples_and_reports_them(ros_context):
    from rclpy.node import Node
    from sensor_msgs.msg import Imu

    from gait_biofeedback.nodes.common import spin_until
    from gait_biofeedback.nodes.orientation_filter import OrientationFilterNode
    from gait_biofeedback.wire.stamps import s_to_stamp
    from gait_biofeedback.wire.topics import SENSOR_QOS

    node = OrientationFilterNode(ros_context, segments=["chest"], startup_s=0.2, diagnostics_period_s=0.2,
                                 recover_s=0.2)  # the 0.3 s after the restart re-acquire the attitude
    source = Node("source", context=ros_context)
    pub = source.create_publisher(Imu, "chest/imu/data_raw", SENSOR_QOS)
    outputs, diagnostics = [], []
    source.create_subscription(Imu, "chest/imu/data", outputs.append, 100)
    from diagnostic_msgs.msg import DiagnosticArray

    source.create_subscription(DiagnosticArray, "/diagnostics", diagnostics.append, 10)
    with spinning(ros_context, node, source) as executor:
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0, timeout=5)
        stamps = [100.0 + k * 0.01 for k in range(60)] + [50.0 + k * 0.01 for k in range(30)]
        for k, t in enumerate(stamps):
            msg = Imu()
            msg.header.stamp = s_to_stamp(t)
            msg.header.frame_id = "chest_imu" if k < 70 else "pelvis_imu"
            msg.linear_acceleration.z = float("nan") if k == 40 else 9.81
            pub.publish(msg)
            executor.spin_once(timeout_sec=0.002)
        assert spin_until(executor, lambda: len(outputs) >= 89, timeout=5)
        spin_until(executor, lambda: len(diagnostics) >= 2, timeout=3)
    counts = node.trackers["chest"].counts
    assert counts["nan_skipped"] == 1 and counts["time_resets"] == 1
    assert len(outputs) == 89
    assert node.wrong_frame["chest"] == 20
    status = diagnostics[-1].status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert values["nan_skipped"] == "1" and values["time_resets"] == "1"
    assert status.level == b"\x01" and "frame_id" in status.message


def test_node_names_a_dropout_and_a_glitch_on_diagnostics(ros_context):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from sensor_msgs.msg import Imu

    from gait_biofeedback.nodes.common import spin_until
    from gait_biofeedback.nodes.orientation_filter import OrientationFilterNode
    from gait_biofeedback.wire.stamps import s_to_stamp
    from gait_biofeedback.wire.topics import SENSOR_QOS

    node = OrientationFilterNode(ros_context, segments=["chest"], startup_s=0.2, diagnostics_period_s=0.1,
                                 recover_s=0.3)
    source = Node("source", context=ros_context)
    pub = source.create_publisher(Imu, "chest/imu/data_raw", SENSOR_QOS)
    said: list[str] = []
    source.create_subscription(DiagnosticArray, "/diagnostics",
                               lambda m: said.extend(s.message for s in m.status), 10)
    with spinning(ros_context, node, source) as executor:
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0, timeout=5)
        stamps = [k * 0.01 for k in range(100)] + [2.0 + k * 0.01 for k in range(100)]
        for k, t in enumerate(stamps):
            msg = Imu()
            msg.header.stamp = s_to_stamp(100.0 + t)
            msg.header.frame_id = "chest_imu"
            msg.linear_acceleration.z = 1e6 if k == 150 else 9.81
            pub.publish(msg)
            executor.spin_once(timeout_sec=0.002)
            if k == 99 or k == 160:
                spin_until(executor, lambda: False, timeout=0.25)  # a report or two
        spin_until(executor, lambda: any("out of range" in s for s in said), timeout=3)
    text = " | ".join(said)
    assert "sensor dropout: 1.01 s without data (attitude re-acquired)" in text or (
        "sensor dropout: re-acquiring the attitude" in text), text
    assert "1 sample(s) out of range rejected (glitch)" in text, text
    assert "6D (no magnetometer)" in text
