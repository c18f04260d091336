"""Messages of two sources written in one log-time order as they come, not held to the end (issue 19).

``analyze`` writes the recording's own messages (copied) and what the graph's stages produce from them
in the order of a stable sort by log time of ``[*copied, *produced]``: at equal log times the copied
ones first, each source in the order it came. Holding both until the end and sorting them cost about
1.4 MB of memory per second of an 8-sensor recording (a 600 s session peaked at 1.2 GB); here the
caller says, as it goes, before which log time no message is still to come (:meth:`LogOrderWriter.release`),
and what is released is written in runs of a few thousand messages (one :meth:`BagWriter.write_many`
each), which gives the same file byte for byte.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable
from operator import itemgetter

from gait_biofeedback.io.bag_writer import BagWriter, Message

_LOG_NS = itemgetter(0)


class LogOrderWriter:
    """Copied and produced messages into ``writer`` in the order described above. Each source must
    come in log-time order until :meth:`close`, which writes what is left in that order whatever the
    order it came in. ``hold``: messages held before what is released is written (memory: about
    300 bytes each). A third source, :meth:`batched`, is encoded in bulk by ``prepare`` (called before
    each write: it hands over what it holds); at equal log times it comes after the other two."""

    def __init__(self, writer: BagWriter, hold: int = 4096) -> None:
        self.writer = writer
        self.hold = hold
        self._copied: list[Message] = []
        self._produced: list[Message] = []
        self._batched: list[Message] = []
        self.prepare: Callable[[], None] | None = None
        self._before = -1  # the latest release (log times are >= 0)
        self._due = hold  # held messages at which the released ones are written

    def copied(self, log_ns: int, topic: str, type_name: str, data: bytes) -> None:
        """A message of the recording (its padding is checked when written)."""
        self._copied.append((log_ns, topic, type_name, data, False))

    def produced(self, log_ns: int, topic: str, type_name: str, data: bytes, padded: bool) -> None:
        """A message a stage produced (``padded``: its padding is zeroed already)."""
        self._produced.append((log_ns, topic, type_name, data, padded))

    def batched(self, log_ns: int, topic: str, type_name: str, data: bytes, padded: bool) -> None:
        """A message of the bulk-encoded source (from ``prepare``, in log-time order)."""
        self._batched.append((log_ns, topic, type_name, data, padded))

    def release(self, before_ns: int) -> None:
        """Every message logged before ``before_ns`` may be written: no message still to come is
        logged earlier (the caller's promise). Written once ``hold`` messages are held."""
        if before_ns > self._before:
            self._before = before_ns
        if len(self._copied) + len(self._produced) >= self._due:
            self._write_released()
            self._due = len(self._copied) + len(self._produced) + self.hold

    def _write_released(self) -> None:
        """Write the messages logged before the latest release: each source's are a run at its head
        (each comes in log-time order), merged by a stable sort, copied first at equal times."""
        if self.prepare is not None:
            self.prepare()
        copied, produced, batched = self._copied, self._produced, self._batched
        n_copied = bisect_left(copied, self._before, key=_LOG_NS)
        n_produced = bisect_left(produced, self._before, key=_LOG_NS)
        n_batched = bisect_left(batched, self._before, key=_LOG_NS)
        run = copied[:n_copied]
        if n_produced or n_batched:
            run += produced[:n_produced]
            run += batched[:n_batched]
            run.sort(key=_LOG_NS)
        del copied[:n_copied], produced[:n_produced], batched[:n_batched]
        self.writer.write_many(run)

    def close(self) -> None:
        """Write what is released, then the rest sorted (the stages' last messages can come out of
        order)."""
        self._write_released()
        if self.prepare is not None:
            self.prepare()
        rest = [*self._copied, *self._produced, *self._batched]
        rest.sort(key=_LOG_NS)
        self._copied.clear()
        self._produced.clear()
        self._batched.clear()
        self.writer.write_many(rest)
