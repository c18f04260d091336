"""Recorded or simulated IMU data sent as live sensors would send it (``stream-sim``, the
``simulated`` driver backend, the driver's tests and benchmark).

Each sensor ``k`` (in the order of the mapping) has its own device clock,
``device_time = (1 + drift_k) · t + offset_k`` with ``offset_k = offset_s + 0.1 k`` s and
``drift_k = +drift_ppm`` for even ``k``, ``-drift_ppm`` for odd ``k`` (so the sensors disagree with
each other by twice the drift), where ``t`` is the sample's true time from the recording's stamps.
A frame of ``samples_per_frame`` samples of one sensor is sent when its last sample is taken, plus a
delay uniform in ``[0, jitter_ms]``; a fraction ``reorder`` of the frames is held back two frame
periods more (so they arrive after later ones), a fraction ``loss`` is not sent at all. Sequence
numbers count each sensor's samples from ``1000 k``. Given a session key, the frames are signed
(GBI2).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.core.driver.protocol import MAX_SAMPLES, DeviceSample, encode_frame
from gait_biofeedback.core.segments import ImuSeries


@dataclass(frozen=True)
class LinkModel:
    """How the devices' clocks and the link behave (module docstring)."""

    offset_s: float = 0.0
    drift_ppm: float = 0.0
    jitter_ms: float = 0.0
    loss: float = 0.0
    reorder: float = 0.0
    samples_per_frame: int = 1
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("loss", "reorder"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ValueError(f"--{name} is a fraction in [0, 1), got {getattr(self, name)}")
        if self.offset_s < 0 or self.jitter_ms < 0 or abs(self.drift_ppm) >= 1e5:
            raise ValueError("--offset-s and --jitter-ms must not be negative and --drift-ppm within ±1e5")
        if not 1 <= self.samples_per_frame <= MAX_SAMPLES:
            raise ValueError(f"samples per frame must be 1-{MAX_SAMPLES}, got {self.samples_per_frame}")

    def clock(self, k: int) -> tuple[float, float]:
        """(offset s, drift as a fraction) of sensor ``k``'s device clock."""
        return self.offset_s + 0.1 * k, (1 if k % 2 == 0 else -1) * self.drift_ppm * 1e-6


@dataclass
class SensorTruth:
    """What one sensor sent: true sample times (s from the start), device times (µs), sequence
    numbers, and which samples were dropped by the link."""

    sensor_id: int
    t: np.ndarray
    device_us: np.ndarray
    sequence: np.ndarray
    dropped: np.ndarray


class FrameSchedule:
    """Every frame of a session in sending order: :attr:`send_ns` (ns from the start, sorted),
    :attr:`dropped` (not sent), :meth:`frame` (its bytes, signed with ``key`` if given), :attr:`truth`
    per segment."""

    def __init__(self, series: Mapping[str, ImuSeries], ids: Mapping[str, int], link: LinkModel,
                 key: bytes | None = None) -> None:
        self._key = key
        rng = np.random.default_rng(link.seed)
        self.series = {seg: series[seg] for seg in ids if seg in series}
        missing = [seg for seg in ids if seg not in series]
        if not self.series:
            raise ValueError(f"no sensor of the mapping ({', '.join(ids)}) is in the recording "
                             f"(it has {', '.join(series)})")
        self.missing = missing
        m = link.samples_per_frame
        self.truth: dict[str, SensorTruth] = {}
        send, owner, first, lost_frames = [], [], [], []
        t_start = min(float(s.t[0]) for s in self.series.values())
        for k, (seg, s) in enumerate(self.series.items()):
            offset, drift = link.clock(k)
            t = np.asarray(s.t, dtype=float) - t_start
            n_frames = -(-len(t) // m)
            starts = np.arange(n_frames) * m
            last = np.minimum(starts + m - 1, len(t) - 1)
            period = float(np.median(np.diff(t))) * m if len(t) > 1 else 0.01
            delay = rng.uniform(0.0, link.jitter_ms * 1e-3, n_frames)
            delay += np.where(rng.random(n_frames) < link.reorder, 2.0 * period, 0.0)
            lost = rng.random(n_frames) < link.loss
            dropped = np.repeat(lost, m)[:len(t)]
            device_us = np.round(((1 + drift) * t + offset) * 1e6).astype(np.int64)
            self.truth[seg] = SensorTruth(ids[seg], t, device_us,
                                          1000 * k + np.arange(len(t)), dropped)
            send.append(t[last] + delay)
            owner.append(np.full(n_frames, k))
            first.append(starts)
            lost_frames.append(lost)
        order = np.argsort(np.concatenate(send), kind="stable")
        self.send_ns = np.round(np.concatenate(send)[order] * 1e9).astype(np.int64)
        self._owner = np.concatenate(owner)[order]
        self._first = np.concatenate(first)[order]
        self.dropped = np.concatenate(lost_frames)[order]
        self._segments = list(self.series)
        self._m = m

    def frame(self, i: int) -> bytes:
        """The bytes of frame ``i`` (in sending order)."""
        return encode_frame(self.frame_samples(i), self._key)

    def frame_samples(self, i: int) -> list[DeviceSample]:
        """The samples of frame ``i`` (in sending order), for a fake device of another protocol."""
        seg = self._segments[self._owner[i]]
        s, truth = self.series[seg], self.truth[seg]
        j0 = int(self._first[i])
        samples = []
        for j in range(j0, min(j0 + self._m, len(truth.t))):
            mag = None if s.mag is None else tuple(s.mag[j].tolist())
            samples.append(DeviceSample(truth.sensor_id, int(truth.sequence[j]), int(truth.device_us[j]),
                                        tuple(s.acc[j].tolist()), tuple(s.gyr[j].tolist()), mag))
        return samples

    @property
    def samples(self) -> int:
        return sum(len(t.t) for t in self.truth.values())

    @property
    def samples_dropped(self) -> int:
        return sum(int(t.dropped.sum()) for t in self.truth.values())


@dataclass
class SendReport:
    """What :func:`send_udp` did: the host time (ns) of the samples' time zero, samples sent and
    dropped, frames sent, how late the sender was at worst (s)."""

    t0_ns: int
    samples_sent: int
    samples_dropped: int
    frames_sent: int
    worst_lateness_s: float


def play_frames(schedule: FrameSchedule, send_frame: Callable[[int], None], lead_s: float = 0.2,
                progress: Callable[[float], None] | None = None,
                stop: Callable[[], bool] | None = None) -> SendReport:
    """``send_frame(i)`` for each frame of ``schedule`` not dropped, at its send time in real time (the
    first sample taken ``lead_s`` after the call). ``progress(fraction)`` is called about once a
    second; ``stop()``, asked every 256 frames, ends it early."""
    t0 = time.time_ns() + round(lead_s * 1e9)
    frames = worst = 0
    next_progress = 0
    n = len(schedule.send_ns)
    for i in range(n):
        due = t0 + int(schedule.send_ns[i])
        now = time.time_ns()
        if due > now + 200_000:
            time.sleep((due - now) * 1e-9)
            now = time.time_ns()
        while now < due:
            now = time.time_ns()
        worst = max(worst, now - due)
        if progress is not None and now >= next_progress:
            progress(i / n)
            next_progress = now + 1_000_000_000
        if stop is not None and i % 256 == 0 and stop():
            break
        if schedule.dropped[i]:
            continue
        send_frame(i)
        frames += 1
    sent = sum(int((~t.dropped).sum()) for t in schedule.truth.values())
    return SendReport(t0, sent, schedule.samples_dropped, frames, worst * 1e-9)


def send_udp(schedule: FrameSchedule, host: str, port: int, lead_s: float = 0.2,
             progress: Callable[[float], None] | None = None,
             stop: Callable[[], bool] | None = None) -> SendReport:
    """Send ``schedule``'s frames to ``host:port`` in real time (:func:`play_frames`)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        return play_frames(schedule, lambda i: sock.sendto(schedule.frame(i), (host, port)), lead_s, progress,
                           stop)
    finally:
        sock.close()


def simulated_schedules(scenario: str, rate_hz: float, ids: Mapping[str, int], loop: bool,
                        seed: int = 0, key: bytes | None = None) -> Iterator[FrameSchedule]:
    """The ``simulated`` driver backend's frames: the simulator's ``scenario`` with ideal clocks and
    link, one frame per sample and sensor (signed with ``key`` if given), again and again if ``loop``
    (each pass a sensor reboot)."""
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    if scenario not in SCENARIOS:
        raise ValueError(f"imu_driver: unknown scenario {scenario!r}; choose one of {sorted(SCENARIOS)}")
    config = SCENARIOS[scenario]()
    config.rate_hz = rate_hz
    config.seed = seed
    schedule = FrameSchedule(simulate(config).imu, ids, LinkModel(), key)
    yield schedule
    while loop:
        yield schedule
