"""rosbag2/MCAP I/O: round trips, interoperability with rosbags and mcap, damage recovery, splits."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import rosbags_typestore, stamp_ns
from mcap.reader import make_reader
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, MagneticField
from std_msgs.msg import String

from gait_biofeedback.core.segments import SEGMENTS, ImuSeries
from gait_biofeedback.io.bag import (
    BagReader,
    BagRecoveryWarning,
    BagWriter,
    read_imu_bag,
    repair,
    write_imu_bag,
)
from gait_biofeedback.io.mcap_file import McapFile
from gait_biofeedback.io.schemas import SEPARATOR, schema_text
from gait_biofeedback.wire.cdr import IMU_DOUBLES, decode_stamped
from gait_biofeedback.wire.imu import encode_series, series_messages
from gait_biofeedback_msgs.msg import GaitEvent, SegmentCalibration, SegmentCalibrationArray


def ns_grid_imu(with_mag: bool, n: int = 150, seed: int = 1) -> dict[str, ImuSeries]:
    """8 segments of random samples; times on the 1 ns grid (jittered steps), one segment at epoch scale.
    Not conftest's ``synthetic_imu``: its ``t0 + k / rate`` times do not all come back bit for bit from
    integer ns at epoch scale (t0 = 1.7e9: 3 of 150), and the round trips here are checked to the bit."""
    rng = np.random.default_rng(seed)
    out = {}
    for k, segment in enumerate(SEGMENTS):
        ns = 3_000_000_000 + np.cumsum(rng.integers(9_000_000, 11_000_000, n))
        t = ns / 1e9
        if k == 0:
            t = np.sort(1.7e9 + rng.uniform(0, 10, n))  # any float this large is on the 1 ns grid
        mag = rng.normal(size=(n, 3)) * 5e-5 if with_mag else None
        out[segment] = ImuSeries(segment, t, rng.normal(size=(n, 3)) * 9.81, rng.normal(size=(n, 3)), mag)
    return out


def gait_event(i: int) -> GaitEvent:
    msg = GaitEvent(side=GaitEvent.SIDE_RIGHT, type=GaitEvent.TERMINAL_CONTACT, event_index=i)
    msg.header.stamp.sec, msg.header.frame_id = 10 + i, "right_foot"
    msg.detection_latency, msg.signal_value = 0.01 * i, -0.5
    return msg


def calibration() -> SegmentCalibrationArray:
    segments = [
        SegmentCalibration(segment=s, sensor_frame=f"{s}_imu", valid=True, quality=0.9, message="")
        for s in ("left_shank", "right_shank")
    ]
    segments[1].rotation.x, segments[1].rotation.w = 0.6, 0.8
    msg = SegmentCalibrationArray(protocol="walking", segments=segments)
    msg.header.frame_id = "world"
    return msg


def string_msg(i: int) -> String:
    return String(data=f"message {i:05d} " + "x" * 40)


@pytest.mark.parametrize(("with_mag", "block"), [(True, None), (False, None), (True, 7)])
def test_imu_series_round_trip_is_exact(tmp_path: Path, with_mag: bool, block: int | None,
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """Also when the reader decodes a few messages at a time (an hour is read in blocks)."""
    if block is not None:
        monkeypatch.setattr("gait_biofeedback.io.imu_bag.DECODE_BLOCK", block)
    imu = ns_grid_imu(with_mag)
    bag = write_imu_bag(tmp_path / "imu", imu)
    back = read_imu_bag(bag)
    assert set(back) == set(SEGMENTS)
    for segment, series in imu.items():
        got = back[segment]
        assert got.frame_id == f"{segment}_imu"
        np.testing.assert_array_equal(got.t, series.t)
        np.testing.assert_array_equal(got.acc, series.acc)
        np.testing.assert_array_equal(got.gyr, series.gyr)
        if with_mag:
            np.testing.assert_array_equal(got.mag, series.mag)
        else:
            assert got.mag is None
    assert set(read_imu_bag(bag, segments=["chest"])) == {"chest"}
    with pytest.raises(ValueError, match="head"):
        read_imu_bag(bag, segments=["head"])


def test_fast_cdr_matches_rclpy_messages() -> None:
    series = ns_grid_imu(with_mag=True, n=5)["left_foot"]
    _, imu_payloads, mag_payloads = encode_series(series)
    messages = list(series_messages(series))
    imu_msgs = [m for topic, m, _ in messages if topic == "/left_foot/imu/data_raw"]
    mag_msgs = [m for topic, m, _ in messages if topic == "/left_foot/imu/mag"]
    assert [deserialize_message(p, Imu) for p in imu_payloads] == imu_msgs
    assert [deserialize_message(p, MagneticField) for p in mag_payloads] == mag_msgs
    assert imu_msgs[0].orientation_covariance[0] == -1.0
    assert all(t == stamp_ns(m.header.stamp) for _, m, t in messages)
    ns, doubles, frame_id = decode_stamped([serialize_message(m) for m in imu_msgs], Imu, IMU_DOUBLES)
    assert frame_id == "left_foot_imu"
    assert ns.tolist() == [stamp_ns(m.header.stamp) for m in imu_msgs]
    np.testing.assert_array_equal(doubles[:, 25:28], series.acc)


def test_schema_text_lists_each_dependency_once_depth_first() -> None:
    text = schema_text("sensor_msgs/msg/Imu")
    names = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert names == [
        "MSG: std_msgs/Header",
        "MSG: builtin_interfaces/Time",
        "MSG: geometry_msgs/Quaternion",
        "MSG: geometry_msgs/Vector3",
    ]
    assert text.count(SEPARATOR) == 4
    assert "MSG: gait_biofeedback_msgs/SegmentCalibration" in schema_text(
        "gait_biofeedback_msgs/msg/SegmentCalibrationArray"
    )


def test_custom_messages_round_trip_in_log_time_order(tmp_path: Path) -> None:
    events = [gait_event(i) for i in range(6)]
    with BagWriter(tmp_path / "custom") as writer:
        for i in (3, 1, 5):  # out of order across two chunks
            writer.write("/gait/events", events[i], 1000 + i)
        writer.flush()
        for i in (0, 4, 2):
            writer.write("/gait/events", events[i], 1000 + i)
        writer.write("/calibration/sensor_to_segment", calibration(), 999)
    reader = BagReader(tmp_path / "custom")
    assert reader.topics() == {
        "/gait/events": "gait_biofeedback_msgs/msg/GaitEvent",
        "/calibration/sensor_to_segment": "gait_biofeedback_msgs/msg/SegmentCalibrationArray",
    }
    got = list(reader.messages())
    assert [t for _, _, t in got] == list(range(999, 1006))
    assert got[0][1] == calibration()
    assert [m for _, m, _ in got[1:]] == events
    window = list(reader.messages(topics=["/gait/events"], start_ns=1002, stop_ns=1004))
    assert [m.event_index for _, m, _ in window] == [2, 3]


def test_rosbags_reads_imu_and_custom_messages(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    imu = {s: v for s, v in ns_grid_imu(with_mag=True, n=20).items() if s in ("pelvis", "chest")}
    bag = write_imu_bag(tmp_path / "interop", imu, extra=[("/gait/events", gait_event(7), 3_100_000_000)])
    typestore = rosbags_typestore()
    with AnyReader([bag], default_typestore=typestore) as reader:
        assert reader.message_count == 2 * 2 * 20 + 1
        by_topic = {c.topic: c for c in reader.connections}
        conn = by_topic["/chest/imu/data_raw"]
        _, t, raw = next(reader.messages(connections=[conn]))
        msg = reader.deserialize(raw, conn.msgtype)
        assert msg.header.frame_id == "chest_imu"
        assert msg.linear_acceleration.x == imu["chest"].acc[0, 0]
        assert msg.orientation_covariance[0] == -1.0
        conn = by_topic["/gait/events"]
        _, t, raw = next(reader.messages(connections=[conn]))
        event = reader.deserialize(raw, conn.msgtype)
        assert (t, event.event_index, event.header.frame_id) == (3_100_000_000, 7, "right_foot")


def write_in_flushed_batches(folder: Path, batches: int = 4, per_batch: int = 30) -> tuple[Path, list[int]]:
    """String messages written in batches with flush() after each; returns file and size after each."""
    sizes = []
    with BagWriter(folder) as writer:
        for b in range(batches):
            for i in range(b * per_batch, (b + 1) * per_batch):
                writer.write("/chatter", string_msg(i), 1_000 + i)
            writer.flush()
            sizes.append(writer.files[0].stat().st_size)
    return writer.files[0], sizes


def test_open_chunk_reaches_disk_on_flush(tmp_path: Path) -> None:
    """The crash-safety point: a flush writes the open chunk and hands the file to the OS."""
    writer = BagWriter(tmp_path / "open", flush_period_s=0.05)
    for i in range(10):
        writer.write("/chatter", string_msg(i), i)
    time.sleep(0.06)
    writer.maybe_flush()  # flush_period_s has passed
    copy = tmp_path / "copy.mcap"
    shutil.copy(writer.files[0], copy)  # what a kill -9 now would leave
    with pytest.warns(BagRecoveryWarning, match=r"copy\.mcap.*recovered 10 messages"):
        reader = BagReader(copy)
    assert [deserialize_message(d, String) for _, _, d, _ in reader.raw_messages()] == [
        string_msg(i) for i in range(10)
    ]
    writer.close()
    writer.close()  # idempotent
    assert McapFile.open(writer.files[0]).complete


def test_truncated_file_reads_complete_chunks_and_repairs(tmp_path: Path) -> None:
    file, sizes = write_in_flushed_batches(tmp_path / "full")
    data = file.read_bytes()
    cuts = {
        3: 0,
        sizes[0] - 1: 30,
        sizes[0] + 20: 30,
        sizes[1] + 1: 60,
        sizes[2] + 20: 90,
        len(data) - 1: 120,
    }
    for cut, expected in cuts.items():
        cut_file = tmp_path / f"cut_{cut}.mcap"
        cut_file.write_bytes(data[:cut])
        with pytest.warns(BagRecoveryWarning, match=rf"cut_{cut}\.mcap.*recovered {expected} messages"):
            reader = BagReader(cut_file)
        got = [deserialize_message(d, String) for _, _, d, _ in reader.raw_messages()]
        assert got == [string_msg(i) for i in range(expected)], f"cut at byte {cut}"
        reader.close()

        report = repair(cut_file)
        assert report["files"][0]["status"] == "repaired"
        assert report["message_count"] == expected
        assert Path(f"{cut_file}.orig").read_bytes() == data[:cut]
        with open(cut_file, "rb") as f:  # the mcap library finds a valid summary
            summary = make_reader(f).get_summary()
            assert summary is not None and summary.statistics.message_count == expected
        repaired = BagReader(cut_file)
        assert repaired.warnings == []
        assert [deserialize_message(d, String) for _, _, d, _ in repaired.raw_messages()] == got


def test_repair_of_crashed_bag_folder_rebuilds_metadata(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    folder = tmp_path / "crashed"
    writer = BagWriter(folder)
    for i in range(50):
        writer.write("/chatter", string_msg(i), 5_000 + i)
    writer.flush()  # then the process dies: no summary, no metadata.yaml
    assert not (folder / "metadata.yaml").exists()
    report = repair(folder)
    assert report["metadata"] == "created"
    assert report["files"][0]["status"] == "repaired"
    with AnyReader([folder]) as reader:
        assert reader.message_count == 50
        assert reader.start_time == 5_000
    assert repair(folder)["metadata"] == "ok"
    meta = folder / "metadata.yaml"
    meta.write_text(meta.read_text().replace("message_count: 50", "message_count: 7"))
    assert repair(folder)["metadata"] == "rebuilt"
    assert "message_count: 7" in (folder / "metadata.yaml.orig").read_text()
    assert "message_count: 50" in meta.read_text()
    writer.close()  # the dead writer's handle; its file was replaced


def test_split_by_size_reads_back_in_order(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    with BagWriter(tmp_path / "split", split_size_bytes=20_000, chunk_size=4_000,
                   compression="lz4") as writer:
        for i in range(1500):
            writer.write("/chatter", string_msg(i), 1_000_000 + i)
    assert len(writer.files) >= 3
    meta = (tmp_path / "split" / "metadata.yaml").read_text()
    assert all(f.name in meta for f in writer.files)
    reader = BagReader(tmp_path / "split")
    assert [t for _, _, _, t in reader.raw_messages()] == [1_000_000 + i for i in range(1500)]
    assert reader.message_counts() == {"/chatter": 1500}
    assert (reader.start_time_ns, reader.duration_ns) == (1_000_000, 1499)
    with AnyReader([tmp_path / "split"]) as any_reader:
        assert any_reader.message_count == 1500


def test_split_by_duration(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "minutes", split_duration_s=1.0) as writer:
        for i in range(30):
            writer.write("/chatter", string_msg(i), i * 100_000_000)  # 3 s of log time
    assert [f.name for f in writer.files] == [f"minutes_{k}.mcap" for k in range(3)]


def test_bad_paths_give_clear_errors(tmp_path: Path) -> None:
    missing = tmp_path / "nope"
    with pytest.raises(FileNotFoundError, match="nope"):
        BagReader(missing)
    with pytest.raises(FileNotFoundError, match="nope"):
        repair(missing)
    text = tmp_path / "notes.mcap"
    text.write_text("hello, not a recording\n")
    with pytest.raises(ValueError, match=r"notes\.mcap is not an MCAP file"):
        BagReader(text)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"empty.*without \.mcap files"):
        BagReader(tmp_path / "empty")
    write_in_flushed_batches(tmp_path / "taken", batches=1)
    with pytest.raises(FileExistsError, match="exists and is not empty: write to another folder or remove"):
        BagWriter(tmp_path / "taken")
    with pytest.raises(OSError, match=r"cannot write the bag folder /proc/gait_biofeedback_out .*: choose a"):
        BagWriter("/proc/gait_biofeedback_out")  # a folder nobody may create, root included
    with pytest.raises(ValueError, match="compression"):
        BagWriter(tmp_path / "other", compression="gzip")
    with BagWriter(tmp_path / "typed") as writer:
        writer.write("/chatter", string_msg(0), 0)
        with pytest.raises(ValueError, match="/chatter carries std_msgs/msg/String"):
            writer.write("/chatter", gait_event(0), 1)


CHILD_WRITER = """
import sys, time
from std_msgs.msg import String
from gait_biofeedback.io.bag import BagWriter
writer = BagWriter(sys.argv[1], flush_period_s=0.1)
i = 0
while True:
    writer.write("/chatter", String(data=f"message {i:05d} " + "x" * 40), 1000 + i)
    i += 1
    if i % 200 == 0:
        writer.flush()
        print(i, flush=True)
    time.sleep(0.0005)
