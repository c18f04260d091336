"""Batch entry point of the gait-event step: one foot's raw IMU recording → its IC/TC event times."""

from __future__ import annotations

from typing import Any

import numpy as np

from gait_biofeedback.core.calibration.foot import foot_calibration
from gait_biofeedback.core.gait.comparator import angular_velocity_events
from gait_biofeedback.core.gait.events import INITIAL_CONTACT, TERMINAL_CONTACT, GaitEventDetector
from gait_biofeedback.core.orientation.stream import track_orientation
from gait_biofeedback.core.segments import ImuSeries
from gait_biofeedback.core.stamps import ns_to_seconds, sample_stamps, seconds_to_ns

METHODS = ("nazarahari", "angular_velocity")


def detect_gait_events(gyr: np.ndarray, acc: np.ndarray, rate_hz: float, mag: np.ndarray | None = None,
                       method: str = "nazarahari", t: np.ndarray | None = None,
                       **options: Any) -> dict[str, list[float]]:
    """Events of one foot's raw IMU recording (quiet standing first, then walking) → ``{"ic": [s],
    "tc": [s]}``, event (extremum) times with sample 0 at 0 s, or on the time base ``t`` (s, one per
    sample, increasing) when given: a recording with lost samples keeps its holes (the orientation
    tracker bridges the short ones as the live node does) instead of being read as evenly sampled.

    Both methods calibrate the foot on the leading standing and the walking after it
    (:func:`~gait_biofeedback.core.calibration.foot.foot_calibration`). ``method="nazarahari"``
    (thesis Algorithm 1): the live path's orientation tracker
    (:func:`~gait_biofeedback.core.orientation.stream.track_orientation`: default filter, start-up
    step on the leading standing), then :class:`~gait_biofeedback.core.gait.events.GaitEventDetector`.
    ``method="angular_velocity"``: the literature comparator
    (:mod:`gait_biofeedback.core.gait.comparator`) on the calibrated sagittal angular velocity.
    ``options`` go to the detector. Raises ValueError for an unknown method or when the foot cannot
    be calibrated (the message says what the recording lacks).
    """
    if method not in METHODS:
        raise ValueError(f"unknown gait event method {method!r}; use one of {list(METHODS)}")
    gyr = np.asarray(gyr, dtype=float)
    acc = np.asarray(acc, dtype=float)
    r = foot_calibration(gyr, acc, rate_hz)
    if method == "angular_velocity":
        events = angular_velocity_events(gyr, rate_hz, r, **options)
        if t is None:
            return events
        at = np.asarray(t, dtype=float)
        index = np.arange(len(at)) / rate_hz  # the comparator's event times are sample numbers / rate
        return {kind: np.interp(times, index, at).tolist() for kind, times in events.items()}
    t = ns_to_seconds(sample_stamps(len(gyr), rate_hz)) if t is None else np.asarray(t, dtype=float)
    if len(t) != len(gyr) or np.any(np.diff(t) <= 0):
        raise ValueError("t must give one increasing time per sample")
    t_q, q, _ = track_orientation(ImuSeries("foot", t, acc, gyr, mag), rate_hz=rate_hz)
    out: dict[str, list[float]] = {INITIAL_CONTACT: [], TERMINAL_CONTACT: []}
    detector = GaitEventDetector(rate_hz=rate_hz, mounting=r, **options)
    for stamp_ns, qk in zip(seconds_to_ns(t_q).tolist(), q.tolist(), strict=True):
        if (event := detector.update(stamp_ns, qk)) is not None:
            out[event.kind].append(event.t)
    while (event := detector.flush()) is not None:
        out[event.kind].append(event.t)
    return out
