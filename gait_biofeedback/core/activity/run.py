"""When the activity stage publishes a state: written once for the ``activity_monitor`` node and ``analyze``.

An :class:`ActivityRun` drives one :class:`~gait_biofeedback.core.activity.stream.ActivityStream` and
returns the states due: each released state that changed (posture, locomotion or the last transition),
the latest state every ``publish_period_s`` s, and at the end the states the stream still held
(:meth:`ActivityStream.finish`). The period runs on one of two clocks (docs/conventions.md, Time):

- ``"wall"`` (the live node): the caller's timer calls :meth:`ActivityRun.periodic` every period, whatever the
  stamps;
- ``"recording"`` (``analyze``): :meth:`ActivityRun.update` itself gives the latest state first when a trunk
  sample's stamp reaches the period's end; the first sample starts the period, a period that ends
  before any state waits for the first one, and each periodic state starts the next period.

Every state goes out stamped :attr:`ActivityRun.newest_ns`, the newest trunk sample's stamp (the
message header); the conversion to a message stays with the caller (the core is ROS-free).
"""

from __future__ import annotations

from collections.abc import Sequence

from gait_biofeedback.core.activity.output import ActivityState
from gait_biofeedback.core.activity.stream import ActivityParams, ActivityStream
from gait_biofeedback.core.stamps import s_to_ns

CLOCKS = ("recording", "wall")


class ActivityRun:
    """The activity stage's publications (see module docstring); ``stream``: the stream it drives."""

    def __init__(self, params: ActivityParams | None = None, *, clock: str = "recording") -> None:
        if clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {clock!r}")
        p = params or ActivityParams()
        self.segment = p.segment
        self.clock = clock
        self.period_ns = s_to_ns(p.publish_period_s)
        self.stream = ActivityStream(p)
        self.newest_ns = 0  # stamp of the newest trunk sample (0 before any)
        self._next_periodic: int | None = None  # recording clock: when the period ends

    def update(self, stamp_ns: int, acc: Sequence[float], gyro: Sequence[float] | None = None
               ) -> list[ActivityState]:
        """A trunk sample → the states due: on the recording clock the periodic one first, then the
        state it released if that changed (:meth:`ActivityStream.update`)."""
        out = []
        if self.clock == "recording":
            if self._next_periodic is None:
                self._next_periodic = stamp_ns + self.period_ns
            elif stamp_ns >= self._next_periodic and self.stream.latest is not None:
                self._next_periodic = stamp_ns + self.period_ns
                out.append(self.stream.latest)
        state, changed = self.stream.update(stamp_ns, acc, gyro)
        self.newest_ns = stamp_ns
        if changed:
            out.append(state)
        return out

    def update_thigh(self, segment: str, stamp_ns: int, acc: Sequence[float]) -> list[ActivityState]:
        """A thigh sample (``ActivityParams.thighs``) → the trunk state it released, if that changed."""
        state, changed = self.stream.update_thigh(segment, stamp_ns, acc)
        return [state] if changed else []

    def periodic(self) -> ActivityState | None:
        """The wall clock's period ended (the node's timer): the latest state, None before any."""
        return self.stream.latest

    def finish(self) -> list[ActivityState]:
        """The end of the data (a recording, a replay): the states the stream still held."""
        return self.stream.finish()
