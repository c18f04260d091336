"""`gait-biofeedback batch`: a folder of simulated sessions and a corrupt one through the command line
on a local Dask cluster of two workers; the cohort table against each session's own strides.csv (a
mean computed here) and the simulator's walking speed and cadence; re-runs skip what is done and retry
what failed; `simulate --duration` makes longer training sessions."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest
from conftest import csv_rows, run_cli

from gait_biofeedback.cohort.sessions import find_recordings
from gait_biofeedback.sim.recording import write_simulated_bag
from gait_biofeedback.sim.simulator import Phase, SimulationConfig, simulate, training

pytestmark = pytest.mark.timeout(300)


def _walk(path: Path, seed: int) -> Path:
    phases = [Phase("stand", 5.0), Phase("walk", 9.0), Phase("stand", 2.0)]
    return write_simulated_bag(path, simulate(SimulationConfig(seed=seed, phases=phases)))


def _rows(path: Path) -> dict[str, dict[str, str]]:
    return {r["session"]: r for r in csv_rows(path)}


def _mean_of_used(strides_csv: Path, name: str, side: str) -> float:
    values = [float(r[name]) for r in csv_rows(strides_csv) if r["side"] == side and r["used"] == "True"]
    finite = [v for v in values if math.isfinite(v)]
    return sum(finite) / len(finite)


@pytest.fixture(scope="module")
def cohort(tmp_path_factory):
    root = tmp_path_factory.mktemp("batch")
    _walk(root / "in" / "p1" / "raw", 1)
    _walk(root / "in" / "p2" / "raw", 2)
    (root / "in" / "p3").mkdir()
    (root / "in" / "p3" / "raw.mcap").write_bytes(b"not a recording at all")
    rc, printed, err = run_cli("batch", str(root / "in"), "-o", str(root / "out"), "--workers", "2")
    return root, rc, printed, err


def test_a_folder_of_sessions_gives_one_analysis_report_and_row_each(cohort):
    root, rc, printed, err = cohort
    assert rc == 1  # one recording failed
    assert "batch: 2 analysed, 0 skipped (done before, same recording), 1 failed" in printed
    assert "p3__raw" in err and "not an MCAP file" in err and "run the batch again to retry" in err
    rows = _rows(root / "out" / "cohort.csv")
    assert sorted(rows) == ["p1__raw", "p2__raw", "p3__raw"]
    assert rows["p3__raw"]["status"] == "failed" and "not an MCAP file" in rows["p3__raw"]["error"]
    assert rows["p3__raw"]["gait_speed_m_per_s_left"] == ""
    for name in ("p1__raw", "p2__raw"):
        row, where = rows[name], root / "out" / name
        assert row["status"] == "done" and row["calibrated"] == "True", row
        assert (where / "analysis" / "metadata.yaml").is_file()
        assert {p.name for p in (where / "report").iterdir()} >= {"report.html", "report.pdf", "strides.csv"}
        # the row is the report's figures: the mean over the strides the report used
        for side in ("left", "right"):
            for column, field in (("gait_speed_m_per_s", "gait_speed"), ("cadence_steps_per_s", "cadence")):
                expected = _mean_of_used(where / "report" / "strides.csv", field, side)
                assert float(row[f"{column}_{side}"]) == pytest.approx(expected, rel=1e-9)
        # the simulator walks at 1.2 m/s and 1.8 steps/s; the bout's ramps pull the means down a little
        assert 1.05 < float(row["gait_speed_m_per_s_left"]) < 1.25
        assert 1.7 < float(row["cadence_steps_per_s_right"]) < 1.85
        assert float(row["duration_s"]) == pytest.approx(16.0, abs=0.05)
        assert int(row["strides_used"]) >= 4
        assert float(row["worker_peak_rss_mb"]) > 50


def test_the_parquet_table_holds_what_the_csv_does(cohort):
    import pyarrow.parquet as pq

    root = cohort[0]
    table = pq.read_table(root / "out" / "cohort.parquet").to_pylist()
    rows = _rows(root / "out" / "cohort.csv")
    assert [r["session"] for r in table] == sorted(rows)
    for parquet_row in table:
        csv_row = rows[parquet_row["session"]]
        assert list(parquet_row) == list(csv_row)
        for column, value in parquet_row.items():
            if value is None:
                assert csv_row[column] == ""
            elif isinstance(value, float):
                assert value == pytest.approx(float(csv_row[column]), rel=1e-12)
            else:
                assert str(value) == csv_row[column]


def test_a_rerun_skips_the_done_sessions_and_retries_the_failed_one(cohort):
    root = cohort[0]
    out = root / "out"
    before = (out / "p1__raw" / "session.json").stat().st_mtime_ns
    shutil.rmtree(out / "p3__raw")
    (root / "in" / "p3" / "raw.mcap").unlink()
    shutil.copytree(root / "in" / "p2" / "raw", root / "in" / "p3" / "raw")  # the recording, made good
    rc, printed, err = run_cli("batch", str(root / "in"), "-o", str(out), "--workers", "1", "--no-report")
    assert rc == 0, err
    assert "batch: 1 analysed, 2 skipped (done before, same recording), 0 failed" in printed
    assert (out / "p1__raw" / "session.json").stat().st_mtime_ns == before
    rows = _rows(out / "cohort.csv")
    assert [r["status"] for r in rows.values()] == ["done"] * 3
    assert rows["p3__raw"]["gait_speed_m_per_s_left"] == rows["p2__raw"]["gait_speed_m_per_s_left"]
    assert not (out / "p3__raw" / "report").exists()  # --no-report
    assert json.loads((out / "p3__raw" / "session.json").read_text())["status"] == "done"


def test_recordings_are_found_by_folder_and_glob_and_named_uniquely(tmp_path):
    for name in ("a", "b/c"):
        (tmp_path / "in" / name).mkdir(parents=True)
        (tmp_path / "in" / name / "metadata.yaml").write_text("")
        (tmp_path / "in" / name / "x_0.mcap").write_bytes(b"")
    (tmp_path / "in" / "d.mcap").write_bytes(b"")
    (tmp_path / "in" / "out" / "a" / "analysis").mkdir(parents=True)  # the batch's own output inside
    (tmp_path / "in" / "out" / "a" / "analysis" / "metadata.yaml").write_text("")
    found = find_recordings(str(tmp_path / "in"), exclude=tmp_path / "in" / "out")
    assert [r.name for r in found] == ["a", "b__c", "d"]
    assert [r.name for r in find_recordings(str(tmp_path / "in" / "*"), exclude=tmp_path / "in" / "out")] == [
        "a", "d"]
    assert [r.name for r in find_recordings(str(tmp_path / "in" / "b" / "c"))] == ["c"]
    with pytest.raises(FileNotFoundError, match="no recording"):
        find_recordings(str(tmp_path / "nothing" / "*"))
    (tmp_path / "in" / "a.mcap").write_bytes(b"")
    with pytest.raises(ValueError, match="share the session name"):
        find_recordings(str(tmp_path / "in"), exclude=tmp_path / "in" / "out")


def test_a_bad_batch_request_is_refused_before_any_worker_starts(tmp_path):
    _walk(tmp_path / "in" / "s", 1)
    rc, _, err = run_cli("batch", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--calibrate-at", "x:y")
    assert rc == 2 and "calibrat" in err
    assert not (tmp_path / "out").exists()


def test_training_sessions_have_the_length_asked_for_in_laps():
    config = training(600.0)
    assert sum(p.duration for p in config.phases) == pytest.approx(600.0)
    assert [p.kind for p in config.phases[:4]] == ["stand", "hip_flexion", "stand", "walk"]
    assert sum(p.kind == "turn" for p in config.phases) == 11  # 560 s: 11 laps of 50 s, then a 10 s walk
    assert config.phases[-1].kind == "walk" and config.phases[-1].duration == pytest.approx(10.0)
    assert sum(p.duration for p in training(100.0).phases) == pytest.approx(100.0)
    with pytest.raises(ValueError, match="at least 60 s"):
        training(30.0)
    rc, _, err = run_cli("simulate", "--scenario", "stairs", "--duration", "100", "-o", "/nonexistent/x")
    assert rc == 2 and "--duration sets the length" in err
