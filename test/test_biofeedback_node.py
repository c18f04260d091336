"""biofeedback node: simulated walk → per-stride cues equal to the truth, dashboard frames, page commands."""

from __future__ import annotations

import contextlib
import json
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from conftest import spinning

from gait_biofeedback.sim.simulator import SCENARIOS, simulate

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]
DEG = np.pi / 180


@pytest.fixture(scope="module")
def session():
    return simulate(SCENARIOS["walk"](duration=8.0).without_errors())


def _strides(truth):
    """(side, index, start, tc, end) of every complete stride in the truth."""
    out = []
    for side in ("left", "right"):
        ics, tcs = truth.initial_contacts[side], truth.terminal_contacts[side]
        for k in range(len(ics) - 1):
            tc = tcs[(tcs > ics[k]) & (tcs < ics[k + 1])]
            if len(tc):
                out.append((side, k, float(ics[k]), float(tc[0]), float(ics[k + 1])))
    return sorted(out, key=lambda s: s[4])


class _Reader(threading.Thread):
    """Websocket client in a thread: keeps every message the node sends."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.ws = None
        self.messages: list[dict] = []
        self.frames: list[dict] = []
        self.opened = threading.Event()

    def run(self) -> None:
        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        with connect(self.url, open_timeout=5) as ws:
            self.ws = ws
            self.opened.set()
            try:
                for raw in ws:
                    msg = json.loads(raw)
                    (self.frames if msg["type"] == "frame" else self.messages).append(msg)
                    self.messages.extend(msg.get("messages", []))
            except ConnectionClosed:
                pass

    def of(self, kind: str) -> list[dict]:
        return [m for m in list(self.messages) if m.get("type") == kind]


def test_node_cues_frames_and_commands(ros_context, session):
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.common import spin_until
    from gait_biofeedback.wire.stamps import s_to_stamp
    from gait_biofeedback.wire.topics import RELIABLE_QOS
    from gait_biofeedback_msgs.msg import BiofeedbackCue, GaitCycle
    from gait_biofeedback_msgs.srv import Calibrate

    truth = session.truth
    node = BiofeedbackNode(ros_context, port=0, frame_rate_hz=50.0)
    source = Node("sim_source", context=ros_context)
    joints = source.create_publisher(JointState, "joint_states", RELIABLE_QOS)
    cycles = source.create_publisher(GaitCycle, "gait/cycles", RELIABLE_QOS)
    cues: list[BiofeedbackCue] = []
    source.create_subscription(BiofeedbackCue, "biofeedback/cues", cues.append, RELIABLE_QOS)
    calls = []

    def calibrate(request, response):
        calls.append(request.protocol)
        response.success, response.message = True, f"stub: calibrated with {request.protocol}"
        return response

    source.create_service(Calibrate, "calibration/calibrate", calibrate)
    with spinning(ros_context, node, source) as executor, contextlib.ExitStack() as first:
        assert node.port and node.port > 0
        base = f"http://127.0.0.1:{node.port}"
        page = urllib.request.urlopen(base + "/", timeout=5).read().decode()
        assert "<canvas id=\"figure\"" in page and "app.js" in page
        js = urllib.request.urlopen(base + "/app.js", timeout=5)
        assert js.headers["Content-Type"].startswith("text/javascript") and b"dashboardState" in js.read()
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(base + "/../../setup.py", timeout=5)

        reader = _Reader(f"ws://127.0.0.1:{node.port}/ws?token={node.server.token}")
        first.callback(lambda: reader.ws is not None and reader.ws.close())  # before the nodes go
        reader.start()
        assert reader.opened.wait(5)
        assert spin_until(executor, lambda: reader.of("hello"), timeout=5)
        hello = reader.of("hello")[0]
        assert set(hello["targets"]["reference"]) == {"hip_flexion", "knee_flexion", "ankle_dorsiflexion"}

        # publish the simulated walk: joint angles at 100 Hz, a GaitCycle at each closing IC
        names = list(truth.joint_angles)
        angles = np.stack([truth.joint_angles[n] for n in names], axis=1)
        strides = _strides(truth)
        ankle = {side: truth.segment_position[f"{side}_foot"] for side in ("left", "right")}
        ics = truth.initial_contacts
        k_stride = 0
        for i, t in enumerate(truth.t):
            msg = JointState(name=names, position=angles[i].tolist())
            msg.header.stamp = s_to_stamp(float(t))
            joints.publish(msg)
            # a GaitCycle comes 1-2 samples after its closing IC
            while k_stride < len(strides) and strides[k_stride][4] <= t + 0.02:
                side, index, t0, tc, t1 = strides[k_stride]
                other = ics["right" if side == "left" else "left"]
                step_time = t1 - other[other < t1][-1]
                travel = np.interp(t1, truth.t, ankle[side][:, 0]) - np.interp(t0, truth.t, ankle[side][:, 0])
                c = GaitCycle(side=0 if side == "left" else 1, stride_index=index, start=s_to_stamp(t0),
                              terminal_contact=s_to_stamp(tc), stride_time=t1 - t0, stance_time=tc - t0,
                              swing_time=t1 - tc, stance_fraction=(tc - t0) / (t1 - t0),
                              cadence=2 / (t1 - t0),
                              step_time_symmetry_index=0.02, plausible=True, step_time=step_time,
                              stride_length=travel, gait_speed=travel / (t1 - t0),
                              max_foot_height=0.1 + 0.001 * index, foot_angle_ic=0.3 + 0.01 * index)
                c.header.stamp = s_to_stamp(t1)
                cycles.publish(c)
                k_stride += 1
            if i % 50 == 49:  # paced at ~4x real time, so the page gets many frames
                target = i + 1
                pace = time.monotonic() + 0.12
                spin_until(executor, lambda pace=pace: time.monotonic() > pace)
                assert spin_until(executor, lambda target=target: node.counts["joint_states"] >= target,
                                  timeout=5)
        assert spin_until(executor, lambda: node.counts["strides"] >= len(strides), timeout=5)
        # 7 kinematic and temporal cues per stride and 5 stroke ones (trailing limb angle, push-off, knee
        # in stance, strike angle, foot clearance; no paretic side: no paretic ratio); 3 spatial ones but
        # on each foot's first stride of the walk (gait initiation); and the step-length symmetry once
        # both sides have a step
        expected = 12 * len(strides) + 3 * (len(strides) - 2) + len(strides) - 3
        assert spin_until(executor, lambda: len(cues) >= expected, timeout=5)
        assert len(strides) >= 8 and len(cues) == expected
        t = truth.t
        for k, (side, index, t0, tc, t1) in enumerate(strides):
            got = {c.quantity: c for c in cues
                   if c.stride_index == index and c.header.frame_id == f"{side}_foot"}
            assert len(got) == (12 if k < 2 else 15 if k == 2 else 16), (k, sorted(got))
            assert got["foot_strike_angle"].measured == pytest.approx(0.3 + 0.01 * index)  # the cycle's
            # the step: from the other foot's footprint to this one's (walking east, along x; the foot
            # is flat 0.15 s after its IC); measured 1.4-2.5 mm short
            other = "right" if side == "left" else "left"
            previous = ics[other][ics[other] < t1][-1]
            step = (np.interp(t1 + 0.15, t, ankle[side][:, 0])
                    - np.interp(previous + 0.15, t, ankle[other][:, 0]))
            if k >= 2 and t1 < strides[-1][4]:  # the last step (the walk stops) is 2.7 cm shorter than ours
                assert got["step_length"].measured == pytest.approx(step, abs=0.004)
            knee = truth.joint_angles[f"{side}_knee_flexion"]
            hip = truth.joint_angles[f"{side}_hip_flexion"]
            swing = (t >= tc) & (t <= t1)
            stance = (t >= t0) & (t <= tc)
            assert got["knee_flexion_peak_swing"].measured == pytest.approx(knee[swing].max(), abs=1e-4)
            assert got["hip_extension_peak_stance"].measured == pytest.approx(-hip[stance].min(), abs=1e-4)
            assert got["knee_flexion_at_ic"].measured == pytest.approx(np.interp(t0, t, knee), abs=1e-4)
            assert got["stance_fraction"].measured == pytest.approx((tc - t0) / (t1 - t0))
            assert got["cadence"].side == "" and got["cadence"].unit == "Hz"
            for c in got.values():
                assert (c.error == 0) == (c.severity == BiofeedbackCue.SEVERITY_IN_BAND)
                assert (c.audio_rate > 0) == (c.severity != BiofeedbackCue.SEVERITY_IN_BAND)
        peak = np.array([c.measured for c in cues if c.quantity == "knee_flexion_peak_swing"])
        assert 50 * DEG < peak.mean() < 70 * DEG  # the simulator walks like a healthy adult

        # the page got every joint-angle sample (decimated into frames), the figure, strides and cues
        settle = time.monotonic() + 0.5
        spin_until(executor, lambda: time.monotonic() > settle)
        samples = [row for f in list(reader.frames) for row in f.get("samples", [])]
        assert len(samples) == len(truth.t)
        assert np.allclose([row[0] for row in samples], truth.t, atol=1e-4)
        figures = [f["figure"] for f in list(reader.frames) if "figure" in f]
        assert len(figures) >= 10 and len(figures) < len(truth.t) / 2  # decimated
        knees = {tuple(np.round(seg[3:], 3)) for fig in figures for seg in fig if seg[0] == "left_shank"}
        assert len(knees) > 5  # the figure moves
        assert len(reader.of("stride")) == len(strides) and len(reader.of("cue")) == len(cues)
        # the page shows each stride's foot height and strike angle (no cue from them)
        spatial = {(m["side"], m["stride"]): m for m in reader.of("spatial")}
        assert len(spatial) == len(strides)
        for (_, index), m in spatial.items():
            assert m["max_foot_height"] == pytest.approx(0.1 + 0.001 * index)
            assert m["foot_angle_ic"] == pytest.approx(0.3 + 0.01 * index)
        assert all(len(s["curves"]["knee_flexion"]) == 51 for s in reader.of("stride"))

        # page commands: calibrate through the (stub) service, recorder missing, feedback choice
        reader.ws.send(json.dumps({"action": "calibrate", "protocol": "walking"}))
        reader.ws.send(json.dumps({"action": "record_start"}))
        reader.ws.send(json.dumps({"action": "feedback", "side": "left", "joint": "knee"}))
        reader.ws.send(json.dumps({"action": "calibrate", "protocol": "jumping"}))

        def replies(action):
            return [m for m in reader.of("reply") if m["action"] == action and not m.get("pending")]

        assert spin_until(executor, lambda: len(replies("calibrate")) >= 2 and replies("record_start")
                          and replies("feedback"), timeout=10)
        assert calls == ["walking"]
        cal = replies("calibrate")
        assert any(m["success"] and m["message"] == "stub: calibrated with walking" for m in cal)
        refusal = "calibrate: protocol='jumping' refused; expected one of ['auto', 'hip_flexion', 'walking']"
        assert any(not m["success"] and m["message"] == refusal for m in cal)
        rec = replies("record_start")[0]
        assert not rec["success"] and "not available" in rec["message"]
        assert node.feedback == {"side": "left", "joint": "knee"}
    assert node.server is None
