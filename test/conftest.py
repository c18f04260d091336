"""Shared fixtures and helpers: data locations, a fresh ROS context per test, nodes spinning in an
executor, small synthetic recordings, the command line in-process, message stamps, calibrations from
the simulator's truth. Test files import the helpers by name (``from conftest import run_cli``); each
is defined here once."""

from __future__ import annotations

import contextlib
import csv
import io
import os
import shutil
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):  # before numpy: see gait_biofeedback/__init__.py
    os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
_HELD_DOMAIN: list = []


def _claim_domain(first: int | None = None) -> int:
    """A DDS domain (1..100) no other test process on this machine holds: an exclusive lock on a file
    per domain, held until this process ends (released by the kernel also on a crash). Test runs side
    by side (two checkouts, CI beside a developer) then never hear each other's nodes; picking by pid
    alone collided (a graph refused as "already runs recorder"). ``first``: the domain to try first
    (default from the pid)."""
    import fcntl
    import tempfile

    start = os.getpid() % 100 if first is None else first - 1
    for i in range(100):
        domain = 1 + (start + i) % 100
        handle = open(Path(tempfile.gettempdir()) / f"gait_biofeedback_test_domain_{domain}.lock", "w")  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _HELD_DOMAIN.append(handle)
        return domain
    return 1 + start


# One DDS domain per test process (each pytest-xdist worker its own), inherited by the subprocesses the
# tests start.
if "GAIT_TEST_DOMAIN_ID" in os.environ:
    os.environ["ROS_DOMAIN_ID"] = os.environ["GAIT_TEST_DOMAIN_ID"]
else:
    os.environ["ROS_DOMAIN_ID"] = str(_claim_domain())
SHARED_DATA = REPO.parent / "shared" / "data"


def rosbags_typestore():
    """The PyPI ``rosbags`` typestore of ROS 2 Jazzy with the project's messages registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    import gait_biofeedback_msgs.msg as project_msgs
    from gait_biofeedback.io.schemas import msg_text

    store = get_typestore(Stores.ROS2_JAZZY)
    for name in (n for n in dir(project_msgs) if n[0].isupper()):
        store.register(get_types_from_msg(msg_text("gait_biofeedback_msgs", name),
                                          f"gait_biofeedback_msgs/msg/{name}"))
    return store


def shared_data(*parts: str) -> Path:
    """Path under ../shared/data, or skip the test with the reason when it is not there."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not found: {path} (../shared/data is not part of a user's clone)")
    return path


@pytest.fixture
def ros_context():
    """A fresh rclpy Context for one test, shut down afterwards whatever happens."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(args=[], context=context, domain_id=int(os.environ.get("ROS_DOMAIN_ID", "42")))
    try:
        yield context
    finally:
        if context.ok():
            rclpy.shutdown(context=context)


def synthetic_imu(segments: list[str], duration: float = 2.0, rate_hz: float = 100.0,
                  with_mag: bool = True, seed: int = 0, t0: float = 1000.0) -> dict:
    """Random-valued ImuSeries per segment (for I/O and transport tests, not physics)."""
    from gait_biofeedback.core.segments import ImuSeries

    rng = np.random.default_rng(seed)
    n = round(duration * rate_hz)
    t = t0 + np.arange(n) / rate_hz
    return {
        s: ImuSeries(s, t, rng.normal(0, 3, (n, 3)) + np.array([0, 0, 9.81]), rng.normal(0, 1, (n, 3)),
                     rng.normal(0, 2e-5, (n, 3)) if with_mag else None)
        for s in segments
    }


@pytest.fixture(scope="session")
def hip_flexion():
    """The simulated hip-flexion calibration trial the calibration tests share (seed 5)."""
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    return simulate(SCENARIOS["calibration_hip_flexion"](seed=5))


@pytest.fixture(scope="session")
def walking():
    """The simulated walking (PC8) calibration trial the calibration tests share (seed 6)."""
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    return simulate(SCENARIOS["calibration_walking"](seed=6))


def find_chromium() -> str | None:
    """Debian's chromium (or a Chrome) on PATH; None when no browser is installed."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        if path := shutil.which(name):
            return path
    return None


@contextlib.contextmanager
def spinning(context, *nodes):
    """The project's executor (``make_executor``) on ``context`` with ``nodes`` added. Leaving the block,
    whatever happened in it, destroys those nodes in the order given, then any node the block added to
    the executor itself (a late subscriber, a replayer started later), and shuts the executor down; a
    node the block removed from the executor is the block's to destroy (a graph stopped mid-test)."""
    from gait_biofeedback.nodes.common import make_executor

    executor = make_executor(context)
    try:
        for node in nodes:
            executor.add_node(node)
        yield executor
    finally:
        running = executor.get_nodes()
        added = [n for n in running if not any(n is given for given in nodes)]
        for node in (*(n for n in nodes if any(n is r for r in running)), *added):
            node.destroy_node()
        executor.shutdown()


