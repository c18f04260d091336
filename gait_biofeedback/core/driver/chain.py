"""Chains of samples that agree with each other: what confirms a sensor's restart, or a new source.

A sample that does not fit what is known is set aside (:meth:`Chains.add`): a suspect of a
:class:`~gait_biofeedback.core.driver.sensor.SensorStream` (a restart, a clock reset, an outage),
or a sample from a source :class:`~gait_biofeedback.core.driver.stream.DriverCore` has not bound
yet. It extends the longest chain whose newest link it can follow: a sequence step of 1 to
:data:`CHAIN_GAP`, device time on by :data:`MIN_PERIOD_US`-:data:`MAX_PERIOD_US` per step and within
:data:`RATE_TOLERANCE` of the chain's first step. A chain is confirmed when a run of its links
ending at the new one

* holds at least :data:`CONFIRM_SAMPLES` samples in at least :data:`CONFIRM_FRAMES` frames,
* spans at least :data:`CONFIRM_SPAN_US` of device time, and
* arrived in real time: its arrival span is at least half its device-time span less
  :data:`JITTER_US` (so at least 5 ms). Frames sent in a burst confirm nothing; a genuine
  sensor's backlog burst confirms once samples in real time have followed it. The run may start
  at a link already dropped (its arrival still tells how long the chain took); its samples are the
  kept ones.

Links are kept at most :data:`SUSPECT_MEMORY` (the oldest dropped first), and until
:data:`SUSPECT_WAIT_S` after their chain's next frame is due (:func:`wait_ns`: a chain of frames of
255 samples at 50 Hz waits 5.1 s more). A dropped link is cut from its chain, which goes on from
its newer links.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from gait_biofeedback.core.driver.protocol import MAX_SAMPLES, DeviceSample

CONFIRM_SAMPLES = 5
"""Samples in one chain that confirm it."""
CONFIRM_FRAMES = 3
"""Frames the confirming run spans at least (one frame alone never confirms)."""
CONFIRM_SPAN_US = 20_000
"""µs of device time the confirming run spans at least (no burst at a claimed high rate confirms)."""
JITTER_US = 5_000
"""µs the confirming run's arrival span may fall short of half its device-time span (link jitter)."""
CHAIN_GAP = 8
"""Largest sequence step between two samples of a chain (samples lost while it forms)."""
RATE_TOLERANCE = 0.25
"""A chain's device time per sequence step may differ this much (fraction) from its first step's."""
MIN_PERIOD_US = 250
MAX_PERIOD_US = 200_000
"""µs of device time per sequence step a chain may have (4 kHz down to 5 Hz)."""
SUSPECT_WAIT_S = 2.0
"""s a link waits for the samples that confirm it, beyond when its chain's next frame is due."""
SUSPECT_MEMORY = CONFIRM_FRAMES * MAX_SAMPLES + 1
"""Links kept at most: a chain confirmed at the first sample of its third full frame fits."""
_MOD = 1 << 32


def seq_diff(a: int, b: int) -> int:
    """``a - b`` for 32-bit sequence numbers that wrap (in [-2³¹, 2³¹))."""
    return (a - b + (1 << 31)) % _MOD - (1 << 31)


@dataclass(eq=False, slots=True)
class Link:
    """A sample set aside: when and in which frame it came, the link it follows, the links and
    frames up to it (dropped ones included: upper bounds), its place among its frame's links in the
    chain (1 = first), the chain's µs per sequence step (None for a chain of one), the least
    :func:`_lead` of the links up to it, the tip of the chain it is in, whether it is kept."""

    sample: DeviceSample
    arrival_ns: int
    frame: int
    prev: Link | None
    length: int
    frames: int
    in_frame: int
    period_us: float | None
    least_lead: int
    tip: _Tip | None = None
    alive: bool = True


@dataclass(eq=False, slots=True)
class _Tip:
    """The newest link of a chain and until when (ns) the chain's links are kept."""

    end: Link
    until_ns: int


def wait_ns(arrival_ns: int, in_frame: int, period_us: float | None) -> int:
    """Until when (ns) a chain whose newest sample came at ``arrival_ns``, the ``in_frame``-th of its
    frame, at ``period_us`` per sample, waits: :data:`SUSPECT_WAIT_S` after its next frame is due."""
    return arrival_ns + round(SUSPECT_WAIT_S * 1e9 + in_frame * (period_us or 0.0) * 1e3)


