"""The sample rate of a stream, measured from its stamps (issue 13).

Every rate-dependent constant of the core is stated in seconds and turned into samples with a rate;
a sensor that runs at another rate than configured (a driver set to 50 Hz, a logger at 400 Hz)
would silently scale every window. :class:`RateCheck` measures the rate from the first
``intervals`` stamp intervals (their mean, leaving out holes of over 3 median intervals: neither a
logger's jitter nor a gap moves it) and decides once which rate a stage uses: the
configured one if the measured one is within ``tolerance`` of it, else the measured one, with a
message naming both. Later changes of rate are not acted on (a stage rebuilt mid-walk would lose
its state).
"""

from __future__ import annotations

from statistics import median

from gait_biofeedback.core.stamps import NS_PER_S

TOLERANCE = 0.10
"""Relative difference between the measured and the configured rate above which the measured one is
used (issue 13: "a mismatch over 10 %")."""


class RateCheck:
    """Measured rate of one stream, compared once with ``configured_hz`` (module docstring)."""

    def __init__(self, configured_hz: float, intervals: int = 20, tolerance: float = TOLERANCE) -> None:
        self.configured_hz = float(configured_hz)
        self.rate_hz = float(configured_hz)  # the rate in use
        self.measured_hz: float | None = None
        self.intervals = int(intervals)
        self.tolerance = float(tolerance)
        self._dts: list[float] = []
        self._last_ns: int | None = None

    @property
    def mismatch(self) -> bool:
        """The measured rate differs from the configured one by more than the tolerance."""
        return self.measured_hz is not None and self.rate_hz != self.configured_hz

    def update(self, stamp_ns: int) -> str | None:
        """One stamp (in order). Returns a message the first time the rate is decided and it is not
        the configured one (the stage then switches to :attr:`rate_hz`), else None."""
        last, self._last_ns = self._last_ns, stamp_ns
        if self.measured_hz is not None or last is None or stamp_ns <= last:
            return None
        self._dts.append((stamp_ns - last) / NS_PER_S)
        return self.decide() if len(self._dts) >= self.intervals else None

    def decide(self) -> str | None:
        """Decide now with the intervals seen so far (none: keep the configured rate); as :meth:`update`."""
        if self.measured_hz is not None or not self._dts:
            return None
        typical = median(self._dts)
        # the mean interval (a logger's jittered clock averages out), holes left out
        kept = [dt for dt in self._dts if dt < 3.0 * typical]
        self.measured_hz = len(kept) / sum(kept)
        if abs(self.measured_hz / self.configured_hz - 1.0) <= self.tolerance:
            return None
        self.rate_hz = round(self.measured_hz, 3)
        return (f"samples arrive at {self.measured_hz:.1f} Hz, configured rate_hz is {self.configured_hz:g}: "
                f"using {self.rate_hz:g} Hz (set rate_hz to the sensor's rate to silence this)")


MISSING_WARN = 0.01
"""Share of a stream's samples missing from its stamps (per /diagnostics report) that is named."""
MISSING_SHARE_MIN = 20
"""Fewer samples expected in a report (the last, short one of a recording) are said as counts, not a
share: 3 samples missing at the end of a stream read "100 % missing" (ipol_gait 1-1's left foot)."""

HOLE = 1.75
"""An interval longer than this many sample periods is a hole (:func:`missing_samples`)."""


def missing_samples(periods: float) -> int:
    """Samples missing in an interval between two stamps ``periods`` sample periods long: none up to
    ``HOLE``, else the nearest whole number of periods less one.

    The one rule of the recorder (:class:`StampHoles`) and the orientation stream (issue 46; the stream
    used 1.5 periods). 1.75, not the midpoint 1.5 between no hole (1) and one sample missing (2): a
    logger's stamps that jitter by ±30 % of the period give intervals up to 1.6 periods, which 1.5
    counted as lost samples (and the stream bridged); a real hole is still found while the two stamps
    around it are off by less than 0.25 period together.
    """
    return round(periods) - 1 if periods > HOLE else 0


class StampHoles:
    """Samples missing from a stream, counted from holes in its stamps (in order; a reordered or
    repeated stamp is ignored) by :func:`missing_samples`. The period is the median of the first
    ``learn`` intervals (a hole early on does not move it). A logger whose stamps jitter by more than
    75 % of the period still counts phantom holes; a swapped pair counts one (the recorder sees
    samples in arrival order)."""

    def __init__(self, learn: int = 20) -> None:
        self.learn = int(learn)
        self.samples = 0
        self.missing = 0
        self._intervals: list[int] = []
        self._period: int | None = None
        self._last: int | None = None

    def update(self, stamp_ns: int) -> None:
        """One sample's stamp."""
        last = self._last
        if last is not None and stamp_ns <= last:
            return
        self._last = stamp_ns
        self.samples += 1
        if last is None:
            return
        dt = stamp_ns - last
        if self._period is None:
            self._intervals.append(dt)
            if len(self._intervals) >= self.learn:
                self._period = median(self._intervals)
            return
        self.missing += missing_samples(dt / self._period)
