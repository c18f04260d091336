"""The activity monitor's output: the delay line of per-sample labels and the states it emits.

Every state describes the sample ``DELAY_S`` = 3 s before the newest input, and its labels are final
when emitted: walking needs 3 steps (≤ 2.6 s) before it is confirmed, and the detectors relabel the
samples still in the line from the instant they find (a walk's first step, a transition). The step
count and the last transition of a state are those with a time ≤ its sample's.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from gait_biofeedback.core.stamps import NS_PER_S, s_to_ns

DELAY_S = 3.0  # label delay: ≥ 3 steps at the slowest step duration (2 × 1.3 s) + peak latency


@dataclass(frozen=True)
class ActivityState:
    """What the ``activity_monitor`` node publishes (posture, modality, last transition, steps, θ)."""

    stamp_ns: int  # the sample this state describes (input stamp − DELAY_S)
    posture: str  # standing | sitting | lying
    locomotion: str  # none | level | upstairs | downstairs
    trunk_inclination: float  # rad, θ of Eq 54 (causal GA; READING: GA_v/|GA|, see ActivityMonitor.update)
    step_count: int  # steps with a time ≤ t since start
    last_transition: str | None  # one of TRANSITIONS
    last_transition_ns: int | None  # estimated instant of last_transition (a stamp, rounded to 1 ns)
    calibrated: bool  # False until the upright reference is known (reference.py, or the first reference_s s)

    @property
    def t(self) -> float:
        """The described sample's stamp in seconds."""
        return self.stamp_ns / NS_PER_S


class DelayLine:
    """Records ``[t, posture, walking, θ, stamp_ns, calibrated]`` held for ``delay_n`` samples."""

    def __init__(self, delay_n: int) -> None:
        self.delay_n = delay_n
        self.pending: deque[list] = deque()
        self.emitted_steps = 0  # steps with a time ≤ the last emitted sample's
        self._emitted_transitions = 0
        self.last_emitted_transition: tuple[float, str] | None = None

    def push(self, t: float, posture: str, walking: bool, theta: float, stamp_ns: int, calibrated: bool
             ) -> list | None:
        """Append a sample's labels; the record ``delay_n`` samples older, if any, leaves the line."""
        self.pending.append([t, posture, walking, theta, stamp_ns, calibrated])
        if len(self.pending) <= self.delay_n:
            return None
        return self.pending.popleft()

    def drain(self) -> list[list]:
        """Every record still held (the end of a recording)."""
        out = list(self.pending)
        self.pending.clear()
        return out

    def relabel(self, t_from: float, *, posture: str | None = None, walking: bool | None = None) -> None:
        """The held samples from ``t_from`` on get this posture and/or walking label."""
        for rec in reversed(self.pending):
            if rec[0] < t_from:
                break
            if posture is not None:
                rec[1] = posture
            if walking is not None:
                rec[2] = walking

    def state(self, rec: list, steps: list[float], transitions: list[tuple[float, str]],
              locomotion: Callable[[], str]) -> ActivityState:
        """The state of a record that left the line; ``locomotion()`` labels a walking sample that is
        standing: a state never pairs sitting or lying with a locomotion (the posture rules decide
        whether a walk made a seated wearer stand, ``posture.py``)."""
        t, posture, walking, theta, stamp_ns, calibrated = rec
        while self.emitted_steps < len(steps) and steps[self.emitted_steps] <= t:
            self.emitted_steps += 1
        while self._emitted_transitions < len(transitions) and transitions[self._emitted_transitions][0] <= t:
            self.last_emitted_transition = transitions[self._emitted_transitions]
            self._emitted_transitions += 1
        last = self.last_emitted_transition
        return ActivityState(
            stamp_ns=stamp_ns,
            posture=posture,
            # only an upright trunk walks (thesis Fig 27): a seated wearer's few peaks are no locomotion
            locomotion=locomotion() if walking and posture == "standing" else "none",
            trunk_inclination=theta,
            step_count=self.emitted_steps,
            last_transition=last[1] if last else None,
            last_transition_ns=s_to_ns(last[0]) if last else None,
            calibrated=calibrated,
        )
