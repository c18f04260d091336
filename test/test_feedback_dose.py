"""The dose recorded (issue 49 item 6): FeedbackGiven messages round-trip through a bag and the PyPI
``rosbags`` and ``mcap-ros2-support`` readers, and the report's dose section counts them.

A hand-made 12-minute session: a stride every 1.2 s whose cadence is in its band on every 4th stride
before 6 min and on 3 strides of 4 after; feedback given on every 3rd stride (words when outside the
band, a cue when in). The expected counts are counted here from that pattern."""

from __future__ import annotations

import math

import pytest
from conftest import rosbags_typestore, spinning

from gait_biofeedback.core.biofeedback.evaluator import Cue
from gait_biofeedback.core.biofeedback.instruction import Instruction, Rule
from gait_biofeedback.core.biofeedback.schedule import KIND_CUE, KIND_INSTRUCTION, Given
from gait_biofeedback.core.stamps import NS_PER_S

STRIDE_S, STRIDES = 1.2, 600
LOW, HIGH = 96 / 60, 126 / 60
RULE = Rule("quicker_steps", "cadence", "below", 30, "Take quicker steps", "Perry & Burnfield 2010")


def in_band(k: int) -> bool:
    return k % 4 == 0 if k * STRIDE_S < 360 else k % 4 != 0


def stamp(k: int) -> int:
    return round((1.0 + k * STRIDE_S) * NS_PER_S)


def _cue(k: int) -> Cue:
    measured = 110 / 60 if in_band(k) else 80 / 60
    error = 0.0 if in_band(k) else measured - LOW
    return Cue("cadence", "", "Hz", measured, LOW, HIGH, error, 0 if in_band(k) else 1, 0.0, 0.0, k, stamp(k))


def _given(k: int) -> Given:
    c = _cue(k)
    instruction = Instruction(RULE, "", RULE.text, c, k == 0, k + 1)
    kind = KIND_CUE if in_band(k) else KIND_INSTRUCTION
    return Given(instruction, kind, "faded", 1.0 - k / 1200, k, stamp(k))


def _cycle(k: int):
    from gait_biofeedback.wire.stamps import ns_to_stamp
    from gait_biofeedback_msgs.msg import GaitCycle

    msg = GaitCycle(side=k % 2, stride_index=k // 2, stride_time=2 * STRIDE_S, stance_time=1.45,
                    swing_time=0.95, stance_fraction=0.6, swing_fraction=0.4, step_time=STRIDE_S,
                    cadence=1.0 / STRIDE_S, plausible=True)
    msg.header.stamp = ns_to_stamp(stamp(k))
    msg.start = ns_to_stamp(stamp(k) - round(2 * STRIDE_S * NS_PER_S))
    return msg


def _session(tmp_path):
    from gait_biofeedback.io.bag import BagWriter
    from gait_biofeedback.wire import topics
    from gait_biofeedback.wire.biofeedback import cue_msg, given_msg

    path = tmp_path / "session"
    with BagWriter(path) as writer:
        for k in range(STRIDES):
            writer.write(topics.GAIT_CYCLES.absolute(), _cycle(k), stamp(k))
            writer.write(topics.CUES.absolute(), cue_msg(_cue(k), "left_foot"), stamp(k))
            if k % 3 == 0:
                writer.write(topics.GIVEN.absolute(), given_msg(_given(k), "left_foot"), stamp(k))
    return path


def test_feedback_given_round_trips_through_rosbags_and_mcap(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    from gait_biofeedback.io.bag import bag_files
    from gait_biofeedback.wire.biofeedback import given_of

    path = _session(tmp_path)
    with AnyReader([path], default_typestore=rosbags_typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == "/biofeedback/given"]
        assert [c.msgtype for c in connections] == ["gait_biofeedback_msgs/msg/FeedbackGiven"]
        decoded = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections)]
    with open(bag_files(path)[0], "rb") as f:
        mcap = [m for _, channel, _, m in make_reader(f, decoder_factories=[DecoderFactory()])
                .iter_decoded_messages() if channel.topic == "/biofeedback/given"]
    assert len(decoded) == len(mcap) == 200
    k = 3 * 150  # stride 450: after 6 min, 450 % 4 = 2: in band, a cue
    for got in (given_of(decoded[150]), given_of(mcap[150])):
        assert got == {"rule": "quicker_steps", "text": "Take quicker steps", "quantity": "cadence",
                       "side": "", "unit": "Hz", "schedule": "faded", "measured": 110 / 60, "band_low": LOW,
                       "band_high": HIGH, "error": 0.0, "schedule_rate": 1.0 - k / 1200, "kind": KIND_CUE,
                       "stride_index": k, "block_strides": 1, "block_in_band": 0, "stamp_ns": stamp(k)}
    assert decoded[1].kind == KIND_INSTRUCTION and math.isclose(decoded[1].error, 80 / 60 - LOW)


