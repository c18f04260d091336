"""Attacks on a live session, on loopback, one row each: what was sent and what the graph did.

``.venv/bin/python benchmarks/attacks.py [--only NAME ...] [--csv-rows 10000000]``

Each attack of issue 45's hostile probe, run against this checkout as an attacker on the same machine
(or on the sensors' network, here loopback) would: a forged sensor frame, a second sender on one
sensor id, an unsigned frame when the session has a frame key, two graphs on one ROS domain, the
dashboard's token on ``/rosout``, a flood of Host headers, a YAML alias bomb, a 5,000-deep nesting, a
10 M-row CSV import and an edited calibration file. One row per attack: what was sent, samples lost,
foreign samples recorded, what the graph said (``/diagnostics`` or the one-line refusal), wall time and
peak memory. Each row has a test in the suite (named in the last column).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@dataclass
class Row:
    attack: str
    sent: str
    lost: str = "-"
    foreign: str = "-"
    said: str = ""
    seconds: float = 0.0
    peak_mb: float = 0.0
    test: str = ""


def _cli(*argv: str, env: dict | None = None, timeout: float = 120.0) -> tuple[int, str, str, float, float]:
    """Run ``gait-biofeedback ARGV`` in a child: (exit code, stdout, stderr, s, peak RSS MB of the child)."""
    t0 = time.monotonic()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen([sys.executable, "-m", "gait_biofeedback.cli", *argv], cwd=REPO,
                                stdout=out, stderr=err, env={**os.environ, **(env or {})})
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        except BaseException:
            proc.kill()
            raise
        proc.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.monotonic() - t0
        out.seek(0)
        err.seek(0)
        return proc.returncode, out.read(), err.read(), seconds, usage.ru_maxrss / 1024


def _first_line(text: str, width: int = 110) -> str:
    """The first line of ``text`` that is not a ROS log line (``[INFO] [...]``), cut to ``width``."""
    line = next((x for x in text.strip().splitlines() if x.strip() and not x.startswith("[")), "")
    return line if len(line) <= width else line[: width - 1] + "…"


def alias_bomb(tmp: Path) -> Row:
    levels = ["a: &a [\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\",\"lol\"]"]
    for k, name in enumerate("bcdefghi"):
        prev = "abcdefghi"[k]
        levels.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    path = tmp / "bomb.yaml"
    path.write_text("\n".join(levels) + "\nimu_driver:\n  ros__parameters:\n    sensors: *i\n")
    code, _, err, seconds, peak = _cli("params", "--check", str(path))
    return Row("YAML alias bomb", f"{path.stat().st_size} B params file, 9 levels of 9 aliases",
               said=f"exit {code}, {len(err.splitlines())} line(s): {_first_line(err)}", seconds=seconds,
               peak_mb=peak, test="test_bounded_inputs.py")


def deep_nesting(tmp: Path) -> Row:
    path = tmp / "deep.yaml"
    path.write_text("imu_driver:\n  ros__parameters:\n    sensors: " + "[" * 5000 + "]" * 5000 + "\n")
    code, _, err, seconds, peak = _cli("params", "--check", str(path))
    return Row("deep nesting", "5,000 nested [ in a params file",
               said=f"exit {code}, {len(err.splitlines())} line(s): {_first_line(err)}", seconds=seconds,
               peak_mb=peak, test="test_bounded_inputs.py")


def huge_csv(tmp: Path, rows: int) -> Row:
    import numpy as np

    path = tmp / "big.csv"
    rng = np.random.default_rng(0)
    with path.open("w") as f:
        f.write("time,ax,ay,az,gx,gy,gz\n")
        block = 1_000_000
        for start in range(0, rows, block):
            n = min(block, rows - start)
            t = (np.arange(start, start + n) / 100.0)[:, None]
            data = np.hstack([t, rng.normal(0, 1, (n, 6)) + np.array([0, 0, 9.81, 0, 0, 0])])
            np.savetxt(f, data, fmt="%.6f", delimiter=",")
    mapping = tmp / "mapping.yaml"
    mapping.write_text("pelvis:\n  acc: [ax, ay, az]\n  gyr: [gx, gy, gz]\ntime: time\n")
    size_mb = path.stat().st_size / 1e6
    code, out, err, seconds, peak = _cli("import", "csv", str(path), "-o", str(tmp / "big_out"),
                                         "--mapping", str(mapping), "--units", "time=s", timeout=1800)
    said = f"exit {code}: {_first_line(out if code == 0 else err)}"
    path.unlink()
    return Row("huge CSV import", f"{rows:,} rows ({size_mb:.0f} MB)", said=said, seconds=seconds,
               peak_mb=peak, test="test_bounded_inputs.py")


FORGED_ACC = (123.0, 45.0, 67.0)
"""m/s²: the forged samples' specific force, to find them in a recording."""


