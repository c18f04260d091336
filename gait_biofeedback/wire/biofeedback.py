"""``biofeedback/cues`` (BiofeedbackCue) of the core's cues; ``biofeedback/given`` (FeedbackGiven) of the
feedback given (:class:`~gait_biofeedback.core.biofeedback.schedule.Given`), and back."""

from __future__ import annotations

from typing import Any

from gait_biofeedback.core.biofeedback.evaluator import Cue
from gait_biofeedback.core.biofeedback.schedule import Given
from gait_biofeedback.wire.stamps import ns_to_stamp, stamp_to_ns
from gait_biofeedback_msgs.msg import BiofeedbackCue, FeedbackGiven


def cue_msg(c: Cue, frame_id: str) -> BiofeedbackCue:
    """One cue (SI units; stamp = the stride's closing IC)."""
    msg = BiofeedbackCue(quantity=c.quantity, side=c.side, unit=c.unit, measured=c.measured,
                         band_low=c.band_low, band_high=c.band_high, error=c.error, severity=c.severity,
                         audio_frequency=c.audio_frequency, audio_rate=c.audio_rate,
                         stride_index=c.stride_index)
    msg.header.stamp = ns_to_stamp(c.stamp_ns)
    msg.header.frame_id = frame_id
    return msg


def given_msg(g: Given, frame_id: str) -> FeedbackGiven:
    """One piece of feedback given (SI units; stamp = the closing IC of the stride it is about)."""
    i, c = g.instruction, g.instruction.cue
    msg = FeedbackGiven(kind=g.kind, rule=i.rule.id, text=i.text, quantity=c.quantity, side=c.side,
                        unit=c.unit, measured=c.measured, band_low=c.band_low, band_high=c.band_high,
                        error=c.error, schedule=g.schedule, schedule_rate=g.rate,
                        stride_index=g.stride_index & 0xFFFFFFFF, block_strides=g.block_strides,
                        block_in_band=g.block_in_band)
    msg.header.stamp = ns_to_stamp(g.stamp_ns)
    msg.header.frame_id = frame_id
    return msg


def given_of(msg: Any) -> dict[str, Any]:
    """The fields of a FeedbackGiven (an rclpy message or a decoded one with the same fields), stamp in ns."""
    out = {name: getattr(msg, name) for name in ("rule", "text", "quantity", "side", "unit", "schedule")}
    out.update({name: float(getattr(msg, name)) for name in ("measured", "band_low", "band_high", "error",
                                                             "schedule_rate")})
    out.update({name: int(getattr(msg, name)) for name in ("kind", "stride_index", "block_strides",
                                                           "block_in_band")})
    out["stamp_ns"] = stamp_to_ns(msg.header.stamp)
    return out
