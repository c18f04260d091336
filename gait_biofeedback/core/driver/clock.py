"""Device time → host (ROS) time of one sensor: clock offset and drift from arrival times.

Model: a sample taken at device time ``d`` arrives at host time ``a = offset + (1 + β) d + delay``
with ``delay >= 0`` (transmission, jitter, bursts, a busy host): the arrival times lie above a line
and touch it when a sample comes through fastest. :class:`DeviceClock` finds that lower line
(the classic one-way clock estimation of NTP/PTP without round trips):

* device time is cut into bins of ``bin_s``; per bin the sample with the smallest
  ``arrival - device`` is kept (the least-delayed one);
* the bins of the last ``window_s`` are fitted with a straight line by least squares; bins more
  than ``3·1.4826·MAD`` (at least :data:`MIN_REJECT_S`) above the line, a bin that arrived
  entirely late (a burst, the radio re-sending a backlog), are dropped and the line fitted again;
* a sample's host time is the line at its device time. Before the first bin closes, the line is
  the smallest ``arrival - device`` so far with no drift.

The host times are therefore the earliest arrival the link allows, i.e. the true sample times plus
the link's smallest latency, which is the same for sensors on the same link: sensors are aligned
with each other to the accuracy of their lower lines (benchmarks/driver.py measures it).
"""

from __future__ import annotations

from collections import deque

import numpy as np

MIN_REJECT_S = 0.0005
"""s: a bin is an outlier only if it lies at least this far above the line (whatever the MAD)."""


class DeviceClock:
    """The lower line of one sensor's arrival times (module docstring)."""

    def __init__(self, bin_s: float = 0.5, window_s: float = 60.0) -> None:
        if not 0 < bin_s < window_s:
            raise ValueError(f"clock bins of {bin_s} s must be positive and shorter than the window "
                             f"({window_s} s)")
        self.bin_s = bin_s
        self.window_s = window_s
        self.reset()

    def reset(self) -> None:
        """Forget everything (the sensor rebooted, its clock was reset)."""
        self._d0: int | None = None  # device µs and host ns of the first sample: the origin
        self._a0 = 0
        self._bins: deque[tuple[float, float]] = deque()
        self._bin = -1
        self._bin_min: tuple[float, float] | None = None
        self._alpha = 0.0  # s, the line: y = alpha + beta * x, y = (a - a0) - x, x = d - d0
        self._beta = 0.0
        self._running_min = float("inf")
        self.fits = 0

    @property
    def started(self) -> bool:
        return self._d0 is not None

    def observe(self, device_us: int, arrival_ns: int) -> None:
        """One sample's device time and host arrival time (any order; a sample older than the
        current bin only counts if its bin is still open)."""
        if self._d0 is None:
            self._d0, self._a0 = device_us, arrival_ns
        x = (device_us - self._d0) * 1e-6
        y = (arrival_ns - self._a0) * 1e-9 - x
        k = int(x // self.bin_s)
        if k > self._bin:
            if self._bin_min is not None:
                self._close(self._bin_min)
            self._bin, self._bin_min = k, (x, y)
        elif k == self._bin and self._bin_min is not None and y < self._bin_min[1]:
            self._bin_min = (x, y)
        if not self._bins and y < self._running_min:
            self._running_min = y
            self._alpha = y

    def _close(self, point: tuple[float, float]) -> None:
        self._bins.append(point)
        while self._bins and self._bins[0][0] < point[0] - self.window_s:
            self._bins.popleft()
        if len(self._bins) == 1:
            self._alpha, self._beta = point[1], 0.0
            return
        xs, ys = np.array(self._bins).T
        keep = np.ones(len(xs), dtype=bool)
        for _ in range(2):
            beta, alpha = np.polyfit(xs[keep], ys[keep], 1)
            r = ys - (alpha + beta * xs)
            mad = float(np.median(np.abs(r[keep] - np.median(r[keep]))))
            new = r <= max(3.0 * 1.4826 * mad, MIN_REJECT_S)
            if new.sum() < 2 or (new == keep).all():
                break
            keep = new
        self._alpha, self._beta = float(alpha), float(beta)
        self.fits += 1

    def to_host_ns(self, device_us: int) -> int:
        """The host time (int ns) of a sample taken at ``device_us``; RuntimeError before any
        :meth:`observe`."""
        if self._d0 is None:
            raise RuntimeError("DeviceClock.to_host_ns before any sample was observed")
        x = (device_us - self._d0) * 1e-6
        return self._a0 + round((x + self._alpha + self._beta * x) * 1e9)

    @property
    def drift_ppm(self) -> float:
        """How much faster the device clock runs than the host's, in parts per million."""
        return -self._beta / (1.0 + self._beta) * 1e6

    def offset_s(self, device_us: int) -> float:
        """Host time minus device time at ``device_us``, s."""
        return (self.to_host_ns(device_us) - device_us * 1000) * 1e-9


def map_device_time(device_us: np.ndarray, arrival_ns: np.ndarray, bin_s: float = 0.5,
                    window_s: float = 60.0) -> np.ndarray:
    """Batch form of :class:`DeviceClock`: the host stamps (int64 ns) the driver gives samples with
    these device times (µs) and arrival times (ns), in arrival order, each mapped with the line known
    when it arrived (as live)."""
    clock = DeviceClock(bin_s, window_s)
    out = np.empty(len(device_us), dtype=np.int64)
    for i, (d, a) in enumerate(zip(np.asarray(device_us).tolist(), np.asarray(arrival_ns).tolist(),
                                   strict=True)):
        clock.observe(d, a)
        out[i] = clock.to_host_ns(d)
    return out