def _udp_session(tmp: Path, attack: Callable[[int], None] | None, seconds: float = 8.0,
                 key_file: Path | None = None) -> dict:
    """The live graph (``imu_driver`` on udp, the recorder) while ``stream-sim``'s sender streams a
    simulated walk over loopback and ``attack(port)`` runs beside it: per segment the header stamps and
    specific forces recorded, and the driver's last ``/diagnostics`` values."""
    import threading

    from gait_biofeedback.core.driver.protocol import load_frame_key
    from gait_biofeedback.graph import running_graph
    from gait_biofeedback.io.bag import BagReader
    from gait_biofeedback.nodes.common import spin_until
    from gait_biofeedback.sim.sensor_link import FrameSchedule, LinkModel, send_udp
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate
    from gait_biofeedback.wire.stamps import stamp_to_ns

    session = simulate(SCENARIOS["walk"](duration=seconds).without_errors())
    driver = {"backend": "udp", "port": 0, "diagnostics_period_s": 0.2,
              **({"frame_key_file": str(key_file)} if key_file else {})}
    key = load_frame_key(key_file) if key_file else None
    out = tmp / f"session_{len(list(tmp.iterdir()))}"
    with running_graph([], out, {"imu_driver": driver}, driver=True) as graph:
        core = graph.nodes["imu_driver"].core
        ids = {seg: sid for sid, seg in core.params.mapping().items()}
        schedule = FrameSchedule(session.imu, ids, LinkModel(jitter_ms=1.0, seed=1), key=key)
        port = graph.nodes["imu_driver"].link.port
        sender = threading.Thread(target=send_udp, args=(schedule, "127.0.0.1", port), daemon=True)
        attacker = threading.Thread(target=attack, args=(port,), daemon=True) if attack else None
        sender.start()
        if attacker:
            attacker.start()
        spin_until(graph.executor, lambda: not sender.is_alive() and not (attacker and attacker.is_alive()))
        spin_until(graph.executor, lambda: False, timeout=0.6)
        reports = {r.name: r for r in core.reports(time.time_ns())}
    recorded: dict[str, tuple[list[int], list[tuple[float, float, float]]]] = {}
    with BagReader(out) as reader:
        for topic, msg, _ in reader.messages([f"/{seg}/imu/data_raw" for seg in ids]):
            stamps, acc = recorded.setdefault(topic.split("/")[1], ([], []))
            stamps.append(stamp_to_ns(msg.header.stamp))
            acc.append((msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z))
    return {"recorded": recorded, "reports": reports, "truth": schedule.truth}


def _frames(sensor_id: int, start_seq: int, start_us: int, n: int, period_us: int = 10_000,
            key: bytes | None = None) -> list[bytes]:
    from gait_biofeedback.core.driver.protocol import DeviceSample, encode_frame

    return [encode_frame([DeviceSample(sensor_id, start_seq + k, start_us + k * period_us, FORGED_ACC,
                                       (0.0, 0.0, 0.0), None)], key) for k in range(n)]


def _sender(frames: list[bytes], delay_s: float, period_s: float = 0.01) -> Callable[[int], None]:
    import socket

    def attack(port: int) -> None:
        time.sleep(delay_s)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            for frame in frames:
                sock.sendto(frame, ("127.0.0.1", port))
                time.sleep(period_s)

    return attack


def _compare(clean: dict, attacked: dict, segment: str) -> tuple[int, int, float, str]:
    """(samples lost against the truth, forged samples recorded, max stamp deviation from the clean
    run in ms after their common offset, what /diagnostics said of the segment)."""
    import numpy as np

    stamps, acc = attacked["recorded"].get(segment, ([], []))
    foreign = sum(a == FORGED_ACC for a in (tuple(round(v, 3) for v in x) for x in acc))
    sent = int((~attacked["truth"][segment].dropped).sum())
    lost = sent - (len(stamps) - foreign)
    genuine = np.array([t for t, a in zip(stamps, acc, strict=True)
                        if tuple(round(v, 3) for v in a) != FORGED_ACC])
    reference = np.array(clean["recorded"][segment][0])
    n = min(len(genuine), len(reference))
    shift = genuine[:n] - reference[:n]
    deviation = float(np.max(np.abs(shift - np.median(shift)))) * 1e-6 if n else float("nan")
    report = attacked["reports"].get(f"imu_driver: {segment}")
    return lost, foreign, deviation, report.message if report else "?"


