"""The dashboard cannot be driven by another web page, and no command or message ends the session:
Origin and Host are checked, commands need the session's token (without it the page is read-only),
every command field is checked before anything runs, a failing callback is skipped and reported, a busy
port moves the dashboard to the next free one."""

from __future__ import annotations

import http.client
import json
import socket
import time

import pytest
from conftest import spinning
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from gait_biofeedback.dashboard.commands import CommandError, parse_command

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]


@pytest.mark.parametrize(("message", "refusal"), [
    ({"action": "calibrate", "protocol": "hip_flexion", "standing_duration": "abc"},
     "calibrate: standing_duration='abc' refused; expected a number from 0 to 60"),
    ({"action": "calibrate", "standing_duration": float("nan")}, "standing_duration=nan refused"),
    ({"action": "calibrate", "motion_duration": 1e9}, "motion_duration=1000000000.0 refused"),
    ({"action": "calibrate", "protocol": "jumping"}, "protocol='jumping' refused; expected one of"),
    ({"action": "calibrate", "segments": ["pelvis"]}, "calibrate: unknown field(s) 'segments'"),
    ({"action": "x" * 60_000}, "unknown action 'xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx…; actions:"),
    ({"action": "mute", "muted": "yes"}, "mute: muted='yes' refused; expected true or false"),
    ({"action": "feedback", "side": 3}, "feedback: side=3 refused"),
    ({"action": "shutdown"}, "unknown action 'shutdown'"),
    ({"protocol": "walking"}, "unknown action None"),
    ({"action": ["calibrate"]}, "unknown action ['calibrate']"),
])
def test_every_command_field_is_checked(message, refusal):
    with pytest.raises(CommandError) as caught:
        parse_command(message)
    assert refusal in str(caught.value)


def test_a_valid_command_passes_with_its_fields_typed():
    assert parse_command({"action": "calibrate", "protocol": "walking", "standing_duration": 4}) == (
        "calibrate", {"protocol": "walking", "standing_duration": 4.0})
    assert parse_command({"action": "record_stop"}) == ("record_stop", {})


@pytest.fixture
def dashboard(ros_context):
    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode

    node = BiofeedbackNode(ros_context, port=0)
    with spinning(ros_context, node) as executor:
        yield node, executor


def _hello(ws) -> dict:
    return json.loads(ws.recv(timeout=5))


