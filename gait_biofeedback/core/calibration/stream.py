"""The live calibration's rolling buffer, shared by the ``calibration`` node and the offline analysis.

When the clinician presses Calibrate, the buffer looks back for the protocol just performed
(:func:`~gait_biofeedback.core.calibration.windows.find_standing_then_motion`) and calibrates every
segment on it (:func:`~gait_biofeedback.core.calibration.sensor_to_segment.calibrate_session`,
thesis ch. 3). Samples and the instant from which a result is in force are stamps in int ns
(``docs/conventions.md``); the stage's parameters are :class:`CalibrationParams`.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gait_biofeedback.core.calibration.file import CALIBRATION_FILE as CALIBRATION_FILE
from gait_biofeedback.core.calibration.file import read_calibration_file as read_calibration_file
from gait_biofeedback.core.calibration.file import write_calibration_file as write_calibration_file
from gait_biofeedback.core.calibration.sensor_to_segment import (
    NOT_IN_KIT,
    REQUESTS,
    SessionCalibration,
    calibrate_session,
)
from gait_biofeedback.core.calibration.walk import calibrate_feet_from_walk
from gait_biofeedback.core.calibration.windows import find_standing_then_motion
from gait_biofeedback.core.params import param, require
from gait_biofeedback.core.segments import SEGMENTS, ImuSeries
from gait_biofeedback.core.stamps import NS_PER_S, s_to_ns


@dataclass(frozen=True)
class CalibrationParams:
    """Parameters of the calibration stage (node ``calibration``, and ``analyze``)."""

    segments: tuple[str, ...] = param(SEGMENTS, "segments calibrated by every request", choices=SEGMENTS)
    buffer_s: float = param(90.0, "how far back a request looks for the protocol", "s", low=10.0, high=600.0)
    session_dir: str = param("", "folder where each calibration is saved (calibration.yaml); '' = the "
                             "recording's folder when the graph records (run/replay --record), else session")
    reload_calibration: bool = param(False, "put the calibration saved in session_dir in force at start "
                                     "(only when it is this patient's: that is not checked)")
    calibration_file: str = param("", "a calibration.yaml (e.g. this patient's earlier session) in force "
                                  "from the start ('' = none; overrides reload_calibration)")
    default_standing_duration_s: float = param(3.0, "quiet standing a request needs when it names none "
                                               "(offline auto: none that long, the longest of at least "
                                               "0.5 s, said in the result)", "s", low=0.2, high=30.0)
    apply_delay_s: float = param(0.5, "a result is in force from this long after the newest sample used "
                                 "(time for every consumer to receive it)", "s", low=0.01, high=10.0)

    def __post_init__(self) -> None:
        require(bool(self.segments) and len(set(self.segments)) == len(self.segments),
                f"parameter 'segments': {list(self.segments)} must name each segment at most once")


@dataclass(frozen=True)
class CalibrationAttempt:
    """What one calibration request gave: ``success``, a ``message`` a clinician can act on, the
    result (None when refused before the core ran), the stamp ``until_ns`` of the newest sample used
    (None when no data was looked at), and ``applies_from_ns``: the sample stamp from which the new
    calibration is in force (``until + apply_delay_s``), so every consumer switches at the same sample;
    ``looks_like``: the protocol the movement showed (None: not looked at, or it could not tell), which
    the dashboard proposes after a refusal."""

    protocol: str
    success: bool
    message: str
    calibration: SessionCalibration | None = None
    until_ns: int | None = None
    applies_from_ns: int | None = None
    looks_like: str | None = None


class CalibrationBuffer:
    """Rolling buffer of every segment's orientation samples and the "calibrate now / at T" logic.

    :meth:`add` keeps the last ``buffer_s`` s (plus ``margin_s``, so a request for an instant a
    little in the past still sees its full window) of (stamp, raw acc, bias-corrected gyro,
    orientation) per segment. A repeated or slightly older stamp is ignored; a stamp more than 1 s
    older than the newest (a bag restarted) empties that segment's buffer.

    :meth:`calibrate` runs the protocol on the window ending at ``until_ns`` (default: each
    segment's newest sample) and starting ``buffer_s`` s earlier. :meth:`schedule` queues a
    request for a stamp the data has not reached yet; :meth:`run_due` (call it after each
    :meth:`add`) runs it as soon as every segment with data has a sample at or after that stamp,
    so the result depends on stamps only, never on when the request or the samples arrived.
    """

    def __init__(self, params: CalibrationParams | None = None, margin_s: float = 10.0) -> None:
        p = params or CalibrationParams()
        self.params = p
        self.segments = list(p.segments)
        self.buffer_s = p.buffer_s
        self.default_standing = p.default_standing_duration_s
        self.apply_delay_ns = s_to_ns(p.apply_delay_s)
        self.margin_s = float(margin_s)
        self.buffers: dict[str, deque[tuple[float, ...]]] = {s: deque() for s in self.segments}
        self._newest_ns: dict[str, int] = {}
        self._scheduled: list[tuple[int, str, dict[str, Any]]] = []
        self.six_d: list[str] = []

    def add(self, segment: str, stamp_ns: int, acc: Sequence[float], gyr: Sequence[float],
            q: Sequence[float], heading: bool = True) -> None:
        """One orientation sample of ``segment`` (acc m/s², gyro rad/s, q w,x,y,z; ``heading``: False
        when it was filtered without a magnetometer)."""
        buf = self.buffers[segment]
        t = stamp_ns / NS_PER_S
        if buf and t <= buf[-1][0]:
            if t < buf[-1][0] - 1.0:  # time went back (a bag restarted): start over
                buf.clear()
            else:
                return
        buf.append((t, *acc, *gyr, *q, float(heading)))
        self._newest_ns[segment] = stamp_ns
        keep_from = t - self.buffer_s - self.margin_s
        while buf and buf[0][0] < keep_from:
            buf.popleft()

    def newest(self, segment: str) -> int | None:
        """Stamp of the newest sample of ``segment``, None before any."""
        return self._newest_ns.get(segment) if self.buffers[segment] else None

    def _silent_text(self, silent: list[str]) -> str:
        """The segments left out of a calibration: those that never sent a sample are not in this kit
        (information: a feet-only kit), those that did and are silent now are named as missing."""
        absent = [s for s in silent if s not in self._newest_ns]
        quiet = [s for s in silent if s in self._newest_ns]
        return ((f"; {', '.join(absent)}: {NOT_IN_KIT}" if absent else "")
                + (f"; no data from {', '.join(quiet)} in the calibration window (not calibrated)"
                   if quiet else ""))

    def reached(self, until_ns: int, segments: Sequence[str] | None = None) -> bool:
        """True when some segment has data and every one with data has a sample at or after ``until_ns``."""
        newest = [self.newest(s) for s in (segments or self.segments)]
        seen = [ns for ns in newest if ns is not None]
        return bool(seen) and all(ns >= until_ns for ns in seen)

    def series(self, segments: Sequence[str], until_ns: int | None = None
               ) -> tuple[dict[str, ImuSeries], dict[str, np.ndarray]]:
        """Per segment with ≥ 2 samples in the window: (ImuSeries, (N, 4) orientations); the segments
        with most of the window filtered without magnetometer go to :attr:`six_d`."""
        data, ori = {}, {}
        self.six_d = []
        for seg in segments:
            buf = self.buffers[seg]
            if not buf:
                continue
            end = buf[-1][0] if until_ns is None else until_ns / NS_PER_S
            rows = [row for row in buf if end - self.buffer_s <= row[0] <= end]
            if len(rows) < 2:
                continue
            arr = np.array(rows, dtype=float)
            data[seg] = ImuSeries(seg, arr[:, 0], arr[:, 1:4], arr[:, 4:7])
            ori[seg] = arr[:, 7:11]
            if arr[:, 11].mean() < 0.5:  # most of the window without magnetometer (not just the first 50 ms)
                self.six_d.append(seg)
        return data, ori

    def calibrate(self, protocol: str, standing_duration: float = 0.0, motion_duration: float = 0.0,
                  segments: Sequence[str] | None = None, until_ns: int | None = None,
                  shorter_standing: bool = False, walk_only: bool = False) -> CalibrationAttempt:
        """Run ``protocol`` (or ``"auto"``: the one the movement shows) on the window ending at
        ``until_ns`` (see class docstring); refusals carry a message saying what to do, and that the
        previous calibration stays in force. Without ``segments`` named, the segments that sent data
        are calibrated and the silent ones named (a feet-only sensor set calibrates its feet); named
        ``segments`` must all have data. ``shorter_standing``: see :func:`find_standing_then_motion`;
        ``walk_only``: without a standing, the feet from the walk's stance phases
        (:func:`~.walk.calibrate_feet_from_walk`; offline ``auto`` only, as ``shorter_standing``)."""
        if protocol not in REQUESTS:
            return CalibrationAttempt(protocol, False, f"unknown protocol {protocol!r}: use one of "
                                      f"{list(REQUESTS)}")
        wanted = list(segments) if segments else self.segments
        bad = [s for s in wanted if s not in self.segments]
        if bad:
            return CalibrationAttempt(protocol, False, f"segments {bad} are not handled by this node "
                                      f"({self.segments})")
        data, ori = self.series(wanted, until_ns)
        if not data and until_ns is not None and any(self.buffers[s] for s in wanted):
            return CalibrationAttempt(protocol, False, "no sensor data before the calibration instant: ask "
                                      "for an instant after the quiet standing and the movements; previous "
                                      "calibration stays in force", until_ns=until_ns)
        silent = [s for s in wanted if s not in data]
        if silent and (segments or not data):  # named segments must all have data; else any one suffices
            text = (f"no data from {', '.join(silent)}: check these sensors and the orientation filter; "
                    "previous calibration stays in force")
            return CalibrationAttempt(protocol, False, text)
        end_ns = until_ns if until_ns is not None else max(self._newest_ns[s] for s in data)
        try:
            standing, motion = find_standing_then_motion(
                data, standing_duration or self.default_standing, motion_duration,
                shorter_standing=shorter_standing)
        except ValueError as exc:
            if not walk_only or protocol == "hip_flexion":
                return CalibrationAttempt(protocol, False, f"{exc}; previous calibration stays in force",
                                          until_ns=end_ns)
            cal = calibrate_feet_from_walk(data, ori, protocol)
            message = cal.message if cal.success else f"{exc}; {cal.message}"
            return CalibrationAttempt(cal.protocol, cal.success, message, cal, end_ns,
                                      end_ns + self.apply_delay_ns, cal.looks_like)
        cal = calibrate_session(data, standing, motion, protocol, orientations=ori,
                                common_heading=not self.six_d)
        message = cal.message + self._silent_text(silent)
        asked = standing_duration or self.default_standing
        if standing[1] - standing[0] < asked - 1e-6:
            short = (f"the quiet standing lasted only {standing[1] - standing[0]:.2f} s (asked {asked:g} s): "
                     "for a surer calibration stand still longer")
            message += f"; {short}"
            for result in cal.segments.values():  # into the calibration message, its file and the report
                if result.valid:
                    result.message = f"{result.message}; {short}" if result.message else short
        return CalibrationAttempt(cal.protocol, cal.success, message, cal, end_ns,
                                  end_ns + self.apply_delay_ns, cal.looks_like)

    def schedule(self, until_ns: int, protocol: str, **options: Any) -> None:
        """Calibrate with ``protocol`` on the window ending at stamp ``until_ns`` once the data gets
        there (``options``: ``standing_duration``, ``motion_duration``, ``segments``)."""
        self._scheduled.append((int(until_ns), protocol, options))
        self._scheduled.sort(key=lambda item: item[0])

    @property
    def scheduled(self) -> list[tuple[int, str]]:
        """(until_ns, protocol) of the requests still waiting for data."""
        return [(ns, p) for ns, p, _ in self._scheduled]

    def run_due(self) -> list[CalibrationAttempt]:
        """Run the scheduled requests whose stamp every segment has reached (oldest first)."""
        done = []
        while self._scheduled and self.reached(self._scheduled[0][0], self._scheduled[0][2].get("segments")):
            until_ns, protocol, options = self._scheduled.pop(0)
            done.append(self.calibrate(protocol, until_ns=until_ns, **options))
        return done