def _driver_row(tmp: Path, name: str, sent: str, segment: str, attack: Callable[[int], None],
                test: str, key_file: Path | None = None) -> Row:
    t0 = time.monotonic()
    clean = _udp_session(tmp, None, key_file=key_file)
    attacked = _udp_session(tmp, attack, key_file=key_file)
    lost, foreign, deviation, said = _compare(clean, attacked, segment)
    link = attacked["reports"].get("imu_driver: link")
    return Row(name, sent, lost=str(lost), foreign=str(foreign),
               said=f"max stamp shift {deviation:.2f} ms; {segment}: {said}"
               + (f"; link: {link.message}" if link else ""),
               seconds=time.monotonic() - t0,
               peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, test=test)


def forged_frame(tmp: Path) -> Row:
    """The probe's forged datagram: sensor 2, sequence 123, device time 1 µs, valid CRC, from another
    socket, 3 s into the session."""
    return _driver_row(tmp, "forged frame", "one 44-byte GBI1 frame for sensor 2 (sequence 123, device time "
                       "1 µs) from another socket", "left_shank", _sender(_frames(2, 123, 1, 1), 3.0),
                       "test_driver_security.py, test_imu_driver_node.py")


def second_sender(tmp: Path) -> Row:
    """A second sender claiming sensor 4 for 3 s at 100 Hz, its own sequence and clock."""
    return _driver_row(tmp, "second sender, one id", "300 frames for sensor 4 over 3 s from another socket",
                       "right_thigh", _sender(_frames(4, 10, 5_000_000, 300), 2.0),
                       "test_driver_security.py, test_imu_driver_node.py")


def unsigned_with_key(tmp: Path) -> Row:
    """With a session key, unsigned and wrongly signed frames for sensor 2 sent before the sensors start
    (each would have bound the id to the attacker's socket)."""
    key_file = tmp / "frame.key"
    key_file.write_bytes(os.urandom(32).hex().encode())
    key_file.chmod(0o600)
    frames = _frames(2, 0, 0, 20) + _frames(2, 20, 200_000, 20, key=b"not the session key, 0123456789")
    return _driver_row(tmp, "unsigned frames, session key set", "20 unsigned + 20 wrongly signed frames for "
                       "sensor 2, before the sensors", "left_shank", _sender(frames, 0.0, 0.005),
                       "test_driver_security.py, test_imu_driver_node.py", key_file)


def _start(*argv: str, domain: int) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "gait_biofeedback.cli", *argv], cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "ROS_DOMAIN_ID": str(domain)})


def two_graphs(tmp: Path, tries: int = 10) -> Row:
    """``run --driver simulated --record`` twice on one domain, the second 0-10 s after the first (0
    and 5 ms among them): how many tries ended with both running, how many recordings of the refused
    one exist, and how many raw samples the winner recorded against what one driver sends."""
    from gait_biofeedback.io.bag import BagReader

    offsets = [0.0, 0.005, 0.05, 0.3, 1.0, 2.0, 3.5, 5.0, 7.5, 10.0][:tries]
    domain = int(os.environ.get("ATTACK_DOMAIN_ID", "77"))
    both = extra_recordings = 0
    said = ""
    excess = []
    t0 = time.monotonic()
    for k, offset in enumerate(offsets):
        a, b = tmp / f"try{k}_a", tmp / f"try{k}_b"
        run_s = offset + 6.0
        first = _start("run", "--driver", "simulated", "--record", str(a), "--duration", f"{run_s:.3f}",
                       domain=domain)
        time.sleep(offset)
        second = _start("run", "--driver", "simulated", "--record", str(b), "--duration", "6", domain=domain)
        results = [(p.wait(timeout=120), *p.communicate()) for p in (first, second)]
        codes = [r[0] for r in results]
        both += codes.count(0) == 2
        extra_recordings += a.exists() and b.exists()
        said = said or next((_first_line(err) for code, _, err in results if code == 2), "")
        for folder, seconds in ((a, run_s), (b, 6.0)):
            if folder.exists():
                counts = BagReader(folder).message_counts()
                pelvis = counts.get("/pelvis/imu/data_raw", 0)
                excess.append(pelvis / (100.0 * seconds))
    return Row("two graphs, one domain", f"{tries} pairs of `run --driver simulated --record`, second "
               f"started {min(offsets):.3f}-{max(offsets):.1f} s after the first",
               lost="-", foreign=f"{extra_recordings} mixed; pelvis samples / one driver's: max "
               f"{max(excess, default=0):.2f}", said=f"{both} of {tries} ran both; refused: {said}",
               seconds=time.monotonic() - t0, test="test_one_session_per_domain.py")