def _reply(ws, executor, action: str, timeout: float = 5.0) -> dict:
    """The next reply to ``action`` (frames and other replies skipped), spinning the node meanwhile."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.02)
        try:
            msg = json.loads(ws.recv(timeout=0.05))
        except TimeoutError:
            continue
        found = [msg] if msg.get("type") == "reply" else msg.get("messages", [])
        for m in found:
            if m.get("type") == "reply" and m.get("action") == action and not m.get("pending"):
                return m
    raise AssertionError(f"no reply to {action}")


def test_another_web_page_cannot_open_or_drive_the_dashboard(dashboard):
    node, _ = dashboard
    port = node.port
    with pytest.raises(InvalidStatus, match="403"):
        connect(f"ws://127.0.0.1:{port}/ws?token={node.server.token}",
                additional_headers={"Origin": "http://evil.example"}, open_timeout=5)
    # DNS rebinding: a page served as evil.example that resolves to 127.0.0.1
    for path in ("/", "/ws"):
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
        conn.request("GET", path, headers={"Host": f"evil.example:{port}"})
        response = conn.getresponse()
        assert response.status == 403 and b"Host" in response.read()
        conn.close()
    # two Host headers (one of them this server's): refused, not a server error
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    conn.putrequest("GET", "/", skip_host=True)
    conn.putheader("Host", f"127.0.0.1:{port}")
    conn.putheader("Host", f"evil.example:{port}")
    conn.endheaders()
    response = conn.getresponse()
    assert response.status == 403 and b"more than one Host header" in response.read()
    conn.close()
    assert node.server.refused >= 4 and node.counts["commands"] == 0
    # the server's own sources are not served from its static folder
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    conn.request("GET", "/server.py")
    assert conn.getresponse().status == 404
    conn.close()


def test_without_the_token_the_page_is_read_only(dashboard):
    node, executor = dashboard
    with connect(f"ws://127.0.0.1:{node.port}/ws", open_timeout=5,
                 additional_headers={"Origin": f"http://127.0.0.1:{node.port}"}) as ws:
        assert _hello(ws)["read_only"] is True
        for command in ({"action": "mute", "muted": True}, {"action": "record_stop"},
                        {"action": "calibrate", "protocol": "walking"}):
            ws.send(json.dumps(command))
            reply = _reply(ws, executor, command["action"])
            assert not reply["success"] and reply["message"].startswith("read-only view")
    assert node.counts["commands"] == 0 and node.muted is False
    with connect(f"ws://localhost:{node.port}/ws?token={node.server.token}", open_timeout=5,
                 additional_headers={"Origin": f"http://localhost:{node.port}"}) as ws:
        assert _hello(ws)["read_only"] is False
        ws.send(json.dumps({"action": "mute", "muted": True}))
        assert _reply(ws, executor, "mute")["success"] and node.muted is True
        # a malformed command is refused with a reply; the node (and the process) go on
        ws.send(json.dumps({"action": "calibrate", "protocol": "hip_flexion", "standing_duration": "abc"}))
        reply = _reply(ws, executor, "calibrate")
        assert not reply["success"] and "standing_duration='abc' refused" in reply["message"]
        # a binary frame is not a command, whatever it holds
        ws.send(json.dumps({"action": "mute", "muted": False}).encode())
        deadline = time.monotonic() + 5
        error = None
        while error is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
            try:
                msg = json.loads(ws.recv(timeout=0.05))
            except TimeoutError:
                continue
            error = msg if msg.get("type") == "error" else None
        assert error and "binary frame" in error["message"] and node.muted is True
        ws.send(json.dumps({"action": "feedback", "side": "left"}))
        assert _reply(ws, executor, "feedback")["success"] and node.feedback["side"] == "left"


def test_a_failing_callback_is_skipped_counted_and_reported(dashboard, ros_context):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    from gait_biofeedback.wire.topics import DIAGNOSTICS, RELIABLE_QOS

    node, executor = dashboard
    source = Node("bad_source", context=ros_context)
    joints = source.create_publisher(JointState, "joint_states", RELIABLE_QOS)
    reports = []
    source.create_subscription(
        DiagnosticArray, DIAGNOSTICS.name,
        lambda m: reports.extend(s for s in m.status if s.name == "biofeedback: callbacks"), RELIABLE_QOS)
    executor.add_node(source)
    try:
        deadline = time.monotonic() + 5
        while joints.get_subscription_count() == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        # a malformed message: more names than positions (a hand-made or corrupt publisher)
        joints.publish(JointState(name=["left_hip_flexion", "left_knee_flexion"], position=[0.1]))
        good = JointState(name=["left_knee_flexion"], position=[0.2])
        good.header.stamp.sec = 1
        joints.publish(good)
        deadline = time.monotonic() + 5
        while (not reports or node._latest is None) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert node.callback_errors == {"callback of joint_states": 1}
        assert node._latest == (1.0, {"left_knee_flexion": 0.2}, ()), "the next good message was processed"
        assert reports and reports[0].level == b"\x02" and "1 callback failure" in reports[0].message
    finally:
        source.destroy_node()


def test_a_busy_port_moves_the_dashboard_to_the_next_free_one(ros_context):
    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        busy = taken.getsockname()[1]
        node = BiofeedbackNode(ros_context, port=busy)
        try:
            assert node.port is not None and busy < node.port <= busy + 20
            assert node.server.url == f"http://127.0.0.1:{node.port}/?token={node.server.token}"
        finally:
            node.destroy_node()


def test_allowed_hosts_for_loopback_wildcard_and_proxied_binds():
    """Host names compare case-insensitively, IPv6 in brackets; a wildcard bind serves loopback and
    the names given in allowed_hosts; a proxy's https origin on its default port is accepted."""
    from gait_biofeedback.dashboard.server import DashboardServer, _origins

    def server(host, extra=()):
        made = DashboardServer(dict, print, dict, host=host, port=8080, allowed_hosts=extra)
        made.port = 8080  # as start() sets it once bound
        return made

    assert server("127.0.0.1")._allowed_hosts() == {"127.0.0.1:8080", "localhost:8080", "[::1]:8080"}
    assert "[::1]:8080" in server("::1")._allowed_hosts()
    wild = server("0.0.0.0", ("Gait-Lab.local", "proxy.example:443"))
    assert {"gait-lab.local:8080", "proxy.example:443", "localhost:8080"} <= wild._allowed_hosts()
    assert "evil.example:8080" not in wild._allowed_hosts()
    assert wild.url.startswith("http://127.0.0.1:8080/?token=")
    origins = _origins(wild._allowed_hosts())
    assert {"https://proxy.example", "http://gait-lab.local:8080"} <= origins
    assert "http://evil.example:8080" not in origins