@contextlib.contextmanager
def spinning_in_background(context, *nodes):
    """:func:`spinning`, the executor spun by a thread of its own until the block is left (the thread
    stops before the nodes are destroyed): for tests that drive a node from outside, e.g. a browser."""
    import threading

    from gait_biofeedback.nodes.common import spin_until

    with spinning(context, *nodes) as executor:
        stop = threading.Event()
        spinner = threading.Thread(target=lambda: spin_until(executor, stop.is_set), daemon=True)
        spinner.start()
        try:
            yield executor
        finally:
            stop.set()
            spinner.join(10)



def through_line_noise(frames: list[bytes], damaged: set[int], rng, max_noise: int, cuts: int,
                       before: bytes = b""):
    """The driver's serial FrameReader fed ``frames`` as a receiver's line delivers them: before each,
    0 to ``max_noise`` - 1 random bytes and ``before``; those indexed in ``damaged`` with byte 30
    flipped; the stream read in pieces cut at ``cuts`` random places. (the frames found, the reader)."""
    from gait_biofeedback.core.driver.protocol import FrameReader

    stream = b""
    for i, f in enumerate(frames):
        if i in damaged:
            f = f[:30] + bytes([f[30] ^ 0xFF]) + f[31:]
        stream += rng.bytes(int(rng.integers(0, max_noise))) + before + f
    reader = FrameReader()
    got = []
    ends = np.sort(rng.integers(0, len(stream), cuts))
    for a, b in zip([0, *ends], [*ends, len(stream)], strict=True):
        got += reader.feed(stream[a:b])
    return got, reader


# ---------------------------------------------------------------- the command line, in this process


def run_cli(*argv: str) -> tuple[int, str, str]:
    """``gait-biofeedback ARGV`` run in this process: (exit code, stdout, stderr). For module-scoped
    fixtures, where pytest's ``capsys`` is not available."""
    from gait_biofeedback.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(list(argv))
    return rc, out.getvalue(), err.getvalue()


def csv_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file with a header line, as the strings written."""
    with Path(path).open() as f:
        return list(csv.DictReader(f))


# ---------------------------------------------------------------- message stamps


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time (``msg.header.stamp``) in integer nanoseconds. Computed here, not by
    the package's own conversion, so that a test does not check that code against itself."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def stamp_s(stamp) -> float:
    """A builtin_interfaces/Time in seconds (the float nearest to its exact value)."""
    return stamp_ns(stamp) / 1e9


# ---------------------------------------------------------------- simulated sessions


def simulated_bag(folder: Path, config) -> tuple[Path, object]:
    """Simulate ``config`` and write it as a recording in ``folder``: (the bag, the simulated session)."""
    from gait_biofeedback.sim.recording import write_simulated_bag
    from gait_biofeedback.sim.simulator import simulate

    session = simulate(config)
    return write_simulated_bag(folder, session), session


def true_calibration(session, segments=None):
    """The SessionCalibration ("walking") that puts every sensor of ``segments`` (default: all the
    session simulated) exactly where the simulator mounted it: quality 1, valid."""
    from gait_biofeedback.core.calibration.sensor_to_segment import (
        SegmentCalibrationResult,
        SessionCalibration,
    )

    mounting = session.truth.mounting
    results = {s: SegmentCalibrationResult(s, mounting[s], True, 1.0, "x", 0.0) for s in segments or mounting}
    return SessionCalibration("walking", results, True, "")


def true_calibration_message(session, segments=None):
    """The SegmentCalibrationArray of :func:`true_calibration`, built field by field here (as a node
    would receive it on ``calibration/sensor_to_segment``)."""
    from gait_biofeedback_msgs.msg import SegmentCalibration, SegmentCalibrationArray

    mounting = session.truth.mounting
    msg = SegmentCalibrationArray(protocol="walking")
    for segment in segments or mounting:
        w, x, y, z = mounting[segment]
        entry = SegmentCalibration(segment=segment, sensor_frame=f"{segment}_imu", valid=True, quality=1.0)
        entry.rotation.w, entry.rotation.x, entry.rotation.y, entry.rotation.z = w, x, y, z
        msg.segments.append(entry)
    return msg
