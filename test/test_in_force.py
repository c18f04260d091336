"""InForceQueue: calibrations waiting for the stamp from which they are in force."""

from __future__ import annotations

from gait_biofeedback.core.in_force import InForceQueue


def test_values_come_due_in_stamp_order_with_ties_in_arrival_order() -> None:
    queue: InForceQueue[str] = InForceQueue()
    assert not queue and queue.first() is None and queue.due(1e9) == []
    queue.put(5.0, "late")
    queue.put(2.0, "early")
    queue.put(5.0, "late again")
    assert queue.first() == "early"
    assert queue.due(1.999) == []
    assert queue.due(2.0) == ["early"]  # in force at its own stamp
    assert queue.due(10.0) == ["late", "late again"]
    assert not queue
    queue.put(3.0, "dropped")
    queue.clear()
    assert queue.due(3.0) == []
