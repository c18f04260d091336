"""Sensor faults injected into a recording, as a body network makes them (issue 13).

Each fault edits the raw IMU messages of a recording (``/<segment>/imu/data_raw`` and
``/<segment>/imu/mag``), at a time in seconds from the recording's first message:

- :class:`Dropout`: the sensors send nothing for a while (radio loss, a sensor off and back on);
- :class:`Reorder`: consecutive samples of one sensor arrive in reverse order (stamps unchanged);
- :class:`Spike`: accelerometer samples of one sensor read an impossible value (a glitch);
- :class:`StampJump`: one sample of one sensor carries a stamp off by ``offset`` (a clock glitch);
- :class:`ClockStep`: every sample of one sensor from a time on carries a stamp off by ``offset`` (its
  clock stepped, or its driver restarted, while its samples kept arriving).

:func:`inject` applies them to ``(topic, type, CDR bytes, log_ns)`` tuples; :func:`write_faulty_bag`
copies a recording with faults. Ground truth topics are copied unchanged.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.io.bag import BagReader, BagWriter
from gait_biofeedback.wire.cdr import LINEAR_ACCELERATION, pack_imu, unpack_imu

Message = tuple[str, str, bytes, int]


def _segment_of(topic: str) -> str | None:
    for suffix in ("/imu/data_raw", "/imu/mag"):
        if topic.endswith(suffix):
            return topic[: -len(suffix)].lstrip("/")
    return None


@dataclass(frozen=True)
class Dropout:
    """Nothing from ``segments`` (all when empty) with a stamp in [at, at + duration) s."""

    at: float
    duration: float
    segments: tuple[str, ...] = ()

    @property
    def span(self) -> tuple[float, float]:
        return self.at, self.at + self.duration


class _AtOneInstant:
    """A fault of one instant ``at`` s: its time span (start, end) is that instant."""

    at: float

    @property
    def span(self) -> tuple[float, float]:
        return self.at, self.at


@dataclass(frozen=True)
class Reorder(_AtOneInstant):
    """``count`` consecutive samples of ``segment`` from ``at`` s arrive in reverse order."""

    segment: str
    at: float
    count: int = 2


@dataclass(frozen=True)
class Spike(_AtOneInstant):
    """``samples`` consecutive samples of ``segment`` from ``at`` s read ``value`` m/s² on every
    accelerometer axis."""

    segment: str
    at: float
    samples: int = 3
    value: float = 1e6


@dataclass(frozen=True)
class StampJump(_AtOneInstant):
    """The first sample of ``segment`` from ``at`` s is stamped ``offset`` s off (arrival unchanged)."""

    segment: str
    at: float
    offset: float = -0.5


@dataclass(frozen=True)
class ClockStep(_AtOneInstant):
    """Every sample of ``segment`` from ``at`` s is stamped ``offset`` s off (arrival unchanged)."""

    segment: str
    at: float
    offset: float = -1.0


Fault = Dropout | Reorder | Spike | StampJump | ClockStep


def _restamped(data: bytes, shift_ns: int = 0, acc: float | None = None) -> bytes:
    """The raw Imu ``data`` stamped ``shift_ns`` later, its specific force ``acc`` on every axis if given."""
    imu = unpack_imu(data)
    if imu is None:
        raise ValueError("not a sensor_msgs/Imu in the project's layout")
    values = list(imu.values)
    if acc is not None:
        values[LINEAR_ACCELERATION] = [acc] * 3
    return pack_imu(imu.ns + shift_ns, imu.frame_id, values)


def inject(messages: Sequence[Message], faults: Iterable[Fault], start_ns: int) -> list[Message]:
    """``messages`` (in log-time order) with ``faults`` applied; times of the faults in s from
    ``start_ns``. Returns a new list in arrival (log-time) order."""
    out = list(messages)
    for fault in faults:
        at_ns = start_ns + round(fault.at * NS_PER_S)
        if isinstance(fault, Dropout):
            end_ns = at_ns + round(fault.duration * NS_PER_S)
            wanted = set(fault.segments)

            def dropped(m: Message, lo: int = at_ns, hi: int = end_ns, only: set = wanted) -> bool:
                segment = _segment_of(m[0])
                return segment is not None and (not only or segment in only) and lo <= m[3] < hi

            out = [m for m in out if not dropped(m)]
            continue
        topic = f"/{fault.segment}/imu/data_raw"
        picks = [i for i, m in enumerate(out) if m[0] == topic and m[3] >= at_ns]
        if not picks:
            raise ValueError(f"{fault}: no {topic} sample at or after {fault.at} s")
        if isinstance(fault, Reorder):
            chosen = picks[: fault.count]
            logs = [out[i][3] for i in chosen]
            for i, log in zip(chosen, reversed(logs), strict=True):
                out[i] = (*out[i][:3], log)  # the later sample arrives first
        elif isinstance(fault, Spike):
            for i in picks[: fault.samples]:
                out[i] = (out[i][0], out[i][1], _restamped(out[i][2], acc=fault.value), out[i][3])
        else:
            for i in picks if isinstance(fault, ClockStep) else picks[:1]:
                shift_ns = round(fault.offset * NS_PER_S)
                out[i] = (out[i][0], out[i][1], _restamped(out[i][2], shift_ns=shift_ns), out[i][3])
    return sorted(out, key=lambda m: m[3])


def write_faulty_bag(source: str | Path, output: str | Path, faults: Iterable[Fault],
                     overwrite: bool = False) -> Path:
    """Copy the recording ``source`` to ``output`` with ``faults`` (see :func:`inject`)."""
    with BagReader(source) as reader:
        messages = list(reader.raw_messages())
        start_ns = reader.start_time_ns
    with BagWriter(output, overwrite=overwrite, flush_period_s=None) as writer:
        writer.write_many((log_ns, topic, type_name, data, False)
                          for topic, type_name, data, log_ns in inject(messages, faults, start_ns))
    return Path(output)
