"""The Parquet tables `analyze` writes into OUT/tables (gait_biofeedback/report/tables.py): read back
with pyarrow, against the output bag's messages decoded by the PyPI
``rosbags`` reader (not the package's own decoders) and against the simulator's truth.

A 28 s walk (stand 5 s, walk 20 s, stand 3 s), calibrated at 12 s (the walking protocol), as
test_report.py analyses it. The tolerances against the truth are about twice the errors measured on
it: stride length within 5.2 mm, stride time within 9 ms (one sample), knee flexion peak in swing
within 0.009 rad.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import rosbags_typestore, run_cli, simulated_bag, stamp_ns

from gait_biofeedback.sim.simulator import Phase, SimulationConfig

TABLES = ("strides", "joint_angles", "events", "activity")


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    """The walk, analysed through the CLI: its folder, what analyze printed, the simulated session, the
    tables read back (name → pyarrow Table) and the output's messages decoded by ``rosbags``."""
    import pyarrow.parquet as pq
    from rosbags.highlevel import AnyReader

    root = tmp_path_factory.mktemp("tables")
    config = SimulationConfig(seed=5, phases=[Phase("stand", 5.0), Phase("walk", 20.0), Phase("stand", 3.0)])
    raw, session = simulated_bag(root / "walk", config)
    out = root / "analysed"
    rc, printed, err = run_cli("analyze", str(raw), "-o", str(out), "--calibrate-at", "12:walking")
    assert rc == 0, err
    tables = {name: pq.read_table(out / "tables" / f"{name}.parquet") for name in TABLES}
    messages: dict[str, list] = {}
    with AnyReader([out], default_typestore=rosbags_typestore()) as reader:
        topics = ("/gait/cycles", "/gait/events", "/joint_states")
        wanted = [c for c in reader.connections if c.topic in topics]
        for conn, _, raw_msg in reader.messages(connections=wanted):
            messages.setdefault(conn.topic, []).append(reader.deserialize(raw_msg, conn.msgtype))
    return {"out": out, "printed": printed, "session": session, "tables": tables, "messages": messages}


def _column(analysed, table: str, name: str) -> np.ndarray:
    """A column as floats (null → NaN) or as it is."""
    return analysed["tables"][table].column(name).to_numpy(zero_copy_only=False)


def test_analyze_says_where_it_wrote_the_tables_and_how_many_rows(analysed):
    tables = analysed["tables"]
    folder = analysed["out"] / "tables"
    line = next(x for x in analysed["printed"].splitlines() if x.startswith(f"wrote {folder}:"))
    for name in TABLES:
        assert f"{name}.parquet {tables[name].num_rows} rows" in line
    assert all(tables[name].num_rows for name in TABLES)


def test_a_row_per_message_with_the_messages_stamps(analysed):
    tables, messages = analysed["tables"], analysed["messages"]
    cycles, events, joints = (messages[t] for t in ("/gait/cycles", "/gait/events", "/joint_states"))
    assert tables["strides"].num_rows == len(cycles) > 10
    assert list(_column(analysed, "strides", "initial_contact_ns")) == [stamp_ns(m.start) for m in cycles]
    assert list(_column(analysed, "strides", "next_initial_contact_ns")) == [stamp_ns(m.header.stamp)
                                                                             for m in cycles]
    assert list(_column(analysed, "strides", "side")) == [("left", "right")[m.side] for m in cycles]
    assert list(_column(analysed, "strides", "stride_index")) == [m.stride_index for m in cycles]
    assert list(_column(analysed, "strides", "plausible")) == [m.plausible for m in cycles]
    assert tables["events"].num_rows == len(events)
    assert list(_column(analysed, "events", "stamp_ns")) == [stamp_ns(m.header.stamp) for m in events]
    assert list(_column(analysed, "events", "kind")) == [("ic", "tc")[m.type] for m in events]
    assert tables["joint_angles"].num_rows == len(joints) > 1000
    assert list(_column(analysed, "joint_angles", "stamp_ns")) == [stamp_ns(m.header.stamp) for m in joints]
    knee = _column(analysed, "joint_angles", "left_knee_flexion_rad")
    recorded = [dict(zip(m.name, m.position, strict=True)).get("left_knee_flexion", np.nan) for m in joints]
    np.testing.assert_array_equal(knee, recorded)  # null where a message did not carry it