def token_on_rosout(tmp: Path) -> Row:
    """``run --nodes biofeedback --record`` while this process listens on /rosout: is the dashboard's
    token there, in the ROS log files, or anywhere but stdout and the owner-only link file?"""
    import stat

    import rclpy
    from rcl_interfaces.msg import Log
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from gait_biofeedback.nodes.common import make_executor

    domain = int(os.environ.get("ATTACK_DOMAIN_ID", "77")) + 1
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    node = Node("attacker_listens", context=context)
    heard: list[str] = []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(Log, "/rosout", lambda m: heard.append(m.msg), qos)
    t0 = time.time()
    child = _start("run", "--nodes", "biofeedback", "--record", str(tmp / "session"), "--duration", "4",
                   domain=domain)
    executor = make_executor(context)
    executor.add_node(node)
    while child.poll() is None:
        executor.spin_once(timeout_sec=0.1)
    out, _ = child.communicate()
    node.destroy_node()
    executor.shutdown()
    rclpy.shutdown(context=context)
    token = out.partition("?token=")[2].split()[0] if "?token=" in out else ""
    log_dir = Path(os.environ.get("ROS_LOG_DIR") or Path(os.environ.get("ROS_HOME", "~/.ros")) / "log")
    logs = [p for p in log_dir.expanduser().rglob("*") if p.is_file() and p.stat().st_mtime >= t0 - 1]
    in_logs = sum(token in p.read_text(errors="replace") for p in logs) if token else 0
    link = tmp / "session" / "dashboard_url.txt"
    mode = oct(stat.S_IMODE(link.stat().st_mode)) if link.exists() else "none"
    return Row("token on /rosout", "listened to /rosout and read the ROS log files during a session start",
               said=f"token printed on stdout: {bool(token)}; on /rosout: "
               f"{sum(token in m for m in heard)} of {len(heard)} messages; in log files: {in_logs}; "
               f"link file mode {mode}",
               seconds=time.time() - t0, test="test_session_token.py")


