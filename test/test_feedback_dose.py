"""The dose recorded (issue 49 item 6): FeedbackGiven messages round-trip through a bag and the PyPI
``rosbags`` and ``mcap-ros2-support`` readers, and the report's dose section counts them.

A hand-made 12-minute session: a stride every 1.2 s whose cadence is in its band on every 4th stride
before 6 min and on 3 strides of 4 after; feedback given on every 3rd stride (words when outside the
band, a cue when in). The expected counts are counted here from that pattern."""

from __future__ import annotations

import math

from conftest import rosbags_typestore

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