def test_columns_carry_their_units_and_times_increase(analysed):
    tables = analysed["tables"]
    strides = tables["strides"].column_names
    for name in ("initial_contact_s", "initial_contact_ns", "terminal_contact_s", "next_initial_contact_s",
                 "stride_time_s", "stance_time_s", "swing_time_s", "stance_pct", "swing_pct",
                 "double_support_pct", "cadence_steps_per_s", "stride_length_m", "gait_speed_m_per_s",
                 "max_foot_height_m", "foot_angle_ic_rad", "turning_angle_rad", "plausible",
                 "implausible_reason", "spatial_flag", "used", "left_out_reason",
                 "knee_flexion_peak_swing_rad", "knee_flexion_range_of_motion_rad"):
        assert name in strides, name
    joints = tables["joint_angles"].column_names
    assert joints[:3] == ["time_s", "stamp_ns", "recovering"]
    assert {f"{side}_{angle}_rad" for side in ("left", "right")
            for angle in ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")} <= set(joints)
    assert all(c.endswith(("_s", "_ns", "_rad")) or c.startswith("recovering") for c in joints)
    for table in TABLES:
        t = _column(analysed, table, "time_s" if table != "strides" else "initial_contact_s")
        ns = _column(analysed, table, "stamp_ns" if table != "strides" else "initial_contact_ns")
        assert np.all(np.diff(t) >= 0) and np.all(np.diff(ns) >= 0), table
        start = int(tables[table].schema.metadata[b"gait_biofeedback.recording_start_ns"])
        np.testing.assert_allclose(t, (ns - start) / 1e9, rtol=0, atol=1e-9)
    assert np.all(np.diff(_column(analysed, "joint_angles", "time_s")) > 0)
    for side in ("left", "right"):
        mine = _column(analysed, "strides", "side") == side
        assert np.all(np.diff(_column(analysed, "strides", "next_initial_contact_ns")[mine]) > 0)


def test_stride_times_are_the_events_tables_ic_to_next_ic(analysed):
    sides, kinds = _column(analysed, "events", "side"), _column(analysed, "events", "kind")
    event_ns, event_s = _column(analysed, "events", "stamp_ns"), _column(analysed, "events", "time_s")
    ic = {(side, int(ns)): s for side, kind, ns, s in zip(sides, kinds, event_ns, event_s, strict=True)
          if kind == "ic"}
    tc = {(side, int(ns)) for side, kind, ns in zip(sides, kinds, event_ns, strict=True) if kind == "tc"}
    strides = analysed["tables"]["strides"].to_pylist()
    for row in strides:
        side = row["side"]
        opening, closing = ic[(side, row["initial_contact_ns"])], ic[(side, row["next_initial_contact_ns"])]
        assert row["stride_time_s"] == pytest.approx(closing - opening, abs=1e-9)
        assert row["initial_contact_s"] == opening and row["next_initial_contact_s"] == closing
        if row["terminal_contact_ns"] is not None:
            assert (side, row["terminal_contact_ns"]) in tc
            assert row["stance_time_s"] == pytest.approx(row["terminal_contact_s"] - opening, abs=1e-9)
        assert row["stance_pct"] == pytest.approx(100 * row["stance_time_s"] / row["stride_time_s"])
        assert row["used"] == (row["left_out_reason"] == "")
        assert row["implausible_reason"] == "" or not row["plausible"]
    # the walk's first and last stride of each foot, and the extra IC's stride after the walk, are left out
    reasons = [r["left_out_reason"] for r in strides]
    assert reasons.count("walk_start_or_end") >= 3 and reasons.count("") >= 10


def test_strides_used_match_the_simulators_truth(analysed):
    """Stride time and length between the true ICs nearest the detected ones (the simulator's stamps are
    s from 0), and the true knee flexion peak from the true toe-off to the next IC."""
    truth = analysed["session"].truth
    used = [r for r in analysed["tables"]["strides"].to_pylist() if r["used"]]
    assert len(used) >= 10
    for row in used:
        side = row["side"]
        ics, tcs = truth.initial_contacts[side], truth.terminal_contacts[side]
        a = ics[np.argmin(abs(ics - row["initial_contact_ns"] / 1e9))]
        b = ics[np.argmin(abs(ics - row["next_initial_contact_ns"] / 1e9))]
        assert row["stride_time_s"] == pytest.approx(b - a, abs=0.02)
        foot = truth.segment_position[f"{side}_foot"]
        length = np.hypot(*(foot[np.searchsorted(truth.t, b)] - foot[np.searchsorted(truth.t, a)])[:2])
        assert row["stride_length_m"] == pytest.approx(length, abs=0.01)
        assert row["gait_speed_m_per_s"] == pytest.approx(row["stride_length_m"] / row["stride_time_s"])
        if row["knee_flexion_peak_swing_rad"] is not None:
            toe_off = tcs[(tcs > a) & (tcs < b)][0]
            swing = (truth.t >= toe_off) & (truth.t <= b)
            true_peak = truth.joint_angles[f"{side}_knee_flexion"][swing].max()
            assert row["knee_flexion_peak_swing_rad"] == pytest.approx(true_peak, abs=0.02)
    assert sum(r["knee_flexion_peak_swing_rad"] is not None for r in used) >= 8


def test_the_tables_command_writes_the_same_tables_from_the_bag(analysed, tmp_path):
    import pyarrow.parquet as pq

    rc, printed, err = run_cli("tables", str(analysed["out"]), "-o", str(tmp_path / "again"))
    assert rc == 0, err
    assert printed.startswith(f"wrote {tmp_path / 'again'}: strides.parquet")
    for name in TABLES:
        assert pq.read_table(tmp_path / "again" / f"{name}.parquet").equals(analysed["tables"][name]), name


def test_no_tables_and_an_overwrite_of_an_output_that_has_them(analysed, tmp_path):
    copy = tmp_path / "analysed"
    shutil.copytree(analysed["out"], copy)
    raw = analysed["out"].parent / "walk"
    rc, printed, err = run_cli("analyze", str(raw), "-o", str(copy), "--calibrate-at", "12:walking",
                               "--overwrite", "--no-tables")
    assert rc == 0, err
    assert not (copy / "tables").exists()
    assert "/gait/cycles" in printed and ".parquet" not in printed