class Chains:
    """Samples set aside until a chain of them is confirmed (module docstring)."""

    def __init__(self, memory: int = SUSPECT_MEMORY) -> None:
        self.memory = memory
        self._links: deque[Link] = deque()
        self._by_seq: dict[int, list[Link]] = {}
        self.longest = 0
        """The most links a chain has had since the last :meth:`clear`."""
        self._check_ns: int | None = None  # no link expires before

    def __len__(self) -> int:
        return len(self._links)

    def add(self, sample: DeviceSample, arrival_ns: int, frame: int) -> tuple[list[Link] | None, list[Link]]:
        """Set ``sample`` aside: (the chain it confirms, oldest first, or None; the links dropped to
        make room). A confirmed chain stays kept until :meth:`clear`."""
        prev = self._prev(sample)
        lead = _lead(sample, arrival_ns)
        if prev is None:
            link = Link(sample, arrival_ns, frame, None, 1, 1, 1, None, lead)
        else:
            steps = seq_diff(sample.sequence, prev.sample.sequence)
            step = (sample.device_time_us - prev.sample.device_time_us) / steps
            same = frame == prev.frame
            link = Link(sample, arrival_ns, frame, prev, prev.length + 1, prev.frames + (not same),
                        prev.in_frame + 1 if same else 1, prev.period_us or step, min(prev.least_lead, lead))
        until = wait_ns(arrival_ns, link.in_frame, link.period_us)
        if prev is not None and prev.tip is not None and prev.tip.end is prev:  # the chain grows
            link.tip = prev.tip
            link.tip.end, link.tip.until_ns = link, max(link.tip.until_ns, until)
        else:  # a new chain, or a branch of one
            link.tip = _Tip(link, until)
        if self._check_ns is not None:
            self._check_ns = min(self._check_ns, until)
        self.longest = max(self.longest, link.length)
        self._links.append(link)
        self._by_seq.setdefault(sample.sequence, []).append(link)
        dropped = []
        while len(self._links) > self.memory:
            dropped.append(self._drop(self._links.popleft()))
        return self._confirmed(link), dropped

    def expire(self, now_ns: int) -> list[Link]:
        """Drop the links whose chain has waited long enough (module docstring)."""
        if not self._links:
            return []
        check = self._links[0].arrival_ns + SUSPECT_WAIT_S * 1e9 if self._check_ns is None else self._check_ns
        if now_ns <= check:
            return []
        old = [link for link in self._links if now_ns > link.tip.until_ns]
        self._links = deque(link for link in self._links if now_ns <= link.tip.until_ns)
        self._check_ns = min((link.tip.until_ns for link in self._links), default=None)
        return [self._drop(link) for link in old]

    def clear(self, keep: Iterable[Link] = ()) -> list[Link]:
        """Drop every link; the dropped ones not in ``keep``."""
        kept = set(keep)
        out = [self._drop(link) for link in self._links]
        self._links.clear()
        self.longest = 0
        self._check_ns = None
        return [link for link in out if link not in kept]

    def _drop(self, link: Link) -> Link:
        link.alive = False
        link.prev = link.tip = None  # its ancestry can be freed
        bucket = self._by_seq[link.sample.sequence]
        bucket.remove(link)
        if not bucket:
            del self._by_seq[link.sample.sequence]
        return link

    def _prev(self, sample: DeviceSample) -> Link | None:
        """The longest chain ``sample`` can follow (the nearest in sequence of equals)."""
        best = None
        for steps in range(1, CHAIN_GAP + 1):
            for link in self._by_seq.get((sample.sequence - steps) % _MOD, ()):
                if (best is None or link.length > best.length) and _follows(link, sample):
                    best = link
        return best

    @staticmethod
    def _confirmed(last: Link) -> list[Link] | None:
        """The kept chain ending at ``last`` if a run of it ending there confirms it (module
        docstring): the runs from the links up to the newest one that holds enough samples, frames and
        device time are checked at once by its :attr:`Link.least_lead`."""
        if last.length < CONFIRM_SAMPLES or last.frames < CONFIRM_FRAMES or last.in_frame > CONFIRM_SAMPLES:
            return None  # too short, or a later sample of a frame whose first ones did not confirm
        latest_start_us = last.sample.device_time_us - CONFIRM_SPAN_US
        n, frames, link = 0, set(), last
        while link is not None and link.alive:
            n += 1
            frames.add(link.frame)
            if n >= CONFIRM_SAMPLES and len(frames) >= CONFIRM_FRAMES and \
                    link.sample.device_time_us <= latest_start_us:
                break
            link = link.prev
        else:
            return None
        if link.least_lead > _lead(last.sample, last.arrival_ns) + 2000 * JITTER_US:
            return None  # arrived faster than real time
        chain = []
        link = last
        while link is not None and link.alive:
            chain.append(link)
            link = link.prev
        return chain[::-1]


def _follows(prev: Link, sample: DeviceSample) -> bool:
    """Whether ``sample`` can follow ``prev`` in a chain: a few sequence numbers on, its device time
    on at the chain's rate."""
    steps = seq_diff(sample.sequence, prev.sample.sequence)
    if not 1 <= steps <= CHAIN_GAP:
        return False
    step = (sample.device_time_us - prev.sample.device_time_us) / steps
    if not MIN_PERIOD_US <= step <= MAX_PERIOD_US:
        return False
    return prev.period_us is None or abs(step - prev.period_us) <= RATE_TOLERANCE * prev.period_us


def _lead(sample: DeviceSample, arrival_ns: int) -> int:
    """2 · arrival (ns) − device time (ns): a run from link j to link k arrived in real time
    (module docstring) iff lead_j <= lead_k + 2 · :data:`JITTER_US` (in ns)."""
    return 2 * arrival_ns - 1000 * sample.device_time_us
