"""Where the calibration protocol happened in a recording: quiet standing, then the motion.

The live calibration looks back over a rolling buffer when the clinician presses Calibrate (protocol:
"stand still 5 s, then ≥ 10 hip flexion/extension per leg or ≥ 8 straight steps, then Calibrate").
EXT/READING (the thesis does not say how the windows were cut, gait.md §1.12): a sample is *still*
when, on every segment, the 0.5 s moving mean of the gyro norm is below ``gyro_threshold`` and the
0.5 s moving standard deviation of the accelerometer norm is below ``acc_threshold``. The standing
window is the last ``standing_duration`` s of the last still run of at least that length that is
followed by at least ``min_motion`` s of movement; the motion window runs from the end of that run
to the end of the recording (trailing standing adds near-zero rates, harmless to the PCA).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gait_biofeedback.core.calibration import PROTOCOLS, SessionCalibration, calibrate_session
from gait_biofeedback.core.segments import ImuSeries

GYRO_STILL = 0.2  # rad/s, moving mean of |ω|
ACC_STILL = 0.3  # m/s², moving std of |a|
STILL_WINDOW = 0.5  # s


def _moving(x: np.ndarray, n: int) -> np.ndarray:
    kernel = np.ones(n) / n
    pad = np.pad(x, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(pad, kernel, mode="valid")


def still_mask(series: ImuSeries, gyro_threshold: float = GYRO_STILL,
               acc_threshold: float = ACC_STILL) -> np.ndarray:
    """(N,) bool: the sensor is still around each sample (module docstring)."""
    n = max(3, round(STILL_WINDOW * series.rate_hz))
    gyro = _moving(np.linalg.norm(series.gyr, axis=1), n)
    a = np.linalg.norm(series.acc, axis=1)
    acc_std = np.sqrt(np.maximum(_moving(a**2, n) - _moving(a, n) ** 2, 0.0))
    return (gyro < gyro_threshold) & (acc_std < acc_threshold)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True))


def find_standing_then_motion(
    data: dict[str, ImuSeries],
    standing_duration: float = 3.0,
    motion_duration: float = 0.0,
    min_motion: float = 2.0,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """((t0, t1) standing, (t0, t1) motion) of the protocol just performed (module docstring).

    Raises ValueError with a message a clinician can act on when the recording has no such pattern.
    ``motion_duration`` > 0: at least that many seconds must follow the standing.
    """
    if not data:
        raise ValueError("no sensor data received: are the sensors on and the orientation filter running?")
    ref = max(data.values(), key=len)
    t = ref.t
    if len(t) < 2:
        raise ValueError("not enough sensor data yet: stand still 5 s, do the movements, then calibrate")
    still = np.ones(len(t), dtype=bool)
    for series in data.values():
        if len(series) < 2:
            continue
        s = still_mask(series).astype(float)
        still &= np.interp(t, series.t, s, left=0.0, right=0.0) > 0.5
    need_motion = max(min_motion, motion_duration)
    runs = [(a, b) for a, b in _runs(still) if t[b - 1] - t[a] >= standing_duration - 1e-9]
    if not runs:
        raise ValueError(f"no quiet standing of {standing_duration:g} s found in the last "
                         f"{t[-1] - t[0]:.0f} s: "
                         "ask the subject to stand still, then repeat the movements and calibrate")
    moving_after = [(a, b) for a, b in runs if np.sum(~still[b:]) / ref.rate_hz >= min_motion]
    if not moving_after:
        raise ValueError("no movement after the quiet standing: do the calibration movements "
                         "(hip flexion/extension or straight walking) before pressing Calibrate")
    _, b = moving_after[-1]
    t_end_stand = float(t[b - 1])
    if t[-1] - t_end_stand < need_motion:
        raise ValueError(f"only {t[-1] - t_end_stand:.1f} s of movement after the quiet standing, "
                         f"need {need_motion:g} s")
    return (t_end_stand - standing_duration, t_end_stand), (t_end_stand, float(t[-1]))


# ----------------------------------------------------------------------------------------------------
# The live calibration's rolling buffer (shared by the ``calibration`` node and the offline analysis)


@dataclass(frozen=True)
class CalibrationAttempt:
    """What one calibration request gave: ``success``, a ``message`` a clinician can act on, the
    result (None when refused before the core ran), the stamp ``until`` (s) of the newest sample
    used, and ``applies_from`` (s): the sample stamp from which the new calibration is in force
    (``until + apply_delay``), so every consumer switches at the same sample."""

    protocol: str
    success: bool
    message: str
    calibration: SessionCalibration | None = None
    until: float = math.nan
    applies_from: float = math.nan


class CalibrationBuffer:
    """Rolling buffer of every segment's orientation samples and the "calibrate now / at T" logic.

    :meth:`add` keeps the last ``buffer_s`` s (plus ``margin_s``, so a request for an instant a
    little in the past still sees its full window) of (stamp, raw acc, bias-corrected gyro,
    orientation) per segment. A repeated or slightly older stamp is ignored; a stamp more than 1 s
    older than the newest (a bag restarted) empties that segment's buffer.

    :meth:`calibrate` runs the protocol on the window ending at ``until`` (s; default: each
    segment's newest sample) and starting ``buffer_s`` s earlier. :meth:`schedule` queues a
    request for a stamp the data has not reached yet; :meth:`run_due` (call it after each
    :meth:`add`) runs it as soon as every segment with data has a sample at or after that stamp,
    so the result depends on stamps only, never on when the request or the samples arrived.
    """

    def __init__(self, segments: Sequence[str], buffer_s: float = 90.0,
                 default_standing_duration: float = 3.0, apply_delay: float = 0.5,
                 margin_s: float = 10.0) -> None:
        if apply_delay <= 0:
            raise ValueError(f"apply_delay must be > 0 s (consumers need time to receive the result), "
                             f"got {apply_delay}")
        self.segments = list(segments)
        self.buffer_s = float(buffer_s)
        self.default_standing = float(default_standing_duration)
        self.apply_delay = float(apply_delay)
        self.margin_s = float(margin_s)
        self.buffers: dict[str, deque[tuple[float, ...]]] = {s: deque() for s in self.segments}
        self._scheduled: list[tuple[float, str, dict[str, Any]]] = []

    def add(self, segment: str, t: float, acc: Sequence[float], gyr: Sequence[float],
            q: Sequence[float]) -> None:
        """One orientation sample of ``segment`` at stamp ``t`` s (acc m/s², gyro rad/s, q w,x,y,z)."""
        buf = self.buffers[segment]
        if buf and t <= buf[-1][0]:
            if t < buf[-1][0] - 1.0:  # time went back (a bag restarted): start over
                buf.clear()
            else:
                return
        buf.append((t, *acc, *gyr, *q))
        keep_from = t - self.buffer_s - self.margin_s
        while buf and buf[0][0] < keep_from:
            buf.popleft()

    def newest(self, segment: str) -> float | None:
        """Stamp (s) of the newest sample of ``segment``, None before any."""
        buf = self.buffers[segment]
        return buf[-1][0] if buf else None

    def reached(self, until: float, segments: Sequence[str] | None = None) -> bool:
        """True when some segment has data and every one with data has a sample at or after ``until``."""
        newest = [self.newest(s) for s in (segments or self.segments)]
        seen = [t for t in newest if t is not None]
        return bool(seen) and all(t >= until for t in seen)

    def series(self, segments: Sequence[str], until: float | None = None
               ) -> tuple[dict[str, ImuSeries], dict[str, np.ndarray]]:
        """Per segment with ≥ 2 samples in the window: (ImuSeries, (N, 4) orientations)."""
        data, ori = {}, {}
        for seg in segments:
            buf = self.buffers[seg]
            if not buf:
                continue
            end = buf[-1][0] if until is None else until
            rows = [row for row in buf if end - self.buffer_s <= row[0] <= end]
            if len(rows) < 2:
                continue
            arr = np.array(rows, dtype=float)
            data[seg] = ImuSeries(seg, arr[:, 0], arr[:, 1:4], arr[:, 4:7])
            ori[seg] = arr[:, 7:11]
        return data, ori

    def calibrate(self, protocol: str, standing_duration: float = 0.0, motion_duration: float = 0.0,
                  segments: Sequence[str] | None = None, until: float | None = None) -> CalibrationAttempt:
        """Run ``protocol`` on the window ending at ``until`` (see class docstring); refusals carry a
        message saying what to do, and that the previous calibration stays in force."""
        if protocol not in PROTOCOLS:
            return CalibrationAttempt(protocol, False, f"unknown protocol {protocol!r}: use one of "
                                      f"{list(PROTOCOLS)}")
        wanted = list(segments) if segments else self.segments
        bad = [s for s in wanted if s not in self.segments]
        if bad:
            return CalibrationAttempt(protocol, False, f"segments {bad} are not handled by this node "
                                      f"({self.segments})")
        data, ori = self.series(wanted, until)
        silent = [s for s in wanted if s not in data]
        if silent:
            text = (f"no data from {', '.join(silent)}: check these sensors and the orientation filter; "
                    "previous calibration stays in force")
            return CalibrationAttempt(protocol, False, text)
        end = until if until is not None else max(float(d.t[-1]) for d in data.values())
        try:
            standing, motion = find_standing_then_motion(
                data, standing_duration or self.default_standing, motion_duration)
        except ValueError as exc:
            return CalibrationAttempt(protocol, False, f"{exc}; previous calibration stays in force",
                                      until=end)
        cal = calibrate_session(data, standing, motion, protocol, orientations=ori)
        return CalibrationAttempt(protocol, cal.success, cal.message, cal, end, end + self.apply_delay)

    def schedule(self, until: float, protocol: str, **options: Any) -> None:
        """Calibrate with ``protocol`` on the window ending at stamp ``until`` s once the data gets
        there (``options``: ``standing_duration``, ``motion_duration``, ``segments``)."""
        self._scheduled.append((float(until), protocol, options))
        self._scheduled.sort(key=lambda item: item[0])

    @property
    def scheduled(self) -> list[tuple[float, str]]:
        """(until, protocol) of the requests still waiting for data."""
        return [(t, p) for t, p, _ in self._scheduled]

    def run_due(self) -> list[CalibrationAttempt]:
        """Run the scheduled requests whose stamp every segment has reached (oldest first)."""
        done = []
        while self._scheduled and self.reached(self._scheduled[0][0], self._scheduled[0][2].get("segments")):
            until, protocol, options = self._scheduled.pop(0)
            done.append(self.calibrate(protocol, until=until, **options))
        return done
