"""Importers: the generic CSV on small hand-written files, the real-data importers on ../shared/data."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data

from gait_biofeedback.core.segments import GRAVITY, SEGMENTS, ImuSeries
from gait_biofeedback.io.importers import (
    IMPORTERS,
    Recording,
    detect_kind,
    import_broad,
    import_gaitmap,
    import_generic_csv,
    import_qmt_fullbody,
    import_recording,
    load_gaitmap_events,
)

LEFT_FOOT_MAPPING = {
    "left_foot": {
        "acc": ["lf_ax", "lf_ay", "lf_az"],
        "gyr": ["lf_gx", "lf_gy", "lf_gz"],
        "mag": ["lf_mx", "lf_my", "lf_mz"],
    }
}
CSV_UNITS = {"acc": "g", "gyr": "deg/s", "mag": "uT", "time": "ms"}


@pytest.fixture
def small_csv(tmp_path: Path) -> Path:
    """Three samples, 10 ms apart, in g, deg/s, µT; the middle row has an empty magnetometer."""
    path = tmp_path / "walk.csv"
    path.write_text(
        "time,lf_ax,lf_ay,lf_az,lf_gx,lf_gy,lf_gz,lf_mx,lf_my,lf_mz,label\n"
        "1000,0,0,1,180,0,-90,20,0,-40,stand\n"
        "1010,0.5,-1,0,0,360,0,,,,walk\n"
        "1020,0,2,0,-45,0,0,0,50,0,walk\n"
    )
    return path


# ---------------------------------------------------------------- generic CSV


def test_generic_csv_converts_g_deg_s_ut_ms_to_si(small_csv: Path) -> None:
    recording = import_generic_csv(small_csv, LEFT_FOOT_MAPPING, units=CSV_UNITS)
    foot = recording.imu["left_foot"]
    # time in ms kept absolute, converted to s
    np.testing.assert_allclose(foot.t, [1.0, 1.01, 1.02])
    # 1 g = 9.80665 m/s² (standard gravity), 0.5 g = 4.903325, -1 g = -9.80665, 2 g = 19.6133
    np.testing.assert_allclose(foot.acc[0], [0.0, 0.0, 9.80665])
    np.testing.assert_allclose(foot.acc[1], [4.903325, -9.80665, 0.0])
    np.testing.assert_allclose(foot.acc[2], [0.0, 19.6133, 0.0])
    # 180 deg/s = π rad/s, -90 = -π/2, 360 = 2π, -45 = -π/4
    np.testing.assert_allclose(foot.gyr[0], [math.pi, 0.0, -math.pi / 2])
    np.testing.assert_allclose(foot.gyr[1], [0.0, 2 * math.pi, 0.0])
    np.testing.assert_allclose(foot.gyr[2], [-math.pi / 4, 0.0, 0.0])
    # 20 µT = 2e-5 T, -40 µT = -4e-5 T, 50 µT = 5e-5 T
    np.testing.assert_allclose(foot.mag[0], [2e-5, 0.0, -4e-5])
    np.testing.assert_allclose(foot.mag[2], [0.0, 5e-5, 0.0])
    assert recording.source.startswith("csv:")


def test_generic_csv_keeps_nan_rows_and_counts_them(small_csv: Path) -> None:
    recording = import_generic_csv(small_csv, LEFT_FOOT_MAPPING, units=CSV_UNITS)
    foot = recording.imu["left_foot"]
    assert len(foot) == 3
    assert np.all(np.isnan(foot.mag[1]))
    nan_warnings = [w for w in recording.warnings if "NaN" in w]
    assert len(nan_warnings) == 1
    assert "left_foot" in nan_warnings[0] and "1 of 3" in nan_warnings[0]


def test_generic_csv_missing_column_names_it_and_lists_the_file_columns(small_csv: Path) -> None:
    mapping = {"left_foot": {"acc": ["lf_ax", "lf_ay", "lf_AZ"], "gyr": ["lf_gx", "lf_gy", "lf_gz"]}}
    with pytest.raises(ValueError, match="lf_AZ") as error:
        import_generic_csv(small_csv, mapping, units=CSV_UNITS)
    assert "lf_az" in str(error.value)  # the columns the file does have


def test_an_accelerometer_alone_is_imported_with_an_unknown_rate_and_said(small_csv: Path, tmp_path: Path,
                                                                          capsys) -> None:
    """A chest accelerometer without gyro (UCI's chest sets): imported with its angular rate NaN, said;
    through analyze the orientation filter gives it no orientation and says why, while the activity
    monitor runs on the accelerometer."""
    from gait_biofeedback.cli import main
    from gait_biofeedback.io.bag import BagReader
    from gait_biofeedback.io.imu_bag import write_imu_bag

    mapping = {"chest": {"acc": ["lf_ax", "lf_ay", "lf_az"]}}
    recording = import_generic_csv(small_csv, mapping, units=CSV_UNITS)
    chest = recording.imu["chest"]
    assert np.isnan(chest.gyr).all() and np.isfinite(chest.acc).all()
    assert recording.warnings == ["chest: no gyro columns: its angular rate is written as unknown (NaN), so "
                                  "the orientation filter gives it no orientation (nor joint angles); the "
                                  "activity monitor uses its accelerometer alone"]
    with pytest.raises(ValueError, match="lacks 'acc'"):
        import_generic_csv(small_csv, {"chest": {"gyr": ["lf_gx", "lf_gy", "lf_gz"]}}, units=CSV_UNITS)
    t = np.arange(0, 20.0, 0.02)
    still = ImuSeries("chest", t, np.tile([0.0, 0.0, 9.81], (len(t), 1)) + 0.01 * np.sin(t)[:, None],
                      np.full((len(t), 3), np.nan))
    import warnings

    from gait_biofeedback.io.importers import unit_contradictions

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # its rest blocks have no gyro: no numpy "All-NaN slice" for the user
        assert unit_contradictions(still, CSV_UNITS) == ([], [])
    bag = write_imu_bag(tmp_path / "chest", {"chest": still})
    assert main(["analyze", str(bag), "-o", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    assert "chest: over the session: no gyro (angular rate not given): no orientation from this sensor" \
        in captured.err
    with BagReader(tmp_path / "out") as reader:
        counts = reader.message_counts()
    assert counts.get("/activity/state", 0) > 0 and "/chest/imu/data" not in counts


@pytest.mark.parametrize(("quantity", "unit"), [("gyr", "rpm"), ("acc", "ft/s2"), ("time", "min")])
def test_generic_csv_unknown_unit_is_named_with_the_allowed_ones(
    small_csv: Path, quantity: str, unit: str
) -> None:
    with pytest.raises(ValueError, match=unit) as error:
        import_generic_csv(small_csv, LEFT_FOOT_MAPPING, units={**CSV_UNITS, quantity: unit})
    assert "allowed" in str(error.value)


def test_generic_csv_mapping_from_yaml_with_time_column_and_units(tmp_path: Path) -> None:
    csv_path = tmp_path / "pelvis.csv"
    csv_path.write_text("stamp_us;ax;ay;az;gx;gy;gz\n0;0;0;9.81;1;2;3\n5000;0;0;9.81;0;0;0\n")
    yaml_path = tmp_path / "mapping.yaml"
    yaml_path.write_text(
        "time: stamp_us\n"
        "units: {time: us}\n"
        "pelvis:\n"
        "  acc: [ax, ay, az]\n"
        "  gyr: [gx, gy, gz]\n"
    )
    recording = import_recording("csv", csv_path, mapping=yaml_path)
    pelvis = recording.imu["pelvis"]
    np.testing.assert_allclose(pelvis.t, [0.0, 0.005])
    np.testing.assert_allclose(pelvis.gyr[0], [1.0, 2.0, 3.0])  # rad/s default: unchanged
    assert pelvis.mag is None
    assert pelvis.rate_hz == pytest.approx(200.0)


def test_generic_csv_rate_without_time_column_and_error_without_either(tmp_path: Path) -> None:
    path = tmp_path / "no_time.csv"
    path.write_text("ax,ay,az,gx,gy,gz\n0,0,9.81,0,0,0\n0,0,9.81,0,0,0\n0,0,9.81,0,0,0\n")
    mapping = {"chest": {"acc": ["ax", "ay", "az"], "gyr": ["gx", "gy", "gz"]}}
    recording = import_generic_csv(path, mapping, rate_hz=50.0)
    np.testing.assert_allclose(recording.imu["chest"].t, [0.0, 0.02, 0.04])
    with pytest.raises(ValueError, match="rate_hz"):
        import_generic_csv(path, mapping)


def test_generic_csv_time_that_goes_back_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "jump.csv"
    path.write_text("t,ax,ay,az,gx,gy,gz\n0.0,0,0,9.81,0,0,0\n0.02,0,0,9.81,0,0,0\n0.01,0,0,9.81,0,0,0\n")
    mapping = {"chest": {"acc": ["ax", "ay", "az"], "gyr": ["gx", "gy", "gz"]}}
    with pytest.raises(ValueError, match="increase"):
        import_generic_csv(path, mapping)


def test_generic_csv_refuses_acc_in_g_declared_as_m_per_s2(tmp_path: Path) -> None:
    """1 at rest with the acc unit m/s² contradicts gravity: refused with the flag that fixes it;
    trusted, the same text is a warning; declared in g, nothing is said."""
    from gait_biofeedback.io.importers import UnitsError

    path = tmp_path / "g.csv"
    path.write_text("t,ax,ay,az,gx,gy,gz\n0.0,0,0,1,0,0,0\n0.01,0,0,1,0,0,0\n")
    mapping = {"chest": {"acc": ["ax", "ay", "az"], "gyr": ["gx", "gy", "gz"]}}
    with pytest.raises(UnitsError, match=r"chest: median \|acc\| is 1 m/s² .* say so with --units acc=g"):
        import_generic_csv(path, mapping)
    trusted = import_generic_csv(path, mapping, trust_units=True)
    assert any("say so with --units acc=g" in w for w in trusted.warnings)
    assert import_generic_csv(path, mapping, units={"acc": "g"}).warnings == []


# ---------------------------------------------------------------- dispatch


def test_import_recording_rejects_an_unknown_kind(small_csv: Path) -> None:
    with pytest.raises(ValueError, match="unknown recording kind 'xsens'") as error:
        import_recording("xsens", small_csv)
    for kind in IMPORTERS:
        assert kind in str(error.value)


def test_detect_kind_from_file_names(tmp_path: Path, small_csv: Path) -> None:
    assert detect_kind("somewhere/full_body_example_data.mat") == "qmt_fullbody"
    assert detect_kind("broad/07_undisturbed_fast_rotation_B.mat") == "broad"
    assert detect_kind("gaitmap_example/imu_sample_not_rotated.csv") == "gaitmap"
    assert detect_kind(small_csv, mapping=LEFT_FOOT_MAPPING) == "csv"
    with pytest.raises(ValueError, match="mapping"):
        detect_kind(small_csv)
    with pytest.raises(ValueError, match="cannot tell"):
        detect_kind(tmp_path / "session.h5")
    recording = import_recording("auto", small_csv, mapping=LEFT_FOOT_MAPPING, units=CSV_UNITS)
    assert isinstance(recording, Recording) and recording.segments == ["left_foot"]


# ---------------------------------------------------------------- real data (../shared/data)


def _static_acc_norm(acc: np.ndarray, gyr: np.ndarray) -> float:
    """Median |acc| over the quietest 5 % of samples (by |gyr|): ≈ g when acc is in m/s²."""
    gyr_norm = np.linalg.norm(gyr, axis=1)
    quiet = gyr_norm <= np.nanpercentile(gyr_norm, 5)
    return float(np.nanmedian(np.linalg.norm(acc[quiet], axis=1)))


@pytest.fixture(scope="module")
def qmt_recording() -> Recording:
    return import_qmt_fullbody(shared_data("qmt_fullbody", "full_body_example_data.mat"))


@pytest.fixture(scope="module")
def gaitmap_recording() -> Recording:
    return import_gaitmap(shared_data("gaitmap_example", "imu_sample.csv"))


@pytest.fixture(scope="module")
def broad_recording() -> Recording:
    return import_broad(shared_data("broad", "01_undisturbed_slow_rotation_A.mat"))


@pytest.mark.realdata
def test_qmt_fullbody_has_the_eight_segments_at_100_hz_in_si(qmt_recording: Recording) -> None:
    assert sorted(qmt_recording.imu) == sorted(SEGMENTS)
    for segment, series in qmt_recording.imu.items():
        assert series.acc.shape == series.gyr.shape == (len(series), 3)
        assert len(series) > 5000
        assert series.t[0] == 0.0
        assert series.rate_hz == pytest.approx(100.0, rel=1e-6)
        assert np.all(np.diff(series.t) > 0)
        assert series.mag is None
        assert _static_acc_norm(series.acc, series.gyr) == pytest.approx(GRAVITY, abs=0.6), segment
        gyr_norm = np.linalg.norm(series.gyr, axis=1)
        assert 0.5 < np.percentile(gyr_norm, 99) < 35.0, segment  # rad/s, not deg/s
        quat = qmt_recording.reference["vendor_quat"][segment]
        assert quat.shape == (len(series), 4)
        np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-3)
    assert qmt_recording.reference["struct_of_segment"]["pelvis"] == "hip"
    assert qmt_recording.reference["struct_of_segment"]["chest"] == "upper_back"


@pytest.mark.realdata
def test_qmt_fullbody_keeps_other_sensors_only_when_asked(qmt_recording: Recording) -> None:
    assert "head" not in qmt_recording.imu
    everything = import_qmt_fullbody(shared_data("qmt_fullbody", "full_body_example_data.mat"),
                                     include_unmapped=True)
    assert {"head", "lower_back", "hand_left"} <= set(everything.imu)
    assert len(everything.imu) == 16
    assert "hip" not in everything.imu  # mapped sensors appear only under their segment name


@pytest.mark.realdata
def test_gaitmap_feet_at_204_8_hz_with_gyr_in_rad_s(gaitmap_recording: Recording) -> None:
    assert sorted(gaitmap_recording.imu) == ["left_foot", "right_foot"]
    for segment, series in gaitmap_recording.imu.items():
        assert series.acc.shape == (7928, 3)
        assert series.rate_hz == pytest.approx(204.8, rel=1e-6)
        assert _static_acc_norm(series.acc, series.gyr) == pytest.approx(GRAVITY, abs=0.6), segment
        gyr_norm = np.linalg.norm(series.gyr, axis=1)
        assert 2.0 < np.percentile(gyr_norm, 99) < 35.0, segment  # walking foot, rad/s
    assert gaitmap_recording.reference["frame"] == "gaitmap_foot"


@pytest.mark.realdata
def test_gaitmap_not_rotated_is_the_same_motion_in_other_axes(gaitmap_recording: Recording) -> None:
    raw = import_gaitmap(shared_data("gaitmap_example", "imu_sample.csv"), rotated=False)
    assert raw.reference["frame"] == "sensor"
    rotated_foot, raw_foot = gaitmap_recording.imu["left_foot"], raw.imu["left_foot"]
    np.testing.assert_allclose(np.linalg.norm(raw_foot.gyr, axis=1), np.linalg.norm(rotated_foot.gyr, axis=1),
                               rtol=1e-6, atol=1e-9)
    assert not np.allclose(raw_foot.acc, rotated_foot.acc)
    # the not-rotated file given by name (as `import gaitmap FILE` does) is read in its own axes
    by_name = import_gaitmap(shared_data("gaitmap_example", "imu_sample_not_rotated.csv"))
    assert by_name.reference["frame"] == "sensor"
    np.testing.assert_array_equal(by_name.imu["left_foot"].acc, raw_foot.acc)


@pytest.mark.realdata
def test_gaitmap_events_in_seconds_inside_their_strides(gaitmap_recording: Recording) -> None:
    events = load_gaitmap_events(shared_data("gaitmap_example", "stride_events_sample.csv"))
    assert set(events) == {"left", "right"}
    assert len(events["left"]["ic"]) + len(events["right"]["ic"]) == 57  # 57 strides (benchmarks/gait_events)
    duration = gaitmap_recording.imu["left_foot"].t[-1]
    for foot in ("left", "right"):
        ic, tc = events[foot]["ic"], events[foot]["tc"]
        start, end = events[foot]["start"], events[foot]["end"]
        assert np.all((start < tc) & (tc < ic) & (ic <= end))
        assert np.all(ic < duration)
        stride_time = end - start
        assert np.all((stride_time > 0.5) & (stride_time < 3.0))  # seconds (in samples: > 100)
    np.testing.assert_array_equal(gaitmap_recording.reference["events"]["left"]["ic"], events["left"]["ic"])


@pytest.mark.realdata
def test_broad_board_at_285_7_hz_with_mag_in_tesla(broad_recording: Recording) -> None:
    board = broad_recording.imu["board"]
    n = len(board)
    assert board.rate_hz == pytest.approx(285.714, rel=1e-4)
    assert board.mag is not None and board.mag.shape == (n, 3)
    mag_norm = np.median(np.linalg.norm(board.mag, axis=1))
    assert 20e-6 < mag_norm < 70e-6
    assert _static_acc_norm(board.acc, board.gyr) == pytest.approx(GRAVITY, abs=0.6)
    assert np.percentile(np.linalg.norm(board.gyr, axis=1), 99) < 35.0
    reference = broad_recording.reference
    assert reference["opt_quat"].shape == (n, 4)
    finite = np.all(np.isfinite(reference["opt_quat"]), axis=1)
    np.testing.assert_allclose(np.linalg.norm(reference["opt_quat"][finite], axis=1), 1.0, atol=1e-6)
    assert reference["movement"].dtype == bool and reference["movement"].shape == (n,)
    assert 0.2 < reference["movement"].mean() < 1.0
    if not finite.all():
        assert any("opt_quat" in w for w in broad_recording.warnings)


@pytest.mark.realdata
def test_auto_kind_reads_eachshared_data() -> None:
    qmt = shared_data("qmt_fullbody", "full_body_example_data.mat")
    broad = shared_data("broad", "01_undisturbed_slow_rotation_A.mat")
    gaitmap = shared_data("gaitmap_example")
    assert detect_kind(qmt) == "qmt_fullbody"
    assert detect_kind(broad) == "broad"
    assert detect_kind(gaitmap) == "gaitmap"
    assert import_recording("auto", broad, segment="chest").segments == ["chest"]


def test_ipol_gait_trial_on_the_packet_counter_time_base():
    from conftest import shared_data

    from gait_biofeedback.io.importers import detect_kind, import_recording

    path = shared_data("ipol_gait", "8-6.json")
    assert detect_kind(path) == "ipol_gait" and detect_kind(path.with_name("8-6_lf.txt.gz")) == "ipol_gait"
    rec = import_recording("auto", path)
    assert set(rec.imu) == {"left_foot", "right_foot", "pelvis"}
    foot = rec.imu["left_foot"]
    # 3362 rows, packet counter 0 ... 3902: 541 samples lost; times from the counter, not the row
    assert len(foot) == 3362 and foot.t[-1] == pytest.approx(39.02) and foot.mag is None
    assert any("left_foot: 541 samples lost by the radio (13.9 %" in w for w in rec.warnings)
    assert rec.notes == ["magnetometer not imported (vendor-normalised units, not tesla): the recording is "
                         "6D"]
    assert not any("magnetometer" in w for w in rec.warnings)  # no fault: a note
    assert rec.reference["trial"] == pytest.approx((5.15, 25.15))
    # the reference's stride time matches the signal's on this time base (row numbers: 16 % short)
    ic = rec.reference["events"]["left"]["ic"]
    assert 1.0 < np.median(np.diff(ic[:8])) < 1.25
    with pytest.raises(ValueError, match="not an IPOL gait trial file"):
        import_recording("ipol_gait", path.with_name("notes.txt"))


def test_a_one_sensor_gaitmap_file_is_sent_to_the_csv_importer(tmp_path: Path) -> None:
    """gaitmap's per-foot files (``imu_sample_ms_left.csv``) have one header row of axes: the gaitmap
    importer says how to import it with ``import csv`` instead of listing data numbers as axes."""
    path = tmp_path / "imu_sample_ms_left.csv"
    path.write_text(",index,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n0,23000,0.1,0.2,9.8,1.0,2.0,3.0\n"
                    "1,23001,0.1,0.2,9.8,1.0,2.0,3.0\n")
    with pytest.raises(ValueError, match=r"one header row of axes .*import csv .*--units gyr=deg/s --rate "
                       r"204\.8.*left_foot: \{acc: \[acc_x, acc_y, acc_z\]"):
        import_gaitmap(path)


def test_a_file_of_another_built_in_kind_is_refused_naming_its_kind(tmp_path: Path) -> None:
    """qmt's .mat given as gaitmap failed on its bytes ("'utf-8' codec can't decode"): refused naming the
    kind its name says, and the command that imports it; a folder given for qmt without its .mat is
    refused naming the file it looked for."""
    qmt = tmp_path / "full_body_example_data.mat"
    qmt.write_bytes(b"MATLAB 5.0 MAT-file\xec")
    with pytest.raises(ValueError, match=r"is a qmt_fullbody recording by its name and contents, not "
                                         r"gaitmap: import it with `gait-biofeedback import qmt_fullbody "):
        import_recording("gaitmap", qmt)
    broad = tmp_path / "07_undisturbed_fast_rotation_B.mat"
    broad.write_bytes(b"MATLAB 5.0 MAT-file")
    with pytest.raises(ValueError, match="is a broad recording by its name and contents, not qmt_fullbody"):
        import_recording("qmt_fullbody", broad)
    empty = tmp_path / "take"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match=r"a folder without full_body_example_data\.mat"):
        import_recording("qmt_fullbody", empty)


# ---------------------------------------------------------------- pyshoe and UCI HAPT


def test_pyshoe_trial_right_foot_and_vicon_reference(tmp_path: Path) -> None:
    """A pyshoe Vicon trial (MAT v5: ts, imu = acc then gyro, gt, zv_*_opt) is found by its variables
    and read as the right foot from t = 0, the Vicon positions and the detectors' labels as reference;
    a .mat lacking ``gt`` is refused naming it."""
    from scipy.io import savemat

    n = 5
    imu = np.column_stack([np.full(n, 0.1), np.zeros(n), np.full(n, -9.8), np.arange(n) * 0.01,
                           np.zeros(n), np.full(n, 0.5)])
    trial = {"ts": 3.0 + np.arange(n) / 200.0, "imu": imu, "gt": np.arange(3 * n, dtype=float).reshape(n, 3),
             "zv_shoe_opt": np.array([1, 1, 0, 0, 1]), "zv_vicon_opt": np.array([1, 0, 0, 0, 1]),
             "best_error": 0.032}
    path = tmp_path / "2017-11-22-11-22-03.mat"
    savemat(path, trial)
    assert detect_kind(path) == "pyshoe"
    recording = import_recording("auto", path)
    foot = recording.imu["right_foot"]
    np.testing.assert_allclose(foot.t, [0.0, 0.005, 0.010, 0.015, 0.020], atol=1e-12)
    np.testing.assert_array_equal(foot.acc[:, 2], -9.8)
    np.testing.assert_array_equal(foot.gyr[:, 0], [0.0, 0.01, 0.02, 0.03, 0.04])
    assert foot.mag is None
    np.testing.assert_array_equal(recording.reference["position"][1], [3.0, 4.0, 5.0])
    np.testing.assert_array_equal(recording.reference["zero_velocity"]["vicon"],
                                  [True, False, False, False, True])
    assert recording.reference["best_error"] == pytest.approx(0.032)
    del trial["gt"]
    savemat(path, trial)
    with pytest.raises(ValueError, match=r"not a pyshoe Vicon trial: variables \['gt'\] missing"):
        import_recording("pyshoe", path)


def _hapt_raw(folder: Path, acc_rows: list[str], gyro_rows: list[str], labels: str) -> Path:
    folder.mkdir(exist_ok=True)
    (folder / "acc_exp03_user02.txt").write_text("\n".join(acc_rows) + "\n")
    (folder / "gyro_exp03_user02.txt").write_text("\n".join(gyro_rows) + "\n")
    (folder / "labels.txt").write_text(labels)
    return folder / "acc_exp03_user02.txt"


def test_hapt_raw_files_in_g_with_1_based_inclusive_labels(tmp_path: Path) -> None:
    """HAPT's RawData layout: acc (g) and gyro (rad/s) files of one experiment, labels.txt rows
    ``experiment user activity start end`` (1-based, inclusive: module docstring's READING), other
    experiments' rows ignored; the phone is the pelvis, at 50 Hz."""
    acc = ["1.0 0.0 0.0", "0.5 0.5 0.0", "0.0 0.0 -1.0", "1.0 0.1 0.2"]
    gyro = ["0.1 0.2 0.3"] * 4
    path = _hapt_raw(tmp_path / "RawData", acc, gyro, "3 2 5 2 3\n3 2 1 4 4\n4 2 6 1 4\n")
    assert detect_kind(path) == "hapt"
    recording = import_recording("auto", path)
    waist = recording.imu["pelvis"]
    np.testing.assert_allclose(waist.t, [0.0, 0.02, 0.04, 0.06])
    np.testing.assert_allclose(waist.acc[2], [0.0, 0.0, -9.80665])
    np.testing.assert_allclose(waist.gyr[3], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(recording.reference["labels"], [-1, 5, 5, 1])
    assert recording.reference["activities"] == [("standing", 0.02, 0.06), ("walking", 0.06, 0.08)]
    assert import_recording("hapt", path.with_name("gyro_exp03_user02.txt")).imu["pelvis"].acc[0, 0] == \
        pytest.approx(9.80665)


def test_hapt_raw_files_that_disagree_are_refused(tmp_path: Path) -> None:
    """A gyro file shorter than its acc file, a label beyond the experiment's samples and a missing gyro
    file are each refused naming the file."""
    path = _hapt_raw(tmp_path / "a", ["1 0 0"] * 3, ["0 0 0"] * 2, "")
    with pytest.raises(ValueError, match=r"acc_exp03_user02\.txt has 3 samples but gyro_exp03_user02\.txt 2"):
        import_recording("hapt", path)
    path = _hapt_raw(tmp_path / "b", ["1 0 0"] * 3, ["0 0 0"] * 3, "3 2 4 2 9\n")
    with pytest.raises(ValueError, match=r"label 4 spans samples 2-9, outside the 3 samples"):
        import_recording("hapt", path)
    path.with_name("gyro_exp03_user02.txt").unlink()
    with pytest.raises(FileNotFoundError, match=r"gyro_exp03_user02\.txt not found"):
        import_recording("hapt", path)


def test_hapt_csv_per_experiment_with_labels_per_sample(tmp_path: Path) -> None:
    """The one-CSV-per-experiment layout (``userUU_runK.csv.gz``): acc in g, the label column per sample;
    a header without ``gyro-z`` is refused naming it."""
    import gzip

    path = tmp_path / "user20_run1.csv.gz"
    with gzip.open(path, "wt") as f:
        f.write("acc-x,acc-y,acc-z,gyro-x,gyro-y,gyro-z,sequence,label\n"
                "1,0,0,0,0,0,0,-1\n0.9,0,0.1,0.2,0,0,1,4\n1,0,0,0,0,0,2,4\n")
    recording = import_recording("auto", path)
    np.testing.assert_allclose(recording.imu["pelvis"].acc[1], [0.9 * 9.80665, 0.0, 0.1 * 9.80665])
    np.testing.assert_array_equal(recording.reference["labels"], [-1, 4, 4])
    assert recording.reference["activities"] == [("sitting", 0.02, 0.06)]
    with gzip.open(path, "wt") as f:
        f.write("acc-x,acc-y,acc-z,gyro-x,gyro-y,sequence,label\n1,0,0,0,0,0,-1\n")
    with pytest.raises(ValueError, match=r"columns \['gyro-z'\] missing.*read as a UCI HAPT experiment; a "
                       r"CSV of your own: `gait-biofeedback import csv .* --mapping map\.yaml`"):
        import_recording("hapt", path)


def test_hapt_and_pyshoe_shared_data_import() -> None:
    """The real files of ../shared/data: HAPT user 20 run 1 at 50 Hz with 1 g at rest and its first
    labelled activity standing; a pyshoe walking trial at 200 Hz with |acc| 1 g in its first 0.25 s."""
    hapt = import_recording("auto", shared_data("hapt_waist", "user20_run1.csv.gz"))
    waist = hapt.imu["pelvis"]
    assert np.median(np.diff(waist.t)) == pytest.approx(0.02)
    assert np.median(np.linalg.norm(waist.acc, axis=1)) == pytest.approx(9.81, abs=0.3)
    assert hapt.reference["activities"][0][0] == "standing"
    shoe = import_recording("auto", shared_data("pyshoe_vicon", "2017-11-22-11-22-03.mat"))
    foot = shoe.imu["right_foot"]
    assert 1 / np.median(np.diff(foot.t)) == pytest.approx(200.0, rel=0.01)
    assert np.linalg.norm(foot.acc[:50], axis=1).mean() == pytest.approx(9.81, abs=0.3)