"""


def test_bag_survives_kill_9(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys

    folder = tmp_path / "killed"
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD_WRITER, str(folder)], stdout=subprocess.PIPE, text=True
    )
    try:
        flushed = [int(child.stdout.readline()) for _ in range(3)]
        time.sleep(0.15)  # more messages, some flushed by flush_period_s only
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
    with pytest.warns(BagRecoveryWarning, match="killed_0.mcap"):
        reader = BagReader(folder)
    got = [deserialize_message(d, String) for _, _, d, _ in reader.raw_messages()]
    assert len(got) >= flushed[-1]
    assert got == [string_msg(i) for i in range(len(got))]
    assert repair(folder)["message_count"] == len(got)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_mcap_writer_indexes_read_by_the_mcap_library(tmp_path: Path, compression: str) -> None:
    """The project's MCAP writer (io/mcap_writer.py) against the PyPI mcap reader: three channels, 4 kB
    chunks (many of them, a channel registered after the first closed), log times out of order within
    a chunk. The summary's statistics and chunk indexes, and the messages read through the indexes in
    log-time order, are what was written."""
    writer = BagWriter(tmp_path / "bag", compression=compression, chunk_size=4096)
    written = []
    for i in range(400):
        topic = ("/a", "/b")[i % 2] if i < 200 else ("/a", "/b", "/late")[i % 3]
        log = 1_000_000 * i + (500_000 if i % 7 == 3 else 0) - (700_000 if i % 11 == 5 else 0)
        writer.write(topic, string_msg(i), log)
        written.append((log, topic, serialize_message(string_msg(i))))
    writer.close()
    with open(writer.files[0], "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary.statistics.message_count == 400
        assert summary.statistics.chunk_count == len(summary.chunk_indexes) >= 8
        counts = {summary.channels[c].topic: n for c, n in summary.statistics.channel_message_counts.items()}
        assert counts == {t: sum(w[1] == t for w in written) for t in ("/a", "/b", "/late")}
        assert summary.statistics.message_start_time == min(w[0] for w in written)
        assert summary.statistics.message_end_time == max(w[0] for w in written)
        got = [(m.log_time, c.topic, m.data) for _, c, m in reader.iter_messages(log_time_order=True)]
    assert got == sorted(written, key=lambda w: w[0])
    assert McapFile.open(writer.files[0]).complete
