"""What ``gait-biofeedback info`` says about a recording: per topic the count and the rate, the
rate from the messages' own stamps (the sensor's rate, whatever the speed it was recorded or
replayed at); and every unreadable chunk with the time range it took away."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from gait_biofeedback.io.bag_reader import BagReader, BagRecoveryWarning
from gait_biofeedback.io.schemas import message_class
from gait_biofeedback.wire.cdr import header_stamp_ns


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a recording."""

    topic: str
    type_name: str
    count: int
    rate_hz: float  # from the header stamps when the type has them, else from the log times
    from_stamps: bool
    stamps_back: int  # sensor stamps not after the one before (reordered or duplicated samples)


def _stamped(type_name: str) -> bool:
    """True when the CDR of ``type_name`` starts with a time (a std_msgs/Header, or a Time itself)."""
    try:
        fields = message_class(type_name).get_fields_and_field_types()
    except ValueError:
        return False
    first = next(iter(fields.values()), "")
    return first in ("std_msgs/Header", "builtin_interfaces/Time")


def _rate(ns: np.ndarray) -> float:
    span = float(ns.max() - ns.min()) if len(ns) > 1 else 0.0
    return (len(ns) - 1) / span * 1e9 if span > 0 else 0.0


def bag_info(reader: BagReader) -> tuple[list[TopicInfo], list[str]]:
    """(per-topic information, the bad chunks in words) of ``reader``'s recording; a full read."""
    types = reader.topics()
    stamped = {t: _stamped(n) for t, n in types.items()}
    stamps: dict[str, list[int]] = {t: [] for t in types}
    log_times: dict[str, list[int]] = {t: [] for t in types}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagRecoveryWarning)  # returned, not printed twice
        bad = reader.verify()
        for topic, _, data, log_ns in reader.raw_messages():
            log_times[topic].append(log_ns)
            stamp_ns = header_stamp_ns(data) if stamped[topic] else None
            if stamp_ns is not None:
                stamps[topic].append(stamp_ns)
    out = []
    for topic in sorted(types):
        from_stamps = len(stamps[topic]) == len(log_times[topic]) > 0
        ns = np.array(stamps[topic] if from_stamps else log_times[topic], dtype=np.int64)
        sensor = types[topic].startswith("sensor_msgs/")  # one publisher per topic: stamps must rise
        back = int(np.sum(np.diff(ns) <= 0)) if from_stamps and sensor else 0
        out.append(TopicInfo(topic, types[topic], len(log_times[topic]), _rate(ns), from_stamps, back))
    return out, bad
