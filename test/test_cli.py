"""The ``gait-biofeedback`` command: help, simulate, import, info, repair (in-process calls)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import shared_data, synthetic_imu

from gait_biofeedback.cli import main
from gait_biofeedback.io.bag import BagReader, read_imu_bag, write_imu_bag

pytestmark = pytest.mark.timeout(120)


def test_help_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for command in ("demo", "simulate", "import", "replay", "run", "record", "info", "repair"):
        assert command in text


def test_simulate_is_deterministic_and_info_reads_it(tmp_path, capsys):
    for name in ("a", "b"):
        assert main(["simulate", "--scenario", "calibration_walking", "--seed", "3",
                     "-o", str(tmp_path / name)]) == 0
    a, b = read_imu_bag(tmp_path / "a"), read_imu_bag(tmp_path / "b")
    assert sorted(a) == sorted(b) and len(a) == 8
    for segment in a:
        np.testing.assert_array_equal(a[segment].acc, b[segment].acc)
        np.testing.assert_array_equal(a[segment].mag, b[segment].mag)
    capsys.readouterr()
    assert main(["info", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "/left_foot/imu/data_raw" in out and "sensor_msgs/msg/Imu" in out and "100.0 Hz" in out


def test_simulate_rejects_an_unknown_scenario(tmp_path, capsys):
    assert main(["simulate", "--scenario", "marathon", "-o", str(tmp_path / "x")]) == 2
    assert "unknown scenario" in capsys.readouterr().err


def test_import_csv_with_mapping_and_units(tmp_path):
    csv = tmp_path / "walk.csv"
    rows = ["time_ms,ax,ay,az,gx,gy,gz"] + [f"{10 * k},0,0,1,{k},0,0" for k in range(50)]
    csv.write_text("\n".join(rows) + "\n")
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text("time: time_ms\nleft_foot:\n  acc: [ax, ay, az]\n  gyr: [gx, gy, gz]\n")
    out = tmp_path / "bag"
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--units", "acc=g", "gyr=deg/s",
                 "time=ms", "-o", str(out)]) == 0
    series = read_imu_bag(out)["left_foot"]
    np.testing.assert_allclose(series.t, np.arange(50) * 0.01)
    np.testing.assert_allclose(series.acc[:, 2], 9.80665)
    np.testing.assert_allclose(series.gyr[:, 0], np.radians(np.arange(50)))
    assert series.mag is None


def test_import_reports_a_missing_column(tmp_path, capsys):
    csv = tmp_path / "bad.csv"
    csv.write_text("t,ax,ay,az\n0,0,0,1\n")
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text("pelvis:\n  acc: [ax, ay, az]\n  gyr: [gx, gy, gz]\n")
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "o")]) == 2
    assert "gx" in capsys.readouterr().err


def test_import_qmt_fullbody(tmp_path):
    source = shared_data("qmt_fullbody", "full_body_example_data.mat")
    assert main(["import", "auto", str(source), "-o", str(tmp_path / "qmt")]) == 0
    imu = read_imu_bag(tmp_path / "qmt")
    assert set(imu) == {"pelvis", "left_thigh", "left_shank", "left_foot", "right_thigh", "right_shank",
                        "right_foot", "chest"}
    assert abs(imu["pelvis"].rate_hz - 100.0) < 0.01


def test_repair_makes_a_cut_recording_whole(tmp_path, capsys):
    assert main(["simulate", "--scenario", "calibration_walking", "-o", str(tmp_path / "full")]) == 0
    cut = tmp_path / "cut"
    cut.mkdir()
    source = next((tmp_path / "full").glob("*.mcap"))
    data = source.read_bytes()
    (cut / "cut_0.mcap").write_bytes(data[: len(data) * 2 // 3])
    assert main(["repair", str(cut)]) == 0
    out = capsys.readouterr().out
    assert "_0.mcap: repaired, " in out and "the original is kept as" in out and "metadata.yaml " in out
    reader = BagReader(cut)
    assert 0 < reader.message_count < BagReader(tmp_path / "full").message_count
    assert (cut / "metadata.yaml").exists()
    # a file cut inside its first chunk holds nothing to recover: said, exit 1
    head = tmp_path / "head.mcap"
    head.write_bytes(data[:300])
    assert main(["repair", str(head)]) == 1
    captured = capsys.readouterr()
    assert "0 messages, (a single .mcap file: no metadata.yaml)" in captured.out
    assert "holds no message that can be read" in captured.err
    shutil.rmtree(tmp_path / "full")


def test_an_unwritable_or_taken_output_is_refused_before_any_work(tmp_path, capsys):
    assert main(["simulate", "--scenario", "calibration_walking", "-o", str(tmp_path / "walk")]) == 0
    capsys.readouterr()
    # the output is checked first: with a bag that does not even exist, the output is what is named
    assert main(["analyze", str(tmp_path / "missing"), "-o", "/proc/gait_out"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gait-biofeedback analyze: cannot write the bag folder /proc/gait_out")
    assert "\n" not in err and "Traceback" not in err
    assert main(["analyze", str(tmp_path / "walk"), "-o", str(tmp_path / "walk")]) == 2
    err = capsys.readouterr().err
    assert "exists and is not empty" in err and "pass --overwrite" in err and "overwrite=True" not in err
    assert main(["import", "qmt_fullbody", "x.mat", "-o", str(tmp_path / "walk")]) == 2
    err = capsys.readouterr().err
    assert "exists and is not empty" in err and "--overwrite" not in err, "import has no such flag"


def test_info_takes_rates_from_the_stamps_and_reports_going_back(tmp_path, capsys):
    """A 100 Hz stream recorded at 2x (log times twice as dense) is 100 Hz; a sample stamped before
    the one before it is counted."""
    from gait_biofeedback.io.bag import BagWriter

    source = write_imu_bag(tmp_path / "in", synthetic_imu(["left_foot"], duration=2.0, with_mag=False))
    messages = list(BagReader(source).raw_messages())
    t0 = messages[0][3]
    with BagWriter(tmp_path / "fast") as writer:
        for k, (topic, type_name, data, log_ns) in enumerate(messages):
            if k == 50:
                data = messages[40][2]  # an old sample again
            writer.write_serialized(topic, type_name, data, t0 + (log_ns - t0) // 2)
    assert main(["info", str(tmp_path / "fast")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "/left_foot/imu/data_raw" in x)
    assert " 100.0 Hz" in line and "1 stamps not after the one before" in line


def _walk_csv(tmp_path, gyr_factor=1.0, time_factor=1.0, bom=False, acc_factor=1.0):
    """A simulated walk's left foot as a CSV (acc m/s² × acc_factor, gyr rad/s × gyr_factor, t s ×
    time_factor)."""
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    foot = simulate(SCENARIOS["walk"](duration=8.0, seed=3)).imu["left_foot"]
    rows = ["time,ax,ay,az,gx,gy,gz"] + [
        ",".join(f"{v:.6g}" for v in (t * time_factor, *(a * acc_factor), *(g * gyr_factor)))
        for t, a, g in zip(foot.t, foot.acc, foot.gyr, strict=True)]
    csv = tmp_path / "walk.csv"
    csv.write_text(("\ufeff" if bom else "") + "\n".join(rows) + "\n", encoding="utf-8")
    mapping = tmp_path / "map.yaml"
    mapping.write_text("left_foot: {acc: [ax, ay, az], gyr: [gx, gy, gz]}\n")
    return csv, mapping, foot


def test_import_csv_reads_a_bom_and_refuses_ms_declared_as_s(tmp_path, capsys):
    csv, mapping, foot = _walk_csv(tmp_path, bom=True)
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().err == "", "no warning for a plausible recording"
    np.testing.assert_allclose(read_imu_bag(tmp_path / "a")["left_foot"].gyr, foot.gyr, rtol=1e-5, atol=1e-5)

    csv, mapping, _ = _walk_csv(tmp_path, time_factor=1000.0)  # a time column in ms
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "median sample interval of 10 s (0.1 Hz" in err and "--units time=ms" in err
    assert not (tmp_path / "b").exists()
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--units", "time=ms",
                 "-o", str(tmp_path / "b")]) == 0


def test_import_csv_refuses_deg_per_s_declared_as_rad_per_s(tmp_path, capsys):
    """A gyro in deg/s declared rad/s contradicts any body's rates: refused (exit 2, nothing written)
    naming the flag that fixes it; --trust-units imports it with a warning. The other way round (rad/s
    declared deg/s) is only a doubt: a warning."""
    csv, mapping, _ = _walk_csv(tmp_path, gyr_factor=np.degrees(1.0))
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "the data contradict the declared units: left_foot: 99th percentile |gyr|" in err
    assert "--units gyr=deg/s" in err and "--trust-units" in err and not (tmp_path / "a").exists()
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--trust-units",
                 "-o", str(tmp_path / "a")]) == 0
    assert "warning: left_foot: 99th percentile |gyr|" in capsys.readouterr().err
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--units", "gyr=deg/s",
                 "-o", str(tmp_path / "b")]) == 0
    assert capsys.readouterr().err == ""
    # and the other way round: rad/s declared as deg/s barely turns while the foot walks
    csv, mapping, _ = _walk_csv(tmp_path)
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--units", "gyr=deg/s",
                 "-o", str(tmp_path / "c")]) == 0
    assert "if the file is in rad/s, say so with --units gyr=rad/s" in capsys.readouterr().err


def test_import_csv_refuses_unknown_segments_and_malformed_units(tmp_path, capsys):
    csv, mapping, _ = _walk_csv(tmp_path)
    mapping.write_text("left_fot: {acc: [ax, ay, az], gyr: [gx, gy, gz]}\n")
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "a")]) == 2
    assert "unknown segment 'left_fot' (did you mean 'left_foot'?)" in capsys.readouterr().err
    mapping.write_text("left_foot: {acc: [ax, ay, az], gyr: [gx, gy, gz]}\n")
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--units", "acc:g",
                 "-o", str(tmp_path / "a")]) == 2
    assert "--units acc:g: expected QUANTITY=UNIT pairs, e.g. --units acc=g" in capsys.readouterr().err
    # the file's acc is in m/s²; declared as g, its median |acc| is about 10 g: refused
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "--units", "acc=g",
                 "-o", str(tmp_path / "b")]) == 2
    assert "if the file is in m/s², say so with --units acc=m/s2" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()
    # and in g declared as m/s²: about 1 m/s² at rest
    g_csv, g_mapping, _ = _walk_csv(tmp_path, acc_factor=1 / 9.80665)
    assert main(["import", "csv", str(g_csv), "--mapping", str(g_mapping), "-o", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "(gravity alone is 9.81); if the file is in g, say so with --units acc=g" in err


def test_analyze_exits_1_when_no_calibration_took_effect(tmp_path, capsys):
    """A request after the end never runs: the outputs are written, the reason printed, exit 1."""
    assert main(["simulate", "--scenario", "calibration_walking", "-o", str(tmp_path / "walk")]) == 0
    capsys.readouterr()
    assert main(["analyze", str(tmp_path / "walk"), "-o", str(tmp_path / "out"), "--calibrate-at",
                 "1000:walking"]) == 1
    captured = capsys.readouterr()
    assert "never ran" in captured.err and "no calibration took effect" in captured.err
    assert BagReader(tmp_path / "out").message_count > 0


def test_import_reads_a_gzip_csv_and_says_what_a_csv_needs(tmp_path, capsys):
    """A .csv.gz reads as its .csv (auto from the name, with a mapping); a CSV without --mapping, and a
    missing file, are refused in one line that says what to give."""
    import gzip

    csv, mapping, foot = _walk_csv(tmp_path)
    packed = tmp_path / "walk.csv.gz"
    packed.write_bytes(gzip.compress(csv.read_bytes()))
    assert main(["import", "auto", str(packed), "--mapping", str(mapping), "-o", str(tmp_path / "a")]) == 0
    assert "1 sensor (left_foot)" in capsys.readouterr().out
    np.testing.assert_allclose(read_imu_bag(tmp_path / "a")["left_foot"].gyr, foot.gyr, rtol=1e-5, atol=1e-5)
    for argv, says in ((["csv", str(csv)], "--mapping map.yaml"), (["auto", str(csv)], "--mapping map.yaml"),
                       (["csv", str(tmp_path / "none.csv"), "--mapping", str(mapping)], "not found")):
        assert main(["import", *argv, "-o", str(tmp_path / "b")]) == 2
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err and err.count("\n") == 1, err
