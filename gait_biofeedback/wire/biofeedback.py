"""``biofeedback/cues`` (BiofeedbackCue) of the core's cues."""

from __future__ import annotations

from gait_biofeedback.core.biofeedback.evaluator import Cue
from gait_biofeedback.wire.stamps import ns_to_stamp
from gait_biofeedback_msgs.msg import BiofeedbackCue


def cue_msg(c: Cue, frame_id: str) -> BiofeedbackCue:
    """One cue (SI units; stamp = the stride's closing IC)."""
    msg = BiofeedbackCue(quantity=c.quantity, side=c.side, unit=c.unit, measured=c.measured,
                         band_low=c.band_low, band_high=c.band_high, error=c.error, severity=c.severity,
                         audio_frequency=c.audio_frequency, audio_rate=c.audio_rate,
                         stride_index=c.stride_index)
    msg.header.stamp = ns_to_stamp(c.stamp_ns)
    msg.header.frame_id = frame_id
    return msg
