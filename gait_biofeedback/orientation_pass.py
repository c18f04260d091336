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

from gait_biofeedback.core.orientation.stream import OrientationParams, SegmentOrientationTracker
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.cdr import Stamped, decode_imu, decode_mag, pack_imu
from gait_biofeedback.wire.imu import mag_sample, orientation_fields, raw_sample
from gait_biofeedback.wire.stamps import ns_to_stamp

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
        for topic, type_name, data, log_ns in messages:
            item = PassItem(topic, type_name, data, log_ns)
            if log_ns >= self._next_status_ns and self.last_raw:
                item.status = self._status(log_ns)
            if topic in self._mag_of:
                if (tracker := self.trackers.get(self._mag_of[topic])) is not None:
                    tracker.add_mag(*mag_sample(decode_mag(data)))
            elif topic in self._segment_of:
                item.segment = seg = self._segment_of[topic]
                item.raw = raw = decode_imu(data)
                if (tracker := self.trackers.get(seg)) is not None:
                    self.last_raw[seg] = raw
                    self.last_log[seg] = self.newest_ns = log_ns
                    item.filtered = self._payloads(seg, tracker.update(*raw_sample(raw)))
                item.notices = self._notices()
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
        raw, variance = self.last_raw[seg], self.params.orientation_variance
        fields = [orientation_fields(seg, sample, raw, variance) for sample in samples]
        return [(pack_imu(*f), Stamped(*f)) for f in fields]

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
