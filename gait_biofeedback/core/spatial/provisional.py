"""A stride's length before its next stance: the forward filter's travel so far plus the rest of the
swing the foot usually makes (EXT, issue 16's live latency).

The smoothed stride (:mod:`.stream`) needs the next stance: the detector finds foot flat 0.1-0.3 s
after the initial contact (IC), so its values come 0.28-0.46 s after it. Around the IC the forward
filter (25 ms behind its newest sample, the detector's look-ahead) has the foot's horizontal travel
from the mean position of the last stance; what is missing is the short, repeatable travel from
there to foot flat. The provisional length is ``|d + ρ_f û + ρ_l l̂|``: ``d`` the travel so far, ``û``
its direction, ``l̂`` = ``û`` turned 90° left, and ``ρ`` the mean of the foot's last ``LEARN``
remainders (forward, left), each measured once its stride closed, from the same point to the forward
filter's mean position over the closing part of the next stance. With fewer than ``LEAST``
remainders there is no provisional value.

Trust (EXT): each estimate is compared, once its stride closes, with the smoothed stride length. A
foot's provisional values are published only while the root mean square of its last ``LEARN``
differences is within ``tolerance`` (``provisional_tolerance_m``, 5 cm: the clinically important
difference of step length) with at least ``CHECKED`` of them; otherwise its strides wait for their
smoothed values (0.28-0.46 s after the IC), as a foot's first strides do. The estimates go on being
made and compared, so the provisional values come back once they agree again. On the qmt walk
(100 Hz, 1.55 m/s) the provisional values differed from the smoothed by 10.7 cm SD, and cues from
them would have been wrong by more than the difference they are meant to show.

Measured on gaitmap_example (``benchmarks/spatial.py``), against the heel marker: with the mocap IC
and the filter at IC + 25 ms, −0.1 ± 2.6 cm on 56 strides (the smoothed value +0.1 ± 1.7 cm), within
3.6 cm SD for an IC found 50 ms early to 100 ms late; through ``analyze`` with the detected IC and the
filter at IC − 10 ms (the default, :mod:`gait_biofeedback.core.gait.spatial`), −0.2 ± 3.8 cm on 57.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

LEARN = 5  # remainders averaged
LEAST = 2  # remainders needed for a provisional value
CHECKED = 3  # estimates compared with their smoothed values before one is published
MIN_TRAVEL_M = 0.05  # less travel has no direction


class ProvisionalStride(NamedTuple):
    """A stride's values before it closes (SI; NaN when unknown): the swing left its stance at
    ``foot_off_ns``; the other fields are :class:`~.strides.SpatialStride`'s
    (:func:`~.strides.swing_so_far`)."""

    foot_off_ns: int
    stride_length: float
    max_sensor_height: float
    foot_angle_ic: float
    foot_angle_tc: float
    min_toe_clearance: float = math.nan
    turning_angle: float = math.nan
    lateral_excursion: float = math.nan


SWING_TOLERANCES = {"max_sensor_height": 0.02, "min_toe_clearance": 0.01, "foot_angle_ic": math.radians(5.0),
                    "foot_angle_tc": math.radians(5.0), "turning_angle": math.radians(10.0),
                    "lateral_excursion": 0.02}
"""EXT: RMS differences from the smoothed values within which a foot's provisional foot height, toe
clearance and lateral excursion (m), foot angles and turning angle (rad) are published
(:class:`SwingAgreement`). The toe clearance, a few cm, needs 1 cm. The turning angle tells a turn (over
the report's 20°: no spatial cue) from a straight stride; chosen on gaitmap_example through ``analyze``
(``benchmarks/spatial.py --cli-only``): with 5° 27 of its 51 provisional strides had one, with 10° 40,
each told turn or straight as its smoothed value tells it; on qmt's walk 53 of 54 either way."""


class Agreement:
    """How one provisional quantity of a foot agreed with its smoothed values: the last ``LEARN``
    differences; trusted while there are at least ``CHECKED`` and their RMS is within ``tolerance``;
    ``withheld`` counts the estimates refused once enough were checked."""

    def __init__(self, tolerance: float) -> None:
        self.tolerance = float(tolerance)
        self._differences: deque[float] = deque(maxlen=LEARN)
        self.withheld = 0

    @property
    def spread(self) -> float:
        """RMS of the last differences; NaN before any."""
        return math.sqrt(np.mean(np.square(self._differences))) if self._differences else math.nan

    @property
    def trusted(self) -> bool:
        return len(self._differences) >= CHECKED and self.spread <= self.tolerance

    def admit(self) -> bool:
        """May an estimate be published now (counted as withheld when not, once enough were checked)."""
        if self.trusted:
            return True
        self.withheld += len(self._differences) >= CHECKED
        return False

    def add(self, estimate: float, smoothed: float) -> None:
        """An estimate and its smoothed value (either NaN: nothing learnt)."""
        if math.isfinite(estimate) and math.isfinite(smoothed):
            self._differences.append(estimate - smoothed)


class SwingAgreement:
    """One foot's trust in its provisional swing values (EXT: foot height, toe clearance, foot angles,
    turning angle, lateral excursion), value by value as
    :class:`RestOfSwing` trusts the lengths (an :class:`Agreement` each, ``SWING_TOLERANCES``): a value
    not trusted is NaN, and the smoothed value follows with the stride's revision. Through ``analyze``
    (``benchmarks/spatial.py --cli-only``), against the smoothed values: gaitmap_example +0.1 ± 0.7 cm
    (45 of its 51 provisional strides), strike −0.1 ± 1.9° (45), push-off +0.3 ± 2.2° (40);
    qmt_fullbody's fast walk with its lengths let through (``provisional_tolerance_m`` 1 m), before this
    check +1.3 ± 4.6 cm and angles up to 68° off (95th percentile; the direction of travel so far was
    off), with it 6 heights of 62, 40 and 28 angles (−0.9 ± 1.9°, +0.3 ± 1.4°)."""

    def __init__(self) -> None:
        self.values = {name: Agreement(tolerance) for name, tolerance in SWING_TOLERANCES.items()}
        self._offered: ProvisionalStride | None = None

    def forget(self) -> None:
        """The current swing's estimate is void (the foot restarted)."""
        self._offered = None

    def offer(self, estimate: ProvisionalStride) -> ProvisionalStride:
        """``estimate`` with the values not trusted set to NaN; kept to be checked when its stride closes."""
        self._offered = estimate
        refused = [name for name, agreement in self.values.items() if not agreement.admit()]
        return estimate._replace(**dict.fromkeys(refused, math.nan))

    def check(self, foot_off_ns: int, smoothed: dict[str, float]) -> None:
        """The stride that left its stance at ``foot_off_ns`` has the smoothed values given (name → value;
        one not given is not learnt)."""
        if self._offered is not None and self._offered.foot_off_ns == foot_off_ns:
            for name, agreement in self.values.items():
                agreement.add(getattr(self._offered, name), smoothed.get(name, math.nan))
        self._offered = None


class RestOfSwing:
    """One foot's remainders, how its length estimates agreed with the smoothed lengths
    (:class:`Agreement`), and the pending request and estimate of the current swing."""

    def __init__(self, tolerance: float = 0.05) -> None:
        self.agreement = Agreement(tolerance)
        self._rests: deque[np.ndarray] = deque(maxlen=LEARN)
        self._asked: tuple[int, np.ndarray, np.ndarray] | None = None  # (foot_off_ns, now, û)
        self._offered: tuple[int, float] | None = None  # (foot_off_ns, estimate) awaiting its check

    @property
    def tolerance(self) -> float:
        return self.agreement.tolerance

    @property
    def withheld(self) -> int:
        """Estimates not published because the foot's differences spread."""
        return self.agreement.withheld

    @property
    def spread(self) -> float:
        """RMS (m) of the last estimates' differences from their smoothed lengths; NaN before any."""
        return self.agreement.spread

    @property
    def trusted(self) -> bool:
        """The foot's estimates agreed with the smoothed lengths (module docstring)."""
        return self.agreement.trusted

    def offer(self, foot_off_ns: int, length: float) -> float | None:
        """``length``, the estimate for the swing that left its stance at ``foot_off_ns``, if the
        foot's estimates are trusted, else None; kept to be checked when its stride closes."""
        self._offered = (foot_off_ns, float(length))
        return float(length) if self.agreement.admit() else None

    def check(self, foot_off_ns: int, smoothed_length: float) -> None:
        """The stride that left its stance at ``foot_off_ns`` has the smoothed length given."""
        if self._offered is not None and self._offered[0] == foot_off_ns:
            self.agreement.add(self._offered[1], smoothed_length)
        self._offered = None

    def estimate(self, foot_off_ns: int, start: np.ndarray, now: np.ndarray) -> float | None:
        """The provisional length (m) of the swing that left the stance at ``foot_off_ns`` (mean
        horizontal position ``start``), the forward filter now at ``now``; None without one. The
        request is kept to learn this swing's remainder when its stride closes (:meth:`learn`)."""
        travel = np.asarray(now[:2], float) - np.asarray(start[:2], float)
        distance = float(np.hypot(*travel))
        if distance < MIN_TRAVEL_M:
            return None
        ahead = travel / distance
        self._asked = (foot_off_ns, np.asarray(now[:2], float), ahead)
        if len(self._rests) < LEAST:
            return None
        forward, left = np.mean(self._rests, axis=0)
        return float(np.hypot(*(travel + forward * ahead + left * np.array([-ahead[1], ahead[0]]))))

    def learn(self, foot_off_ns: int, end: np.ndarray) -> None:
        """The stride that left its stance at ``foot_off_ns`` closed at the mean position ``end``."""
        if self._asked is None or self._asked[0] != foot_off_ns:
            return
        _, now, ahead = self._asked
        self._asked = None
        rest = np.asarray(end[:2], float) - now
        self._rests.append(np.array([rest @ ahead, rest @ np.array([-ahead[1], ahead[0]])]))

    def forget_request(self) -> None:
        """The current swing's request is void (the foot restarted)."""
        self._asked = None
        self._offered = None
