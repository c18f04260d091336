"""Where the calibration protocol happened in a recording: quiet standing, then the motion.

The live calibration looks back over a rolling buffer when the clinician presses Calibrate (protocol:
"stand still 5 s, then ≥ 10 hip flexion/extension per leg or ≥ 8 straight steps, then Calibrate").
EXT/READING (the thesis does not say how the windows were cut, gait.md §1.12): a sample is *still*
when, on every segment, the 0.5 s moving mean of the gyro norm is below ``gyro_threshold`` and the
0.5 s moving standard deviation of the accelerometer norm is below ``acc_threshold``. The standing
window is the last ``standing_duration`` s of the last still run of at least that length that is
followed by at least ``min_motion`` s of movement; the motion window runs from the end of that run
to the end of the recording (trailing standing adds near-zero rates, harmless to the PCA).

Issue 15 (real sensors, through ``analyze --calibrate-at auto``): a still run ends while the
centred 0.5 s statistics still average the first movement in, so its last part is the movement's
onset, a weight shift before the first step (the standing check, RMS about the mean, refuses above
4.6 °/s). On ipol_gait 1-6 the right foot's last 3 s of the run have 3.7 °/s, 0.3 °/s without the
last 0.1 s; on 7-6 6.6 °/s without the last 0.1 s, 1.3 °/s without 0.15 s, 0.35 °/s without 0.2 s.
But a fixed margin can bring in an earlier movement: qmt's right thigh settles at 2.2-2.7 s, and its
window ending at the run's end passes (4.3 °/s) where one ending 0.25 s earlier does not (6.0 °/s).
So the standing window ends where the sensors are quietest (:func:`standing_window`: the smallest
largest-over-segments gyro RMS about the mean), at the run's end or up to ``ONSET_S`` before it (half
the statistics' window, 0.25 s, the farthest they look ahead), in steps of 0.05 s. When no run is long
enough and the request allows it (``analyze`` / ``replay --calibrate-at auto`` on a recording of
another lab), the longest run of at least ``MIN_STANDING_S`` (0.5 s) followed by movement is taken
instead, shorter than asked (the result says so): a walk that starts after a short standing is
calibrated, the quietness of that standing still checked (:func:`~.sensor_to_segment.standing_check`).
"""

from __future__ import annotations

import numpy as np

from gait_biofeedback.core.segments import ImuSeries

GYRO_STILL = 0.2  # rad/s, moving mean of |ω|
ACC_STILL = 0.3  # m/s², moving std of |a|
STILL_WINDOW = 0.5  # s
ONSET_S = STILL_WINDOW / 2  # s: how much of a still run's end may be the movement's onset
ONSET_STEP_S = 0.05  # s: the ends of the standing tried
MIN_STANDING_S = 0.5  # s: the shortest standing taken when none is as long as asked


def moving_mean(x: np.ndarray, n: int) -> np.ndarray:
    """Centred n-sample moving mean of (N,) or (N, k) ``x`` along its first axis, the ends padded with
    the edge values."""
    x = np.asarray(x, dtype=float)
    if x.ndim > 1:
        return np.column_stack([moving_mean(column, n) for column in x.T])
    kernel = np.ones(n) / n
    pad = np.pad(x, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(pad, kernel, mode="valid")


def rms_about_mean(x: np.ndarray) -> float:
    """RMS of the (N, k) ``x`` about its mean (norm over the k axes): how much a still sensor moved."""
    return float(np.sqrt(np.mean(np.sum((x - x.mean(axis=0)) ** 2, axis=1))))


def moving_std(x: np.ndarray, n: int) -> np.ndarray:
    """Centred n-sample moving standard deviation of (N,) or (N, k) ``x`` (as :func:`moving_mean`)."""
    return np.sqrt(np.maximum(moving_mean(np.square(x), n) - moving_mean(x, n) ** 2, 0.0))


def still_mask(series: ImuSeries, gyro_threshold: float = GYRO_STILL,
               acc_threshold: float = ACC_STILL) -> np.ndarray:
    """(N,) bool: the sensor is still around each sample (module docstring)."""
    n = max(3, round(STILL_WINDOW * series.rate_hz))
    gyro = moving_mean(np.linalg.norm(series.gyr, axis=1), n)
    acc_std = moving_std(np.linalg.norm(series.acc, axis=1), n)
    return (gyro < gyro_threshold) & (acc_std < acc_threshold)


def common_still(data: dict[str, ImuSeries]) -> tuple[np.ndarray, np.ndarray, ImuSeries]:
    """(t, still, the longest series): the longest series' times and whether every segment is still
    there (:func:`still_mask`). ValueError when there is no data, or too little."""
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
    return t, still, ref


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True))


