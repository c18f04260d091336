"""The shimmer backend: Shimmer3 calibration and clock, the real pyshimmer reading fake devices on
pseudo-terminals (values, losses, a device out of range and back), and ``run --driver shimmer:...``
into a recording."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.io.vendors import shimmer_protocol as sp

pytest.importorskip("pyshimmer", reason="the shimmer backend's tests need pyshimmer (requirements.txt)")
pytestmark = pytest.mark.timeout(90)


def _series(segment: str, n: int = 300, rate_hz: float = 100.0, seed: int = 0) -> ImuSeries:
    """Bounded random values (within the Shimmer3's default ranges: ±2 g, ±500 °/s, ±1.3 Ga)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    acc = np.clip(rng.normal(0, 3, (n, 3)), -9, 9) + np.array([0, 0, 9.81])
    gyr = np.clip(rng.normal(0, 2, (n, 3)), -8, 8)
    mag = rng.normal(0, 2e-5, (n, 3))
    return ImuSeries(segment, t, acc, gyr, mag)


def test_calibration_bytes_give_the_shimmer_model_and_defaults_stand_in_for_unset_ones():
    # gyroscope: bias (10, -20, 0), sensitivity 65.5 LSB/(°/s) stored in hundredths, axes x→-y, y→-x, z→-z
    gyro = struct.pack(">3h3h9b", 10, -20, 0, 6550, 6550, 6550, 0, -100, 0, -100, 0, 0, 0, 0, -100)
    data = b"\xff" * 21 + gyro + b"\xff" * 42
    cal = sp.parse_calibration(data)
    # u = (10 + 65.5, -20 + 131, 0 - 32.75) → K⁻¹(u - b) = (1, 2, -0.5) °/s → R⁻¹: (-2, -1, 0.5) °/s
    assert cal["gyro"].apply((75.5, 111, -32.75)) == pytest.approx((-2.0, -1.0, 0.5), abs=1e-12)
    assert cal["low_noise"] == sp.DEFAULT_CALIBRATION["low_noise"]
    # the low-noise default: 2047 counts at rest, 83 LSB per m/s² along -z
    assert cal["low_noise"].apply((2047, 2047, 2047 - 83 * 9.81)) == pytest.approx((0, 0, 9.81), abs=1e-9)
    assert sp.parse_calibration(sp.calibration_bytes(cal)) == cal  # what the fake sends reads back
    with pytest.raises(ValueError, match="gyro sensitivity is 0"):
        sp.parse_calibration(b"\xff" * 21 + gyro[:6] + b"\0" * 6 + gyro[12:] + b"\xff" * 42)
    with pytest.raises(ValueError, match="20 bytes"):
        sp.parse_calibration(b"\0" * 20)


def test_the_24_bit_clock_unwraps_to_microseconds_and_sequences():
    unwrap = sp.TickUnwrapper()
    assert unwrap(0xFFFF00) == 0
    assert unwrap(0x000100) == 0x200  # across the wrap: 512 ticks later
    assert sp.ticks_to_us(sp.CLOCK_HZ) == 1_000_000 and sp.ticks_to_us(328) == 10009
    assert sp.rate_divider(100.0) == 328 and sp.rate_divider(200.0) == 164
    assert [sp.sequence_of(k * 328, 328) for k in (0, 1, 7)] == [0, 1, 7]


def _collect(link, seconds: float, until=None) -> list:
    """What ``link`` gives for ``seconds``, or until ``until(got)`` is true (then at most ``seconds``:
    a loaded machine connects later, the test waits for what it checks, not for a set time)."""
    got, end = [], time.monotonic() + seconds
    while time.monotonic() < end and not (until is not None and until(got)):
        got.extend(link.receive(0.05))
    return got


@pytest.mark.parametrize("accelerometer", ["wide_range", "low_noise"])
def test_pyshimmer_reads_the_fake_devices_values_in_si_with_losses_as_sequence_gaps(accelerometer):
    from gait_biofeedback.io.vendors.shimmer import ShimmerLink
    from gait_biofeedback.io.vendors.shimmer_fake import FakeShimmer, FakeShimmers

    series = [_series("left_foot", seed=1), _series("right_foot", seed=2)]
    if accelerometer == "low_noise":  # ±2 g
        for s in series:
            s.acc[:] = np.clip(s.acc, -15, 15)
    # their clocks wrap (at 512 s) while they stream
    fakes = [FakeShimmer(s, offset_s=511.5, loss=0.05, seed=k) for k, s in enumerate(series)]
    server = FakeShimmers(fakes).start()
    link = ShimmerLink({fakes[0].path: 3, fakes[1].path: 6}, 100.0, accelerometer)
    try:
        got = _collect(link, 20.0, lambda got: all(f.finished for f in fakes)
                       and len(got) == sum(f.sent for f in fakes))
    finally:
        link.close()
        server.close()
    assert link.problem is None
    for fake, sid, s in zip(fakes, (3, 6), series, strict=True):
        assert fake.finished
        samples = [item[0][0] for item in got if item[0][0].sensor_id == sid]
        assert {item[2] for item in got if item[0][0].sensor_id == sid} == {f"shimmer {fake.path}"}
        seq = np.array([x.sequence for x in samples])
        first = int(np.argmin(np.abs(s.acc - samples[0].acc).max(axis=1)))  # samples lost before it: unseen
        k = seq - seq[0] + first
        assert len(samples) == fake.sent
        assert int(np.sum(np.diff(seq) - 1)) + first + (len(s.t) - 1 - k[-1]) == fake.dropped > 0
        period_us = 328 / 32768 * 1e6  # the 100 Hz divider: 10009.8 µs
        assert np.abs(np.diff([x.device_time_us for x in samples]) - np.diff(seq) * period_us).max() <= 1.0
        # quantization: half a count of 1631 (or 83) LSB/(m/s²), 65.5 LSB/(°/s), 1100/980 LSB/Ga
        acc_lsb = 1631 if accelerometer == "wide_range" else 83
        assert np.abs(np.array([x.acc for x in samples]) - s.acc[k]).max() < 0.55 / acc_lsb
        assert np.abs(np.array([x.gyr for x in samples]) - s.gyr[k]).max() < np.radians(0.55 / 65.5)
        assert np.abs(np.array([x.mag for x in samples]) - s.mag[k]).max() < 0.55e-4 / 980


def test_a_device_out_of_range_is_reconnected_and_its_missed_samples_are_a_gap(monkeypatch):
    from gait_biofeedback.io.vendors.shimmer import ShimmerLink
    from gait_biofeedback.io.vendors.shimmer_fake import FakeShimmer, FakeShimmers

    monkeypatch.setattr(ShimmerLink, "SILENT_S", 0.8)
    monkeypatch.setattr(ShimmerLink, "RETRY_S", 0.2)
    monkeypatch.setattr(ShimmerLink, "CONNECT_TIMEOUT_S", 1.0)
    fake = FakeShimmer(_series("left_foot", n=1000))
    server = FakeShimmers([fake]).start()
    link = ShimmerLink({fake.path: 3}, 100.0)
    missing = ShimmerLink({"/nonexistent/rfcomm9": 4}, 100.0)
    try:
        got = _collect(link, 10.0, lambda got: len(got) > 100)
        fake.go_out_of_range(2.0)
        got += _collect(link, 3.0, lambda _: link.problem is not None)
        problem = link.problem
        got += _collect(link, 10.0, lambda _: link.problem is None)
        assert link.reconnects == 1 and not fake.finished  # back before its recording ends
        got += _collect(link, 15.0, lambda more: fake.finished and len(got) + len(more) == fake.sent)
        assert "no data from" in (problem or "") or "did not answer" in (problem or "")
        assert missing.receive(0.05) == [] and "cannot open /nonexistent/rfcomm9" in missing.problem
    finally:
        link.close()
        missing.close()
        server.close()
    seq = np.array([item[0][0].sequence for item in got])
    assert len(seq) == fake.sent and np.all(np.diff(seq) >= 1)
    assert int(np.sum(np.diff(seq) - 1)) == fake.dropped > 150  # the 2 s away: a gap the driver counts


def test_a_device_that_does_not_answer_is_given_up_on_and_connected_once_it_does(monkeypatch):
    from gait_biofeedback.io.vendors.shimmer import ShimmerLink
    from gait_biofeedback.io.vendors.shimmer_fake import FakeShimmer, FakeShimmers

    monkeypatch.setattr(ShimmerLink, "RETRY_S", 0.2)
    monkeypatch.setattr(ShimmerLink, "CONNECT_TIMEOUT_S", 0.4)
    fake = FakeShimmer(_series("left_foot", n=200))
    link = ShimmerLink({fake.path: 3}, 100.0)  # nobody answers on the terminal yet
    server = None
    try:
        assert _collect(link, 5.0, lambda _: link.problem is not None) == []
        assert link.problem == f"{fake.path} did not answer within 0.4 s; trying again in 0.2 s"
        server = FakeShimmers([fake]).start()
        got = _collect(link, 15.0, lambda got: fake.finished and len(got) == fake.sent)
    finally:
        link.close()
        if server is not None:
            server.close()
    assert link.problem is None and len(got) == fake.sent == 200  # streamed once, by one connection
    assert len({item[0][0].sequence for item in got}) == 200


def test_parameters_and_driver_spec_map_devices_to_segments():
    from gait_biofeedback.cli import parse_driver
    from gait_biofeedback.core.driver.stream import DriverParams
    from gait_biofeedback.core.params import ParameterError

    spec = parse_driver("shimmer:/dev/rfcomm0=left_shank,/dev/rfcomm1=chest")
    assert spec == {"backend": "shimmer", "devices": ["/dev/rfcomm0=left_shank", "/dev/rfcomm1=chest"]}
    assert DriverParams(**{**spec, "devices": tuple(spec["devices"])}).device_ids() == {
        "/dev/rfcomm0": 2, "/dev/rfcomm1": 7}
    assert parse_driver("dot:D4:22:CD:00:12:34=left_foot")["devices"] == ["D4:22:CD:00:12:34=left_foot"]
    with pytest.raises(ValueError, match="DEVICE_ID=SEGMENT"):
        parse_driver("shimmer:/dev/rfcomm0")
    for devices, what in [(("/dev/a=left_knee",), "names no segment"),
                          (("/dev/a=chest", "/dev/a=pelvis"), "twice"),
                          (("/dev/a=chest", "/dev/b=chest"), "twice")]:
        with pytest.raises(ParameterError, match=what):
            DriverParams(backend="shimmer", devices=devices)
    with pytest.raises(ParameterError, match="has no sensor id"):
        DriverParams(backend="shimmer", devices=("/dev/a=chest",), sensors=("0:pelvis",))


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_stream_sim_as_shimmer_and_run_driver_shimmer_record_8_devices_that_analyze_reads(tmp_path):
    from gait_biofeedback.core.segments import SEGMENTS
    from gait_biofeedback.io.bag import read_imu_bag, write_imu_bag

    series = {segment: _series(segment, n=300, seed=k) for k, segment in enumerate(SEGMENTS)}
    for s in series.values():
        s.t[:] += 1000.0
    bag = write_imu_bag(tmp_path / "in", series)
    out = tmp_path / "rec"
    cli = [sys.executable, "-m", "gait_biofeedback.cli"]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    link = ["--offset-s", "3", "--drift-ppm", "80", "--jitter-ms", "3", "--loss", "0.02", "--seed", "4"]
    sim = subprocess.Popen([*cli, "stream-sim", str(bag), "--as", "shimmer", *link], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True, env=env)
    run = None
    try:
        spec = next(word for line in sim.stdout for word in line.split() if word.startswith("shimmer:"))
        run = subprocess.Popen([*cli, "run", "--driver", spec, "--nodes", "", "--record", str(out),
                                "--duration", "60"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True)
        sent = sim.communicate(timeout=60)[0]  # it ends once every device has streamed its recording
        time.sleep(0.5)  # the last packets reach the recorder
        run.send_signal(signal.SIGINT)  # Ctrl-C: the recording is closed
        output = run.communicate(timeout=30)[0]
    finally:
        for p in (sim, run):
            if p is not None:
                p.kill()
    assert sim.returncode == 0 and run.returncode == 0, sent[-2000:] + output[-3000:]
    words = sent.split("sent ")[-1].split()
    n_sent, n_dropped = int(words[0]), int(sent.split("dropped ")[-1].split()[0])
    assert n_sent + n_dropped == 8 * 300 and n_dropped > 0
    recorded = read_imu_bag(out)
    assert sum(len(r) for r in recorded.values()) == n_sent  # every sample sent, once
    for segment, r in recorded.items():
        err = np.abs(r.acc[:, None, :] - series[segment].acc[None, :, :]).max(axis=2)
        # each recorded sample is one the device measured (to half a count of its ±8 g range)
        assert err.min(axis=1).max() < 0.55 / 408 + 1e-6
        assert np.all(np.diff(err.argmin(axis=1)) >= 1)  # in order, none twice
    analyzed = subprocess.run([*cli, "analyze", str(out), "-o", str(tmp_path / "an"), "--no-tables"],
                              capture_output=True, text=True, timeout=90)
    assert analyzed.returncode == 0, analyzed.stderr[-2000:]
    assert "wrote" in analyzed.stdout
