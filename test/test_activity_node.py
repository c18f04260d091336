"""activity_monitor node: simulated chest IMU replayed → ActivityState with the true transitions."""

from __future__ import annotations

import pytest
from conftest import simulated_bag, stamp_ns

from gait_biofeedback.core.activity.monitor import classify_activity
from gait_biofeedback.graph import replay_through_graph
from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.sim.simulator import SCENARIOS
from gait_biofeedback.wire.activity import POSTURE_CODES, TRANSITION_CODES

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


def _restarts(out) -> str:
    """What the node's /diagnostics counted of a stream that stopped or jumped ('' when nothing)."""
    counts: dict[str, str] = {}
    for _, msg, _ in BagReader(out).messages(["/diagnostics"]):
        for status in msg.status:
            if status.name.startswith("activity_monitor"):
                counts.update({kv.key: kv.value for kv in status.values
                               if kv.key in ("restarts", "bad_stamps")})
    return ", ".join(f"{k} {v}" for k, v in counts.items() if v and float(v) != 0.0)


def test_node_reports_the_simulated_transitions(tmp_path):
    config = SCENARIOS["activity"]()
    config.segments = ("chest",)
    bag, session = simulated_bag(tmp_path / "in", config)
    out = tmp_path / "out"
    replay_through_graph(bag, out, speed=4.0, nodes=["activity_monitor"], timeout=90)
    states = [m for _, m, _ in BagReader(out).messages(["/activity/state"])]
    assert states, "the node published its state"
    seen = []
    for m in states:
        ns = stamp_ns(m.last_transition_stamp)
        if m.last_transition and (not seen or seen[-1][1] != ns):
            seen.append((m.last_transition, ns))
    kinds = [code for code, _ in seen]
    truth = [TRANSITION_CODES[kind] for _, kind in session.truth.transitions]
    if kinds != truth and (lost := _restarts(out)):
        # beside busy processes the 4x replay loses chest samples (DDS best effort): the node restarts
        # over the hole, as it should, and a transition in it is not seen; that is the load, not the node
        pytest.xfail(f"known load fragility: the replay lost chest samples ({lost}); transitions {kinds}")
    assert kinds == truth
    for (_, ns), (t_true, _) in zip(seen, session.truth.transitions, strict=True):
        assert abs(ns * 1e-9 - t_true) < 0.5
    # the live node gives what the batch entry point gives on the same samples
    batch = classify_activity(session.imu["chest"].acc, 100.0)
    assert [k for _, k in batch["transitions"]] == [k for _, k in session.truth.transitions]
    lying = [m for m in states if m.posture == POSTURE_CODES["lying"]]
    assert lying and sorted(m.trunk_inclination for m in lying)[len(lying) // 2] > 1.3, "lying ~ 90 deg"
    assert max(m.step_count for m in states) >= len(session.truth.steps) - 2


def test_chest_calibration_entry_sets_the_forward_axis():
    import numpy as np
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import Quaternion

    from gait_biofeedback.core.activity.stream import ActivityStream
    from gait_biofeedback.core.quaternion import from_axis_angle, rotate
    from gait_biofeedback.wire.calibration import entries
    from gait_biofeedback_msgs.msg import SegmentCalibration, SegmentCalibrationArray

    r = from_axis_angle(np.array([0.2, 1.0, 0.1]), 2.0)  # segment → sensor, an arbitrary mounting
    msg = SegmentCalibrationArray(protocol="walking", segments=[
        SegmentCalibration(segment="chest", valid=True, rotation=Quaternion(w=r[0], x=r[1], y=r[2], z=r[3]))])
    msg.header.stamp = Time(sec=0)
    stream = ActivityStream()
    stream.apply_calibration(*entries(msg))
    (notice,) = stream.notices.pop()
    assert notice.level == "info" and "forward axis" in notice.text
    assert stream.options["forward_axis"] == pytest.approx(list(rotate(r, np.array([1.0, 0.0, 0.0]))))
    msg.segments[0].valid = False
    stream = ActivityStream()
    stream.apply_calibration(*entries(msg))
    (notice,) = stream.notices.pop()
    assert notice.level == "info" and "no valid chest entry" in notice.text
