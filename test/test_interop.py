"""Every bag the project writes decodes, message by message, in the PyPI ``rosbags`` library and in
``mcap-ros2-support``: what ``simulate``, ``import``, ``analyze`` and the recorder of a live graph write."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import rosbags_typestore

from gait_biofeedback.cli import main
from gait_biofeedback.io.bag import bag_files


def _rosbags_decode_all(bag: Path) -> dict[str, int]:
    from rosbags.highlevel import AnyReader

    typestore = rosbags_typestore()
    counts: dict[str, int] = {}
    with AnyReader([bag], default_typestore=typestore) as reader:
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)  # raises on a size mismatch
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    return counts


def _mcap_ros2_decode_all(bag: Path) -> dict[str, int]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    counts: dict[str, int] = {}
    for file in bag_files(bag):
        with open(file, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _, channel, _, decoded in reader.iter_decoded_messages():
                assert decoded is not None
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def _decodes_everywhere(bag: Path, expected_topics: set[str]) -> dict[str, int]:
    a, b = _rosbags_decode_all(bag), _mcap_ros2_decode_all(bag)
    assert a == b
    assert expected_topics <= set(a), sorted(set(a))
    return a


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sim") / "walk"
    assert main(["simulate", "-o", str(out), "--scenario", "walk", "--duration", "20"]) == 0  # 28 s
    return out


def test_simulated_and_analyzed_bags_decode(simulated, tmp_path):
    truth = {f"/ground_truth/{t}" for t in ("joint_states", "gait/events", "calibration/sensor_to_segment")}
    counts = _decodes_everywhere(simulated, {*truth, "/left_foot/imu/mag"})
    assert counts["/ground_truth/joint_states"] == 2800
    out = tmp_path / "offline"
    assert main(["analyze", str(simulated), "-o", str(out), "--calibrate-at", "13:walking"]) == 0
    outputs = {"/joint_states", "/skeleton", "/gait/events", "/gait/cycles", "/gait/stride_space",
               "/activity/state", "/calibration/sensor_to_segment", "/pelvis/imu/data", "/tf"}
    counts = _decodes_everywhere(out, outputs)
    assert counts["/joint_states"] > 0
    assert counts["/tf"] == counts["/joint_states"]  # the body's frames, one per joint state


def test_imported_csv_decodes(tmp_path):
    t = np.arange(200) / 100.0
    rows = ["time,ax,ay,az,gx,gy,gz"] + [f"{ti:.2f},0,0,9.81,0.01,0,0" for ti in t]
    (tmp_path / "rec.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "map.yaml").write_text("chest: {acc: [ax, ay, az], gyr: [gx, gy, gz]}\n")
    out = tmp_path / "imported"
    assert main(["import", "csv", str(tmp_path / "rec.csv"), "--mapping", str(tmp_path / "map.yaml"),
                 "-o", str(out)]) == 0
    assert _decodes_everywhere(out, {"/chest/imu/data_raw"}) == {"/chest/imu/data_raw": 200}


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_recording_of_the_live_graph_decodes(simulated, tmp_path):
    from gait_biofeedback.graph import replay_through_graph

    out = tmp_path / "live"
    replay_through_graph(simulated, out, speed=4.0, nodes=["orientation_filter", "activity_monitor"],
                         timeout=90,
                         node_parameters={"orientation_filter": {"segments": ["left_foot", "chest"]}})
    _decodes_everywhere(out, {"/left_foot/imu/data", "/chest/imu/data", "/activity/state", "/diagnostics",
                              "/left_foot/imu/data_raw"})
