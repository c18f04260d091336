"""Recordings with reference orientations for gain optimisation, and the thesis' error measure.

A :class:`ReferenceRecording` is one IMU's samples with the reference orientation of the same sensor (sensor →
world), a body ``location`` (gains are optimised per location, thesis §4.3) and a ``group`` (the unit
of cross-validation: a participant, a day, a trial). Sources: BROAD (Laidig et al. 2021: one
hand-moved board, location ``board``, each trial its own group; references already aligned) and the
project's simulator (subjects = seeds, the legs' and trunk's sensors by location).

Error (thesis Eq 24-25, orientation.md §3.6): ᴱR = R_refᵀ · R_align · R_est with a constant world
alignment R_align taken as the mean rotation between reference and estimate over the last ``ALIGN_S``
seconds of quiet before the motion starts (the thesis uses the initial quiet standing; for BROAD it is
≈ identity); its ZYX Euler angles give the roll, pitch and yaw errors; the cost of a recording
is RMS(roll) + RMS(pitch) + RMS(yaw) over the scored samples (thesis ch. 5 cost).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.orientation.filters.config import segment_location

ALIGN_S = 1.0
MOTION_RAD_S = 0.3


@dataclass
class ReferenceRecording:
    """One sensor's samples (SI), its reference orientation (N, 4) and which samples are scored."""

    name: str
    location: str
    group: str
    rate_hz: float
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray | None
    reference: np.ndarray
    scored: np.ndarray

    @cached_property
    def motion_onset(self) -> int:
        """First sample with the gyro above ``MOTION_RAD_S`` (0 if never): where the motion starts."""
        moving = np.linalg.norm(self.gyr, axis=1) > MOTION_RAD_S
        return int(np.argmax(moving)) if moving.any() else 0

    def cut(self, seconds: float | None) -> ReferenceRecording:
        """The first ``seconds`` after the first scored sample (all of it when None)."""
        if seconds is None:
            return self
        first = int(np.argmax(self.scored)) if self.scored.any() else 0
        n = min(len(self.gyr), first + round(seconds * self.rate_hz))
        mag = None if self.mag is None else self.mag[:n]
        return replace(self, gyr=self.gyr[:n], acc=self.acc[:n], mag=mag, reference=self.reference[:n],
                       scored=self.scored[:n])


def broad_recordings(folder: str | Path, trials: Sequence[str] | None = None) -> list[ReferenceRecording]:
    """BROAD trials (``NN_*.mat``) of ``folder``, optionally only the numbers in ``trials``."""
    import scipy.io

    folder = Path(folder)
    paths = sorted(folder.glob("[0-9][0-9]_*.mat"))
    if not paths:
        raise ValueError(f"no BROAD trials (NN_*.mat) in {folder}")
    out = []
    for path in paths:
        if trials and path.stem[:2] not in trials:
            continue
        d = scipy.io.loadmat(path, squeeze_me=True)
        ref = np.asarray(d["opt_quat"], dtype=float)
        out.append(
            ReferenceRecording(
                path.stem,
                "board",
                path.stem[:2],
                float(d["sampling_rate"]),
                np.ascontiguousarray(d["imu_gyr"], dtype=float),
                np.ascontiguousarray(d["imu_acc"], dtype=float),
                np.ascontiguousarray(d["imu_mag"], dtype=float),
                ref,
                np.asarray(d["movement"], dtype=bool) & np.isfinite(ref).all(1),
            )
        )
    if not out:
        raise ValueError(f"none of the trials {list(trials or [])} is in {folder}")
    return out


def simulated_recordings(
    subjects: int, seconds: float = 30.0, locations: Sequence[str] | None = None, first_seed: int = 1
) -> list[ReferenceRecording]:
    """``subjects`` simulated walks (seeds ``first_seed``…), every sensor whose location is wanted."""
    from gait_biofeedback.sim.simulator import simulate as run_simulation
    from gait_biofeedback.sim.simulator import walk

    out = []
    for seed in range(first_seed, first_seed + subjects):
        session = run_simulation(walk(duration=seconds, seed=seed))
        for segment, imu in session.imu.items():
            loc = segment_location(segment)
            if locations and loc not in locations:
                continue
            ref = session.truth.sensor_orientation[segment]
            scored = imu.t >= 5.0  # after the 5 s of standing
            out.append(
                ReferenceRecording(
                    f"s{seed}_{segment}", loc, f"s{seed}", imu.rate_hz, imu.gyr, imu.acc, imu.mag, ref, scored
                )
            )
    return out


def euler_errors(estimate: np.ndarray, rec: ReferenceRecording) -> np.ndarray:
    """(M, 3) roll, pitch, yaw errors (rad) of the scored samples, after the world alignment over the
    ``ALIGN_S`` s before the motion starts (module docstring)."""
    onset = rec.motion_onset
    valid = np.isfinite(estimate).all(1) & np.isfinite(rec.reference).all(1)
    ok = rec.scored & valid
    n = max(1, int(ALIGN_S * rec.rate_hz))
    window = np.zeros_like(ok)
    window[max(0, onset - n) : onset] = True
    if not (window & valid).any():
        window[:n] = True
    window &= valid
    if not ok.any():
        return np.full((1, 3), np.inf)
    align = quat.IDENTITY
    if window.any():  # mean of q_ref ⊗ q_est* (hemisphere-aligned), the world alignment of Eq 25
        d = quat.canonical(quat.multiply(rec.reference[window], quat.conjugate(estimate[window])))
        align = quat.normalize(d.mean(0))
    e = quat.multiply(quat.conjugate(rec.reference[ok]), quat.multiply(align, estimate[ok]))
    yaw, pitch, roll = quat.to_euler_zyx(e)
    return np.stack([roll, pitch, yaw], 1)


def rms_errors(estimate: np.ndarray, rec: ReferenceRecording) -> np.ndarray:
    """RMS roll, pitch, yaw error (rad) of one recording."""
    e = euler_errors(estimate, rec)
    return np.sqrt(np.mean(e * e, axis=0))
