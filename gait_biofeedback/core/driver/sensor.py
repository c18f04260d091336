"""One sensor's samples as the driver receives them → in sequence order, stamped in host time.

:class:`SensorStream` puts a sensor's samples back in the order of their sequence numbers and gives
each the host stamp of its device time (:class:`~gait_biofeedback.core.driver.clock.DeviceClock`):

* the next expected sample goes out at once (no added latency on a clean link);
* a sample after a gap is held until the missing ones come (reordered on the way) or until the
  oldest held sample has waited ``reorder_window_s``; the missing ones are then counted lost, and if
  one arrives later it is counted ``late`` and dropped (stamps never go back);
* a sample seen before is counted as a duplicate and dropped;
* a sample that does not fit the sequence is a *suspect*: a sequence number far behind (more than
  :data:`REBOOT_SAMPLES`) or behind with a device time more than :data:`CLOCK_BACK_S` before the
  last sample's (the sensor rebooted), far ahead (a reboot, or a long outage if its device time
  fits), or a device time more than :data:`CLOCK_JUMP_S` off the sensor's own rate (the device
  clock was reset). One sample never changes anything: suspects are set aside, unstamped and unseen
  by the clock estimate, until a chain of them is confirmed
  (:mod:`~gait_biofeedback.core.driver.chain`: 5 agreeing samples in at least 3 frames over at
  least 20 ms, arrived in real time) with no fitting sample of the old sequence in between. Then
  the chain is taken: a reboot (sequence and clock picked up again from its first sample,
  ``reboots``), a clock reset (``clock_resets``, the sequence goes on) or an outage (the samples in
  between lost); its samples go out, and the other suspects that fit then. A suspect not confirmed
  in time (2 s after its chain's next frame was due), beyond the chains' memory (766), or set aside
  when the old sequence goes on, is dropped (``rejected``);
* stamps are strictly increasing: a stamp not after the last one is moved 1 µs after it
  (``stamps_adjusted``).
"""

from __future__ import annotations

from collections import deque
from typing import NamedTuple

from gait_biofeedback.core.driver.chain import Chains, Link, seq_diff
from gait_biofeedback.core.driver.clock import DeviceClock
from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.core.notices import Notices

REBOOT_SAMPLES = 1000
CLOCK_BACK_S = 1.0
CLOCK_JUMP_S = 1.0
LOST_MEMORY = 4096
"""Lost sequence numbers remembered (to tell a late sample from a duplicate)."""
_MOD = 1 << 32


class StampedSample(NamedTuple):
    """A sample ready for the graph: the segment, the host stamp (int ns), angular velocity (rad/s),
    specific force (m/s²) and magnetic field (T or None)."""

    segment: str
    stamp_ns: int
    gyr: tuple[float, float, float]
    acc: tuple[float, float, float]
    mag: tuple[float, float, float] | None