def test_the_report_s_dose_section_counts_in_band_strides_cues_and_instructions(tmp_path):
    from test_report import FORBIDDEN

    from gait_biofeedback.report.dose import dose_section, instructions_recorded
    from gait_biofeedback.report.extract import read_session

    data = read_session(_session(tmp_path))
    assert instructions_recorded(data)
    section = dose_section(data)
    table = next(b for b in section.blocks if hasattr(b, "rows"))
    assert table.header[1:3] == ["in range, first 5 min", "in range, last 5 min"]
    # times from the first message (stride 0); the session lasts 599 x 1.2 = 718.8 s
    first = [k for k in range(STRIDES) if k * STRIDE_S <= 300]
    last = [k for k in range(STRIDES) if k * STRIDE_S >= 718.8 - 300 - 1e-9]
    given = range(0, STRIDES, 3)
    shares = [f"{100 * sum(map(in_band, ks)) / len(ks):.0f} % of {len(ks)}" for ks in (first, last)]
    cues, words = sum(in_band(k) for k in given), sum(not in_band(k) for k in given)
    row = table.rows[0]
    assert row[:2] == ["Cadence", shares[0]] and row[2] == (shares[1], "in")
    assert row[3:] == [str(cues), str(words), "“Take quicker steps”"]
    # given on multiples of 3; in band: multiples of 12 before stride 300 (25 of 100), the others after
    assert (shares, cues, words) == (["25 % of 251", "75 % of 251"], 25 + 75, 75 + 25)
    text = " ".join([b.text for b in section.blocks if hasattr(b, "text")] + [section.title]
                    + table.header + [c if isinstance(c, str) else c[0] for c in row])
    assert "on a share of the strides that fell over the session (faded): 100 instructions" in text
    assert not FORBIDDEN.findall(text)
    assert section.blocks[-1].text.startswith("Schedule: Winstein CJ, Schmidt RA. Reduced frequency")


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_the_recorded_dose_of_a_faded_schedule_falls(ros_context, tmp_path):
    """The biofeedback node and the recorder: 40 strides 0.75 s apart, all at 80 steps/min (below the
    band), after a calibration, with feedback fading from every stride to a quarter over 30 s.

    Share at stride k (t = 0.75 k s, all within the 30 s): 1 - 0.75 t / 30 = 1 - 0.01875 k; given after
    n strides: floor(0.5 + sum of the shares). First 20: 20 - 0.01875 x 190 = 16.44 → 16; all 40:
    40 - 0.01875 x 780 = 25.38 → 25, so 9 in the last 20. The words (words_every 4) on the 1st, 5th, ...
    25th given: 7 instructions, 18 cues."""
    from rclpy.node import Node
    from test_dashboard_layout import _cycle
    from test_interop import _decodes_everywhere

    from gait_biofeedback.io.bag import BagReader
    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.common import publisher, spin_until
    from gait_biofeedback.nodes.recorder import Recorder
    from gait_biofeedback.report.dose import dose_section
    from gait_biofeedback.report.extract import read_session
    from gait_biofeedback.wire import topics
    from gait_biofeedback.wire.calibration import mounting_msg

    bio = BiofeedbackNode(ros_context, serve_dashboard=False, stride_wait_s=0.0, feedback_schedule="faded",
                          fade_start=1.0, fade_end=0.25, fade_duration_s=30.0)
    recorder = Recorder(ros_context, output=str(tmp_path / "session"), flush_period_s=0.1,
                        topics=[t.absolute() for t in (topics.GAIT_CYCLES, topics.CUES, topics.GIVEN,
                                                       topics.CALIBRATION)])
    source = Node("hand_made_inputs", context=ros_context)
    cycles, calibration = (publisher(source, t) for t in (topics.GAIT_CYCLES, topics.CALIBRATION))
    with spinning(ros_context, bio, recorder, source) as executor:
        assert spin_until(executor, lambda: bio._given.get_subscription_count() > 0
                          and cycles.get_subscription_count() >= 2, timeout=10)
        calibration.publish(mounting_msg({"left_foot": [1.0, 0, 0, 0]}, 0, "walking", "explained_variance"))
        assert spin_until(executor, lambda: bio.calibrated, timeout=10)
        for k in range(40):
            cycles.publish(_cycle(("left", "right")[k % 2], 1 + k // 2, 10.0 + 0.75 * k))
            assert spin_until(executor, lambda n=k + 1: bio.counts["strides"] >= n, timeout=5)
        published = 1 + 40 + bio.counts["cues"] + bio.counts["instructions_given"] + bio.counts["cues_given"]
        assert spin_until(executor, lambda: recorder.written >= published, timeout=10)
    given = [m for topic, m, _ in BagReader(tmp_path / "session").messages([topics.GIVEN.absolute()])]
    strides = [m.stride_index for m in given]
    halves = sum(s <= 10 for s in strides), sum(s > 10 for s in strides)  # stride index 1-10: k < 20
    assert halves == (16, 9), strides
    assert {(m.rule, m.schedule) for m in given} == {("quicker_steps", "faded")}
    assert [m.kind for m in given] == ([KIND_INSTRUCTION] + [KIND_CUE] * 3) * 6 + [KIND_INSTRUCTION]
    counts = _decodes_everywhere(tmp_path / "session", {topics.GIVEN.absolute(), topics.CUES.absolute()})
    assert counts[topics.GIVEN.absolute()] == 25
    section = dose_section(read_session(tmp_path / "session"))
    assert section.blocks[1].rows[0][3:5] == ["18", "7"]
