"""One sensor's samples as the driver receives them → in sequence order, stamped in host time.

:class:`SensorStream` puts a sensor's samples back in the order of their sequence numbers and gives
each the host stamp of its device time (:class:`~gait_biofeedback.core.driver.clock.DeviceClock`):

* the next expected sample goes out at once (no added latency on a clean link);
* a sample after a gap is held until the missing ones come (reordered on the way) or until the
  oldest held sample has waited ``reorder_window``; the missing ones are then counted lost, and if
  one arrives later it is counted ``late`` and dropped (stamps never go back);
* a sample seen before is counted as a duplicate and dropped;
* a sequence number far behind (more than :data:`REBOOT_SAMPLES`), or one behind whose device time
  lies more than :data:`CLOCK_BACK_S` before the last sample's, is the sensor rebooting: its
  sequence and clock are picked up again from that sample (``reboots``), with a notice;
* a device time that does not fit the sequence numbers (more than :data:`CLOCK_JUMP_S` off the
  sensor's own rate) is the device clock being reset: the clock is estimated again
  (``clock_resets``), the sequence goes on;
* stamps are strictly increasing: a stamp not after the last one is moved 1 µs after it
  (``stamps_adjusted``).
"""

from __future__ import annotations

from collections import deque
from typing import NamedTuple

from gait_biofeedback.core.driver.clock import DeviceClock
from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.core.notices import Notices

REBOOT_SAMPLES = 1000
CLOCK_BACK_S = 1.0
CLOCK_JUMP_S = 1.0
LOST_MEMORY = 4096
"""Lost sequence numbers remembered (to tell a late sample from a duplicate)."""
_MOD = 1 << 32


def seq_diff(a: int, b: int) -> int:
    """``a - b`` for 32-bit sequence numbers that wrap (in [-2³¹, 2³¹))."""
    return (a - b + (1 << 31)) % _MOD - (1 << 31)


class StampedSample(NamedTuple):
    """A sample ready for the graph: the segment, the host stamp (int ns), angular velocity (rad/s),
    specific force (m/s²) and magnetic field (T or None)."""

    segment: str
    stamp_ns: int
    gyr: tuple[float, float, float]
    acc: tuple[float, float, float]
    mag: tuple[float, float, float] | None


class SensorStream:
    """One mapped sensor (module docstring)."""

    def __init__(self, sensor_id: int, segment: str, reorder_window_s: float = 0.05,
                 clock_bin_s: float = 0.5, clock_window_s: float = 60.0,
                 notices: Notices | None = None) -> None:
        self.sensor_id = sensor_id
        self.segment = segment
        self.reorder_window_ns = round(reorder_window_s * 1e9)
        self.clock = DeviceClock(clock_bin_s, clock_window_s)
        self.notices = notices if notices is not None else Notices()
        self.received = self.published = self.lost = self.late = self.duplicates = 0
        self.reboots = self.clock_resets = self.stamps_adjusted = 0
        self.last_arrival_ns: int | None = None
        self._next: int | None = None  # the sequence number expected next
        self._held: dict[int, tuple[DeviceSample, int]] = {}
        self._lost: deque[int] = deque(maxlen=LOST_MEMORY)
        self.last_device_us: int | None = None
        self._last_seq: int | None = None
        self._last_stamp = -1
        self._recent: deque[tuple[int, int]] = deque(maxlen=201)  # (sequence, device µs), last published

    @property
    def name(self) -> str:
        return f"{self.segment} (sensor {self.sensor_id})"

    def push(self, sample: DeviceSample, arrival_ns: int) -> list[StampedSample]:
        """One received sample → the samples that can go out now, in sequence order."""
        self.received += 1
        self.last_arrival_ns = arrival_ns
        if self._next is None:
            self._next = sample.sequence
        diff = seq_diff(sample.sequence, self._next)
        if diff < 0:
            back = (self.last_device_us is not None
                    and sample.device_time_us < self.last_device_us - CLOCK_BACK_S * 1e6)
            if diff < -REBOOT_SAMPLES or back:
                self._reboot(sample)
                diff = 0
            elif sample.sequence in self._lost:
                self._lost.remove(sample.sequence)
                self.late += 1
                return []
            else:
                self.duplicates += 1
                return []
        elif sample.sequence in self._held:
            self.duplicates += 1
            return []
        elif diff > REBOOT_SAMPLES and abs(self._time_error_us(sample)) > CLOCK_JUMP_S * 1e6:
            self._reboot(sample)  # a new sequence start, not an outage of the same clock
            diff = 0
        self.clock.observe(sample.device_time_us, arrival_ns)
        if diff == 0 and not self._held:  # in order: straight out
            self._next = (sample.sequence + 1) % _MOD
            return [self._stamp(sample)]
        self._held[sample.sequence] = (sample, arrival_ns)
        return self._release()

    def expire(self, now_ns: int) -> list[StampedSample]:
        """Give up waiting for missing samples once the oldest held one has waited the reorder
        window: they are lost, the held ones go out."""
        if not self._held:
            return []
        oldest = min(arrival for _, arrival in self._held.values())
        if now_ns - oldest < self.reorder_window_ns:
            return []
        first = min(self._held, key=lambda s: seq_diff(s, self._next))
        gap = seq_diff(first, self._next)
        self.lost += gap
        self._lost.extend((self._next + i) % _MOD for i in range(min(gap, LOST_MEMORY)))
        self._next = first
        return self._release()

    def _release(self) -> list[StampedSample]:
        out = []
        while self._next in self._held:
            sample, _ = self._held.pop(self._next)
            out.append(self._stamp(sample))
            self._next = (self._next + 1) % _MOD
        return out

    def _reboot(self, sample: DeviceSample) -> None:
        self.reboots += 1
        self.notices.say("warn", f"{self.name} restarted (sequence {self._last_seq} → {sample.sequence}, "
                         f"device clock {self.last_device_us} → {sample.device_time_us} µs): picked up "
                         f"again, clock re-estimated; {len(self._held)} held sample(s) dropped")
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

    def _check_clock(self, sample: DeviceSample) -> None:
        """Reset the clock estimate if the device time does not fit the sequence numbers."""
        error = self._time_error_us(sample)
        if abs(error) > CLOCK_JUMP_S * 1e6:
            self.clock_resets += 1
            self.notices.say("warn", f"{self.name}: device clock jumped by {error * 1e-6:+.3f} s against "
                             "its sequence numbers; clock offset and drift estimated again")
            self._recent.clear()
            self.clock.reset()
            self.clock.observe(sample.device_time_us, self.last_arrival_ns)

    def _stamp(self, sample: DeviceSample) -> StampedSample:
        self._check_clock(sample)
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