class SensorStream:
    """One mapped sensor (module docstring). :attr:`source` is where its frames come from (set by
    :class:`~gait_biofeedback.core.driver.stream.DriverCore`), :attr:`foreign` the samples claiming
    its id from elsewhere, per source."""

    def __init__(self, sensor_id: int, segment: str, reorder_window_s: float = 0.05,
                 clock_bin_s: float = 0.5, clock_window_s: float = 60.0,
                 notices: Notices | None = None) -> None:
        self.sensor_id = sensor_id
        self.segment = segment
        self.reorder_window_ns = round(reorder_window_s * 1e9)
        self.clock = DeviceClock(clock_bin_s, clock_window_s)
        self.notices = notices if notices is not None else Notices()
        self.received = self.published = self.lost = self.late = self.duplicates = 0
        self.reboots = self.clock_resets = self.stamps_adjusted = self.rejected = 0
        self.source: str | None = None
        self.foreign: dict[str, int] = {}
        self.last_arrival_ns: int | None = None
        self._next: int | None = None  # the sequence number expected next
        self._held: dict[int, tuple[DeviceSample, int]] = {}
        self._lost: deque[int] = deque(maxlen=LOST_MEMORY)
        self.last_device_us: int | None = None
        self._last_seq: int | None = None
        self._last_stamp = -1
        self._recent: deque[tuple[int, int]] = deque(maxlen=201)  # (sequence, device µs), last published
        self._suspects = Chains()
        self._frames = 0

    @property
    def name(self) -> str:
        return f"{self.segment} (sensor {self.sensor_id})"

    @property
    def suspects(self) -> int:
        """Suspects set aside now (bounded by the chains' memory)."""
        return len(self._suspects)

    def push(self, sample: DeviceSample, arrival_ns: int, frame: int | None = None) -> list[StampedSample]:
        """One received sample → the samples that can go out now, in sequence order. ``frame``: a
        number of the frame it came in (samples of one frame share it); None: a frame of its own."""
        self.received += 1
        if self.last_arrival_ns is None or arrival_ns > self.last_arrival_ns:
            self.last_arrival_ns = arrival_ns  # held samples handed over late keep it from going back
        if frame is None:
            self._frames += 1
            frame = -self._frames
        if self._next is None:
            self._next = sample.sequence
        if self._suspicion(sample) is not None:
            return self._suspect(sample, arrival_ns, frame)
        return self._accept(sample, arrival_ns)

    def expire(self, now_ns: int) -> list[StampedSample]:
        """Give up waiting for missing samples once the oldest held one has waited the reorder
        window: they are lost, the held ones go out. Suspects that waited long enough
        (:mod:`~gait_biofeedback.core.driver.chain`) are rejected."""
        self._reject(self._suspects.expire(now_ns))
        if not self._held:
            return []
        oldest = min(arrival for _, arrival in self._held.values())
        if now_ns - oldest < self.reorder_window_ns:
            return []
        first = min(self._held, key=lambda s: seq_diff(s, self._next))
        self._count_lost(seq_diff(first, self._next))
        self._next = first
        return self._release()

    def _suspicion(self, sample: DeviceSample) -> str | None:
        """What ``sample`` would mean if confirmed: ``"reboot"``, ``"outage"``, ``"clock"`` (a reset
        device clock), or None: it fits the sequence (new, duplicate or late)."""
        diff = seq_diff(sample.sequence, self._next)
        if diff < 0:
            back = (self.last_device_us is not None
                    and sample.device_time_us < self.last_device_us - CLOCK_BACK_S * 1e6)
            return "reboot" if diff < -REBOOT_SAMPLES or back else None
        jumped = abs(self._time_error_us(sample)) > CLOCK_JUMP_S * 1e6
        if diff > REBOOT_SAMPLES:
            return "reboot" if jumped else "outage"
        return "clock" if jumped else None

    def _accept(self, sample: DeviceSample, arrival_ns: int) -> list[StampedSample]:
        """A sample that fits the sequence: out now, held, or dropped as a duplicate or late."""
        diff = seq_diff(sample.sequence, self._next)
        if diff < 0:
            if sample.sequence in self._lost:
                self._lost.remove(sample.sequence)
                self.late += 1
            else:
                self.duplicates += 1
            return []
        if sample.sequence in self._held:
            self.duplicates += 1
            return []
        if self._suspects:  # the old sequence goes on: what looked like a restart was none
            self._reject(self._suspects.clear())
        self.clock.observe(sample.device_time_us, arrival_ns)
        if diff == 0 and not self._held:  # in order: straight out
            self._next = (sample.sequence + 1) % _MOD
            return [self._stamp(sample)]
        self._held[sample.sequence] = (sample, arrival_ns)
        return self._release()

    def _suspect(self, sample: DeviceSample, arrival_ns: int, frame: int) -> list[StampedSample]:
        """Set ``sample`` aside; take the chain it confirms, if it does."""
        chain, dropped = self._suspects.add(sample, arrival_ns, frame)
        self._reject(dropped)
        return [] if chain is None else self._confirm(chain)

    def _confirm(self, chain: list[Link]) -> list[StampedSample]:
        """Take a confirmed chain: restart what its first sample says, then pass its samples on, and
        the other suspects that fit now (a sample of the chain's that came out of order)."""
        others = self._suspects.clear(keep=chain)
        first = chain[0].sample
        kind = self._suspicion(first)
        out: list[StampedSample] = []
        if kind == "reboot":
            self._reboot(first, len(chain))
        elif kind == "outage":
            out += self._skip_to(first.sequence)
        elif kind == "clock":
            self.clock_resets += 1
            jump_s = self._time_error_us(first) * 1e-6
            self.notices.say("warn", f"{self.name}: device clock jumped by {jump_s:+.3f} s against its "
                             f"sequence numbers (confirmed by {len(chain)} samples); clock offset and drift "
                             "estimated again")
            self._recent.clear()
            self.clock.reset()
        for s in chain:
            out += self._accept(s.sample, s.arrival_ns)
        self._reject([s for s in others if self._suspicion(s.sample) is not None])
        for s in others:
            if self._suspicion(s.sample) is None:
                out += self._accept(s.sample, s.arrival_ns)
        return out

    def _reject(self, suspects: list[Link]) -> None:
        if not suspects:
            return
        if self.rejected == 0:
            s = suspects[0].sample
            self.notices.say("warn", f"{self.name}: a sample that would restart its sequence or clock "
                             f"(sequence {s.sequence}, device clock {s.device_time_us} µs) was not confirmed "
                             "by the ones after it and was dropped (a glitch, or a frame forged or replayed "
                             "from the sensor's address); further ones are counted on /diagnostics "
                             "('rejected')")
        self.rejected += len(suspects)

    def _count_lost(self, gap: int) -> None:
        self.lost += gap
        self._lost.extend((self._next + i) % _MOD for i in range(min(gap, LOST_MEMORY)))

    def _skip_to(self, sequence: int) -> list[StampedSample]:
        """An outage ended at ``sequence``: the held samples go out, the ones missing are lost."""
        out = []
        while self._held:
            first = min(self._held, key=lambda s: seq_diff(s, self._next))
            self._count_lost(seq_diff(first, self._next))
            self._next = first
            out += self._release()
        self._count_lost(seq_diff(sequence, self._next))
        self._next = sequence
        return out

    def _release(self) -> list[StampedSample]:
        out = []
        while self._next in self._held:
            sample, _ = self._held.pop(self._next)
            out.append(self._stamp(sample))
            self._next = (self._next + 1) % _MOD
        return out

    def _reboot(self, sample: DeviceSample, confirmed_by: int) -> None:
        self.reboots += 1
        self.notices.say("warn", f"{self.name} restarted (sequence {self._last_seq} → {sample.sequence}, "
                         f"device clock {self.last_device_us} → {sample.device_time_us} µs, confirmed by "
                         f"{confirmed_by} samples): picked up again, clock re-estimated; {len(self._held)} "
                         "held sample(s) dropped")
        self.lost += len(self._held)
        self._held.clear()
        self._lost.clear()
        self._next = sample.sequence
        self.last_device_us = None
        self._recent.clear()
        self.clock.reset()

    def _time_error_us(self, sample: DeviceSample) -> float:
        """µs between the sample's device time and the one its sequence number implies at the
        sensor's own rate (0 until that rate is known)."""
        period_us = self._period_us()
        if self.last_device_us is None or period_us is None:
            return 0.0
        expected = self.last_device_us + seq_diff(sample.sequence, self._last_seq) * period_us
        return sample.device_time_us - expected

    def _stamp(self, sample: DeviceSample) -> StampedSample:
        stamp = self.clock.to_host_ns(sample.device_time_us)
        if stamp <= self._last_stamp:
            stamp = self._last_stamp + 1000
            self.stamps_adjusted += 1
        self._last_stamp = stamp
        self.last_device_us = sample.device_time_us
        self._last_seq = sample.sequence
        self._recent.append((sample.sequence, sample.device_time_us))
        self.published += 1
        return StampedSample(self.segment, stamp, sample.gyr, sample.acc, sample.mag)

    def _period_us(self) -> float | None:
        """µs per sequence number over the last published samples (None before two)."""
        if len(self._recent) < 2:
            return None
        (s0, d0), (s1, d1) = self._recent[0], self._recent[-1]
        steps = seq_diff(s1, s0)
        return (d1 - d0) / steps if steps > 0 and d1 > d0 else None

    def rate_hz(self) -> float:
        """The sensor's sampling rate in its own clock, lost samples included (last 200 published;
        NaN before 2)."""
        period = self._period_us()
        return float("nan") if period is None else 1e6 / period