def host_flood(tmp: Path, requests: int = 13_000) -> Row:
    """13k requests with distinct 4 kB Host headers to a dashboard: log lines and memory they cost."""
    import socket
    import tracemalloc

    from gait_biofeedback.dashboard.server import DashboardServer

    logged = [0, 0]  # lines, characters

    class Log:
        def warning(self, text: str) -> None:
            logged[0] += 1
            logged[1] += len(text)

        info = error = warning

    server = DashboardServer(lambda: None, lambda m: None, lambda: {}, port=0, logger=Log())
    port = server.start()
    tracemalloc.start()
    t0 = time.monotonic()
    for k in range(requests):
        host = f"h{k}-" + "x" * 4000
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            sock.sendall(f"GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
            while sock.recv(65536):
                pass
    seconds = time.monotonic() - t0
    _, peak = tracemalloc.get_traced_memory()
    current, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    server.stop()
    return Row("Host header flood", f"{requests:,} requests, each a distinct 4 kB Host",
               said=f"{server.refused:,} refused, {logged[0]} log line(s), {logged[1] / 1e3:.1f} kB logged; "
               f"Python heap after {current / 1e6:.1f} MB", seconds=seconds, peak_mb=peak / 1e6,
               test="test_bounded_inputs.py, test_session_token.py")


def edited_calibration(tmp: Path) -> Row:
    """A saved calibration.yaml with left_thigh's w edited 0.706... → 7.06..., and one with right_foot's
    entry deleted (``complete: true`` kept), each given to ``replay --calibration``."""
    import numpy as np

    from gait_biofeedback.core.calibration.file import write_calibration_file
    from gait_biofeedback.core.calibration.sensor_to_segment import (
        SegmentCalibrationResult,
        SessionCalibration,
    )
    from gait_biofeedback.core.segments import SEGMENTS
    from gait_biofeedback.io.bag import write_imu_bag
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    bag = write_imu_bag(tmp / "walk", simulate(SCENARIOS["walk"](duration=4.0).without_errors()).imu)
    rng = np.random.default_rng(0)
    results = {}
    for segment in SEGMENTS:
        r = np.array([0.706, 0.5, 0.4, 0.3]) if segment == "left_thigh" else rng.normal(size=4)
        results[segment] = SegmentCalibrationResult(segment, r / np.linalg.norm(r), True, 0.9,
                                                    "explained_variance", 0.01)
    calibration = SessionCalibration("walking", results, True, "calibrated", (0.0, 3.0), (3.0, 20.0),
                                     "walking")
    said, t0, peak = [], time.monotonic(), 0.0
    for name, edit in (("edited", lambda text: text.replace("- 0.706", "- 7.06", 1)),
                       ("deleted", lambda text: _drop_entry(text, "right_foot"))):
        path = tmp / f"{name}.yaml"
        write_calibration_file(path, calibration, "2026-12-07T10:00:00+00:00")
        path.write_text(edit(path.read_text()))
        code, _, err, _, child_peak = _cli("replay", str(bag), "--calibration", str(path), "--speed", "0",
                                           "--nodes", "orientation_filter,calibration,joint_angles")
        peak = max(peak, child_peak)
        said.append(f"{name}: exit {code}, {_first_line(err, 150)}")
    return Row("edited calibration file", "left_thigh's w 0.706 → 7.06; right_foot's entry deleted",
               said="; ".join(said), seconds=time.monotonic() - t0, peak_mb=peak, test="test_calibration.py")


def _drop_entry(text: str, segment: str) -> str:
    """The YAML text without the block of ``segments: {segment: ...}`` (indentation tells where it ends)."""
    lines = text.splitlines(keepends=True)
    start = next(i for i, line in enumerate(lines) if line.strip() == f"{segment}:")
    indent = len(lines[start]) - len(lines[start].lstrip())
    end = next((j for j in range(start + 1, len(lines))
                if len(lines[j]) - len(lines[j].lstrip()) <= indent), len(lines))
    return "".join(lines[:start] + lines[end:])


def busy_replay(tmp: Path) -> Row:
    """A 1x replay of a 30 s walk of 8 sensors while two CPU hogs hold both cores: what replay says of
    the samples the graph could not take, and its exit code."""
    from gait_biofeedback.io.bag import write_imu_bag
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    bag = write_imu_bag(tmp / "walk", simulate(SCENARIOS["walk"](duration=30.0).without_errors()).imu)
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        code, _, err, seconds, peak = _cli("replay", str(bag), "--speed", "1", timeout=300)
    finally:
        for hog in hogs:
            hog.kill()
    said = next((line for line in err.splitlines() if line.startswith("replay: ")), "nothing said")
    return Row("replay on a busy machine", "1x replay of a 30 s walk, 2 CPU hogs on the 2 cores",
               said=f"exit {code}: {_first_line(said, 400)}", seconds=seconds, peak_mb=peak,
               test="test_graph.py, test_demo_summary.py")


ATTACKS: dict[str, Callable[..., Row]] = {
    "forged_frame": forged_frame,
    "second_sender": second_sender,
    "unsigned_with_key": unsigned_with_key,
    "alias_bomb": alias_bomb,
    "deep_nesting": deep_nesting,
    "huge_csv": huge_csv,
    "two_graphs": two_graphs,
    "edited_calibration": edited_calibration,
    "token_on_rosout": token_on_rosout,
    "host_flood": host_flood,
    "busy_replay": busy_replay,
}


def main() -> None:
    """Run the attacks and print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", nargs="*", choices=sorted(ATTACKS), help="run only these attacks")
    parser.add_argument("--csv-rows", type=int, default=10_000_000, help="rows of the huge CSV")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name in args.only or list(ATTACKS):
            tmp = Path(folder) / name
            tmp.mkdir()
            extra = {"rows": args.csv_rows} if name == "huge_csv" else {}
            rows.append(ATTACKS[name](tmp, **extra))
            print(f"  {name}: done in {rows[-1].seconds:.1f} s", file=sys.stderr, flush=True)
    header = ("attack", "sent", "lost", "foreign recorded", "what the graph said", "s", "peak MB", "test")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for r in rows:
        print(f"| {r.attack} | {r.sent} | {r.lost} | {r.foreign} | {r.said} | {r.seconds:.1f} | "
              f"{r.peak_mb:.0f} | {r.test} |")
    print(f"(this process peaked at {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB)")


if __name__ == "__main__":
    main()
