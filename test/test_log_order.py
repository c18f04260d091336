"""``analyze``'s output written as it goes (gait_biofeedback/io/log_order.py): the order of a stable sort
by log time of [*copied, *produced], whatever the releases; a failed analysis leaves no output."""

from __future__ import annotations

import numpy as np
import pytest

from gait_biofeedback.io.log_order import LogOrderWriter


class _Recorder:
    def __init__(self) -> None:
        self.written: list[tuple[str, int]] = []

    def write_many(self, messages: list[tuple[int, str, str, bytes, bool]]) -> None:
        self.written += [(topic, log_ns) for log_ns, topic, *_ in messages]


@pytest.mark.parametrize("hold", [1, 7, 4096])
@pytest.mark.parametrize("seed", range(5))
def test_released_as_it_goes_it_writes_the_stable_sort(seed, hold):
    """Two sources with many equal log times, released at random watermarks that keep the promise
    (nothing still to come is logged earlier), and a tail that comes out of order: the file gets what
    sorting everything at the end gave, ties copied first, each source in its own order, whether what
    is released is written at once (``hold`` 1) or in runs."""
    rng = np.random.default_rng(seed)
    recorder = _Recorder()
    ordered = LogOrderWriter(recorder, hold=hold)
    copied, produced = [], []
    now = released = 0
    for k in range(400):
        now += int(rng.integers(0, 3))  # repeated log times are common
        if rng.random() < 0.5:
            copied.append((f"c{k}", now))
            ordered.copied(now, f"c{k}", "t", b"")
        for j in range(int(rng.integers(0, 3))):
            produced.append((f"p{k}.{j}", now))
            ordered.produced(now, f"p{k}.{j}", "t", b"", True)
        watermark = now - int(rng.integers(0, 4))
        ordered.release(watermark)
        released = max(released, watermark)
    for j, log in enumerate((now + 5, released, now + 5, now)):  # the stages' last words, out of order
        produced.append((f"end{j}", log))
        ordered.produced(log, f"end{j}", "t", b"", True)
    ordered.close()
    expected = sorted([*copied, *produced], key=lambda r: r[1])
    assert recorder.written == expected


def test_a_failed_analysis_leaves_no_output_and_keeps_the_old_one(tmp_path, monkeypatch):
    """The bag is written into a staging folder beside the output as the analysis goes; an analysis
    that fails midway leaves neither a half bag nor the staging folder, and with ``overwrite`` the
    previous output is still there."""
    import gait_biofeedback.analyze as analyze
    from gait_biofeedback.core.gait.stream import GaitEventStream
    from gait_biofeedback.sim.recording import write_simulated_bag
    from gait_biofeedback.sim.simulator import Phase, SimulationConfig, simulate

    bag = write_simulated_bag(tmp_path / "in", simulate(SimulationConfig(seed=1, phases=[
        Phase("stand", 3.0), Phase("walk", 6.0)])))
    first = analyze.analyze_recording(bag, tmp_path / "out", [(1.0, "hip_flexion")])
    before = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    assert first.output == tmp_path / "out" and any(name.endswith(".mcap") for name in before)

    calls = []

    def failing(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > 300:
            raise RuntimeError("a stage failed")
        return original(self, *args, **kwargs)

    original = GaitEventStream.update
    monkeypatch.setattr(GaitEventStream, "update", failing)
    with pytest.raises(RuntimeError, match="a stage failed"):
        analyze.analyze_recording(bag, tmp_path / "out", [(1.0, "hip_flexion")], overwrite=True)
    with pytest.raises(RuntimeError, match="a stage failed"):
        analyze.analyze_recording(bag, tmp_path / "new", [(1.0, "hip_flexion")])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out"]
    assert {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()} == before
