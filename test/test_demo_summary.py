"""The demo's summary says when raw samples never reached the recording (a machine that did not keep
up with the live graph), with what to do, and says nothing of it when every sample arrived."""

from __future__ import annotations

from conftest import synthetic_imu

from gait_biofeedback.demo import summarize
from gait_biofeedback.io.bag import BagReader, BagWriter, write_imu_bag


def _recorded(source, output, keep):
    with BagReader(source) as reader, BagWriter(output, flush_period_s=None) as writer:
        for i, (topic, type_name, data, log_ns) in enumerate(reader.raw_messages()):
            if keep(i, topic):
                writer.write_serialized(topic, type_name, data, log_ns)
    return output


def test_lost_raw_samples_are_said_with_what_to_do(tmp_path):
    source = write_imu_bag(tmp_path / "in", synthetic_imu(["left_foot", "right_foot"], duration=1.0))
    complete = _recorded(source, tmp_path / "complete", lambda i, topic: True)
    text = summarize(source, complete, 1.0, 400, speed=1.5)
    assert "IMU: 200 raw samples recorded" in text and "LOST" not in text

    lossy = _recorded(source, tmp_path / "lossy",
                      lambda i, topic: not (topic.endswith("data_raw") and i % 4 == 0))
    lines = [line for line in summarize(source, lossy, 1.0, 400, speed=1.5).splitlines() if "LOST" in line]
    recorded = sum(n for t, n in BagReader(lossy).message_counts().items() if t.endswith("data_raw"))
    assert len(lines) == 1 and lines[0].startswith(f"LOST: {200 - recorded} of the 200 raw samples of the")
    assert f"({100 * (200 - recorded) / 200:.1f} %)" in lines[0] and "at 1.5x" in lines[0]
    assert "demo --speed 1" in lines[0] and f"analyze {source} -o OUT --calibrate-at auto" in lines[0]
    # a replay cut short (Ctrl-C, a full disk) is said as such, not blamed on the machine
    text = summarize(source, lossy, 1.0, 400, cut_short="the replay was interrupted")
    (line,) = [x for x in text.splitlines() if "LOST" in x]
    assert line.endswith("never reached the output: the replay was interrupted")


def test_at_real_time_the_advice_is_not_to_replay_slower(tmp_path):
    """A machine that lost samples at 1x (a CPU hog beside it) is told to close programs or analyze offline,
    not to replay at the speed it already ran at."""
    source = write_imu_bag(tmp_path / "in", synthetic_imu(["left_foot"], duration=1.0))
    lossy = _recorded(source, tmp_path / "lossy",
                      lambda i, topic: not (topic.endswith("data_raw") and i % 4 == 0))
    (line,) = [x for x in summarize(source, lossy, 1.0, 200, speed=1.0).splitlines() if "LOST" in x]
    assert "even at real time: close other programs" in line and "--speed 1" not in line
    assert f"analyze {source} -o OUT --calibrate-at auto" in line
