"""``analyze``'s orientation stage as one pass over a recording, read once for two users (issue 19).

The ``orientation_filter`` node's work offline: each raw IMU message, in log order, through its
segment's :class:`~gait_biofeedback.core.orientation.stream.SegmentOrientationTracker`, the samples it
releases serialised as the node publishes them, ``/diagnostics`` every ``diagnostics_period_s`` s of
recording time and the trackers' notices. An ``auto`` calibration looks ahead along this pass up to
the instant it finds (:func:`gait_biofeedback.analyze.calibration_ahead`) and keeps what it read; the
analysis then runs on those kept items and the rest of the same pass. Before, the look-ahead ran its
own trackers over the same messages (a sixth of ``analyze``'s time on the demo): the trackers see
each message once, in the same order, so both get what they got before, byte for byte
(test/test_analyze.py).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sensor_msgs.msg import Imu, MagneticField

from gait_biofeedback.core.orientation.stream import (
    OrientationBatch,
    OrientationParams,
    SegmentOrientationTracker,
)
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.cdr import (
    ANGULAR_VELOCITY,
    IMU_DOUBLES,
    LINEAR_ACCELERATION,
    MAG_DOUBLES,
    MAGNETIC_FIELD,
    Stamped,
    decode_stamped,
)
from gait_biofeedback.wire.imu import orientation_messages
from gait_biofeedback.wire.stamps import ns_to_stamp

BLOCK = 4096
"""Messages read ahead at most: a block ends there or where a ``/diagnostics`` status is due."""

Filtered = list[tuple[bytes, Stamped]]
"""Orientation samples as ``(<segment>/imu/data CDR, the same decoded)``."""


@dataclass
class PassItem:
    """One recorded message and what the orientation stage made of it.

    ``segment``/``raw``: the raw IMU message's segment and its decoded sample (None: a magnetometer or
    ground-truth message); ``filtered``: the samples its tracker released (None: no tracker for the
    segment); ``notices``: what the trackers said by now (warnings and errors, once each);
    ``status``: the ``/diagnostics`` message due before this message is handled."""

    topic: str
    type_name: str
    data: bytes
    log_ns: int
    segment: str | None = None
    raw: Stamped | None = None
    filtered: Filtered | None = None
    notices: list[str] = field(default_factory=list)
    status: Any | None = None


@dataclass
class PassEnd:
    """The end of the recording: what each tracker's reorder window still held (``flushed``, segment →
    samples, in the trackers' order), the notices said then and the last ``/diagnostics`` (None: no
    raw IMU sample at all) at ``status_ns``."""

    flushed: dict[str, Filtered]
    notices: list[str]
    status: Any | None
    status_ns: int


class OrientationPass:
    """The orientation stage over ``reader``'s raw IMU topics (``raw_topics``, ``mag_topics``: segment →
    topic) and its ``truth`` topics, passed through. Iterate once for the :class:`PassItem` of each
    message; then :meth:`finish`. ``last_raw``/``last_log``: each tracked segment's newest raw sample and
    its log time."""

    def __init__(self, reader: BagReader, raw_topics: dict[str, str], mag_topics: dict[str, str],
                 truth: list[str], params: OrientationParams) -> None:
        self.params = params
        self.raw_topics = raw_topics
        self.start_ns = reader.start_time_ns
        self.end_ns = reader.end_time_ns
        self.trackers: dict[str, SegmentOrientationTracker] = {
            seg: params.tracker(seg) for seg in params.segments if seg in raw_topics}
        self.last_raw: dict[str, Stamped] = {}
        self.last_log: dict[str, int] = {}
        self.newest_ns: int | None = None  # log time of the newest raw sample of a tracked segment
        self._segment_of = {topic: seg for seg, topic in raw_topics.items()}
        self._mag_of = {topic: seg for seg, topic in mag_topics.items()}
        self._period_ns = round(params.diagnostics_period_s * NS_PER_S)
        self._next_status_ns = self.start_ns + self._period_ns
        self._items = self._run(reader.raw_messages([*self._segment_of, *self._mag_of, *truth]))
        self._end: PassEnd | None = None

    def __iter__(self) -> Iterator[PassItem]:
        """The items not read yet (one iterator: a loop that stops early leaves the rest to the next)."""
        return self._items

    def put_back(self, items: list[PassItem]) -> None:
        """Items read ahead (an ``auto`` calibration's look-ahead): iterated again, before the rest."""
        self._items = itertools.chain(items, self._items)

    def _run(self, messages: Iterator[tuple[str, str, bytes, int]]) -> Iterator[PassItem]:
        """The messages a block at a time (up to a ``/diagnostics`` status, which reads the trackers'
        state there, or :data:`BLOCK` messages), each block through :meth:`_block`."""
        block: list[PassItem] = []
        seen_raw = False
        for topic, type_name, data, log_ns in messages:
            item = PassItem(topic, type_name, data, log_ns)
            if log_ns >= self._next_status_ns and seen_raw:
                yield from self._block(block)
                block = []
                item.status = self._status(log_ns)
            seen_raw = seen_raw or self.trackers.get(self._segment_of.get(topic, "")) is not None
            block.append(item)
            if len(block) >= BLOCK:
                yield from self._block(block)
                block = []
        yield from self._block(block)

    def _block(self, block: list[PassItem]) -> Iterator[PassItem]:
        """A block's raw IMU and magnetometer messages decoded in bulk per topic, each tracked segment's
        samples through :meth:`SegmentOrientationTracker.update_batch` (the magnetometer samples in
        between as they came), its outputs encoded in bulk; then its items, in log order."""
        by_topic: dict[str, list[int]] = {}
        for k, item in enumerate(block):
            if item.topic in self._segment_of or item.topic in self._mag_of:
                by_topic.setdefault(item.topic, []).append(k)
        raw_of: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # segment → (block indices, doubles)
        mags: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for topic, where in by_topic.items():
            if topic in self._mag_of:
                if self._mag_of[topic] in self.trackers:
                    data = [block[k].data for k in where]
                    ns, doubles, _ = decode_stamped(data, MagneticField, MAG_DOUBLES)
                    mags[self._mag_of[topic]] = (np.array(where), ns, doubles[:, MAGNETIC_FIELD])
                continue
            seg = self._segment_of[topic]
            frames: list[str] = []
            ns, doubles, _ = decode_stamped([block[k].data for k in where], Imu, IMU_DOUBLES, frames)
            for k, stamp, frame, row in zip(where, ns.tolist(), frames, doubles.tolist(), strict=True):
                block[k].segment, block[k].raw = seg, Stamped(stamp, frame, tuple(row))
            if seg in self.trackers:
                raw_of[seg] = (np.array(where), doubles)
        for seg in [s for s in self.trackers if s in raw_of or s in mags]:
            where, doubles = raw_of.get(seg, (np.zeros(0, np.int64), np.zeros((0, IMU_DOUBLES))))
            mag_where, mag_ns, mag = mags.get(seg, (np.zeros(0, np.int64), None, None))
            batch = self.trackers[seg].update_batch(
                np.array([block[k].raw.ns for k in where.tolist()], dtype=np.int64),
                doubles[:, ANGULAR_VELOCITY], doubles[:, LINEAR_ACCELERATION], mag_ns, mag,
                np.searchsorted(mag_where, where))
            messages = orientation_messages(seg, batch.stamp_ns, batch.q, batch.gyr, batch.acc,
                                            batch.recovering, batch.heading, doubles[batch.call],
                                            self.params.orientation_variance)
            bounds = np.searchsorted(batch.call, np.arange(len(where) + 1)).tolist()
            for j, k in enumerate(where.tolist()):
                block[k].filtered = messages[bounds[j]:bounds[j + 1]]
            for j, said in batch.notices:
                block[int(where[j])].notices = [n.text for n in said if n.level != "info"]
        for item in block:
            if item.raw is not None and item.filtered is not None:
                self.last_raw[item.segment] = item.raw
                self.last_log[item.segment] = self.newest_ns = item.log_ns
            yield item

    def finish(self) -> PassEnd:
        """Flush the trackers (once: later calls return the same)."""
        if self._end is None:
            flushed = {seg: self._payloads(seg, tracker.flush(end=True))
                       for seg, tracker in self.trackers.items() if seg in self.last_raw}
            notices = self._notices()
            status_ns = self.end_ns if self.newest_ns is None else self.newest_ns
            self._end = PassEnd(flushed, notices, self._status(status_ns) if self.last_raw else None,
                                status_ns)
        return self._end

    def _payloads(self, seg: str, samples: list) -> Filtered:
        batch = OrientationBatch.of([0] * len(samples), samples)
        raw = np.array([self.last_raw[seg].values])
        return orientation_messages(seg, batch.stamp_ns, batch.q, batch.gyr, batch.acc, batch.recovering,
                                    batch.heading, raw[batch.call], self.params.orientation_variance)

    def _notices(self) -> list[str]:
        return [n.text for tracker in self.trackers.values() if tracker.notices
                for n in tracker.notices.pop() if n.level != "info"]

    def _status(self, log_ns: int) -> Any:
        statuses = [diagnostics.orientation_status(seg, tracker, diagnostics.no_data(
                        (log_ns - self.last_log[seg]) / NS_PER_S, self.params.stale_after_s))
                    for seg, tracker in self.trackers.items() if seg in self.last_raw]
        self._next_status_ns = log_ns + self._period_ns
        return diagnostics.array(ns_to_stamp(log_ns), statuses)


def truth_topics(reader: BagReader) -> list[str]:
    """The recording's ``/ground_truth/...`` topics (copied into ``analyze``'s output)."""
    return [t for t in reader.topics() if t.startswith(topics.TRUTH_PREFIX + "/")]