def find_standing_then_motion(
    data: dict[str, ImuSeries],
    standing_duration: float = 3.0,
    motion_duration: float = 0.0,
    min_motion: float = 2.0,
    shorter_standing: bool = False,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """((t0, t1) standing, (t0, t1) motion) of the protocol just performed (module docstring).

    Raises ValueError with a message a clinician can act on when the recording has no such pattern.
    ``motion_duration`` > 0: at least that many seconds must follow the standing. ``shorter_standing``:
    without a standing that long, the longest of at least ``MIN_STANDING_S`` (offline ``auto`` only:
    live, the clinician can have the patient stand again, and a pause between hip flexions must not
    pass for standing).
    """
    t, still, ref = common_still(data)
    need_motion = max(min_motion, motion_duration)
    quiet = standing_runs(t, still)
    long_enough = any(b - a >= standing_duration - 1e-9 for a, b in quiet)
    followed = [(a, b) for a, b in quiet
                if np.sum(~still[np.searchsorted(t, b):]) / ref.rate_hz >= min_motion]
    moving_after = [(a, b) for a, b in followed if b - a >= standing_duration - 1e-9]
    if not moving_after and shorter_standing:  # the longest shorter one followed by movement
        shorter = [(a, b) for a, b in followed if b - a >= MIN_STANDING_S]
        moving_after = [max(shorter, key=lambda r: r[1] - r[0])] if shorter else []
    if not moving_after and not long_enough:
        longest = max((b - a for a, b in quiet), default=0.0)
        raise ValueError(f"no quiet standing of {standing_duration:g} s found in the last "
                         f"{t[-1] - t[0]:.0f} s (the longest: {longest:.1f} s): "
                         "ask the subject to stand still, then repeat the movements and calibrate (a "
                         "recording with a shorter standing: lower the calibration parameter "
                         "default_standing_duration_s)")
    if not moving_after:
        raise ValueError("no movement after the quiet standing: do the calibration movements "
                         "(hip flexion/extension or straight walking) before pressing Calibrate")
    standing = standing_window(data, *moving_after[-1], standing_duration)
    if t[-1] - standing[1] < need_motion:
        raise ValueError(f"only {t[-1] - standing[1]:.1f} s of movement after the quiet standing, "
                         f"need {need_motion:g} s")
    return standing, (standing[1], float(t[-1]))


def standing_runs(t: np.ndarray, still: np.ndarray) -> list[tuple[float, float]]:
    """(first, last) still sample times, s, of the still runs of ``still`` (on times ``t``)."""
    return [(float(t[a]), float(t[b - 1])) for a, b in runs(still) if b - a > 1]


def standing_window(data: dict[str, ImuSeries], start: float, end: float, duration: float
                    ) -> tuple[float, float]:
    """The standing (s) in the still run ``start``-``end``: ``duration`` s (or the run) ending where
    the segments are quietest, at ``end`` or up to ``ONSET_S`` before it (module docstring)."""
    best, chosen = np.inf, (max(start, end - duration), end)
    for k in range(round(ONSET_S / ONSET_STEP_S) + 1):
        e = end - k * ONSET_STEP_S
        a = max(start, e - duration)
        if e - a < min(MIN_STANDING_S, duration) - 1e-9:
            break
        worst = 0.0
        for series in data.values():
            gyr = series.gyr[(series.t >= a) & (series.t <= e)]
            if len(gyr) > 1:
                worst = max(worst, rms_about_mean(gyr))
        if worst < best - 1e-9:
            best, chosen = worst, (a, e)
    return chosen
