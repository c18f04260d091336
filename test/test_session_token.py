"""The dashboard's command token stays with the person who started the session (issue 45): printed on the
terminal and written to an owner-only file, never on /rosout or in the ROS log files."""

from __future__ import annotations

import os
import stat
import time
from pathlib import Path

import pytest
from conftest import spinning

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]


def test_the_token_is_on_the_terminal_and_in_an_owner_only_file_never_on_rosout(ros_context, tmp_path, capfd):
    from rcl_interfaces.msg import Log
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.common import spin_until

    listener = Node("rosout_listener", context=ros_context)
    heard: list[str] = []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    listener.create_subscription(Log, "/rosout", lambda m: heard.append(m.msg), qos)
    started = time.time()
    node = BiofeedbackNode(ros_context, port=0, session_dir=str(tmp_path / "session"))
    with spinning(ros_context, node, listener) as executor:
        token = node.server.token
        assert len(token) >= 20
        assert spin_until(executor, lambda: any("dashboard:" in m for m in heard), timeout=10), heard
        out = capfd.readouterr()
        assert f"?token={token}" in out.out, "the link with the token is printed on the terminal"
        assert token not in out.err, "rclpy's console log does not carry the token"
        assert not [m for m in heard if token in m], "no token on /rosout"
        said = next(m for m in heard if "dashboard:" in m)
        assert f"http://127.0.0.1:{node.port}/" in said and "printed on the terminal" in said
        link = tmp_path / "session" / "dashboard_url.txt"
        assert link.read_text().strip() == f"http://127.0.0.1:{node.port}/?token={token}"
        assert stat.S_IMODE(link.stat().st_mode) == 0o600
    assert not (tmp_path / "session" / "dashboard_url.txt").exists(), "the dead token's file is removed"
    home = Path(os.environ.get("ROS_HOME", "~/.ros")).expanduser()
    log_dir = Path(os.environ.get("ROS_LOG_DIR") or home / "log")
    recent = [p for p in log_dir.rglob("*") if p.is_file() and p.stat().st_mtime >= started - 1]
    leaked = [p for p in recent if token in p.read_text(errors="replace")]
    assert not leaked, f"the token is in ROS log files: {leaked}"


def test_a_link_file_left_by_an_earlier_session_is_replaced_owner_only(tmp_path):
    from gait_biofeedback.nodes.biofeedback import write_private_link

    old = tmp_path / "dashboard_url.txt"
    old.write_text("http://127.0.0.1:1/?token=old\n")
    old.chmod(0o644)
    path = write_private_link("http://127.0.0.1:8080/?token=new", str(tmp_path))
    assert path == old and old.read_text() == "http://127.0.0.1:8080/?token=new\n"
    assert stat.S_IMODE(old.stat().st_mode) == 0o600
    assert write_private_link("http://x/?token=t", "") is None


def test_wrong_token_attempts_are_counted_and_logged_at_a_bounded_rate():
    """Guessing the token: each wrong one is counted, the page stays read-only, and the log gets the
    first attempt at once and then at most a line per period, whatever the number of guesses."""
    import json

    from websockets.sync.client import connect

    from gait_biofeedback.dashboard.server import DashboardServer

    lines: list[str] = []

    class Log:
        def warning(self, text: str) -> None:
            lines.append(text)

        info = error = warning

    commands: list[dict] = []
    server = DashboardServer(lambda: None, commands.append, lambda: {"type": "hello"}, port=0, logger=Log())
    port = server.start()
    try:
        for k in range(30):
            with connect(f"ws://127.0.0.1:{port}/ws?token=guess{k}", open_timeout=5) as page:
                assert json.loads(page.recv(timeout=5))["read_only"] is True
                page.send(json.dumps({"action": "record_stop"}))
                assert json.loads(page.recv(timeout=5))["success"] is False
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=5) as page:  # no token: a plain view
            assert json.loads(page.recv(timeout=5))["read_only"] is True
    finally:
        server.stop()
    assert server.token_failures == 30 and commands == []
    assert len(lines) <= 3 and "a page with a wrong command token (1 so far)" in lines[0]
    assert all(server.token not in line for line in lines)
