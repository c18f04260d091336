"""Parameters are declared once: the stage dataclasses, what the nodes report over ROS, config/session.yaml
and docs/parameters.md agree; a params file with a typo, a wrong type or a value out of range is refused
before anything starts, naming the file, node, parameter and what is allowed."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from gait_biofeedback.core.params import RENAMED, ParameterError, from_mapping, specs
from gait_biofeedback.parameters import (
    NODE_PARAMETERS,
    PARAMETER_PAGE_MARKER,
    load_params_file,
    parameter_reference,
    parameter_table,
    stage_parameters,
)

REPO = Path(__file__).resolve().parents[1]
SESSION = REPO / "config" / "session.yaml"


def test_every_parameter_has_a_description_a_unit_and_what_is_allowed():
    for node, cls in NODE_PARAMETERS.items():
        for s in specs(cls):
            assert s.description and "\n" not in s.description, f"{node}.{s.name}: a one-line description"
            if s.kind in ("int", "float"):
                assert s.low is not None and s.high is not None, f"{node}.{s.name}: a numeric range"
                assert s.low <= s.default <= s.high, f"{node}.{s.name}: default inside its range"
            if s.kind == "float":
                assert s.unit, f"{node}.{s.name}: a unit ('1' when dimensionless)"
            if s.choices is not None and s.kind == "str":
                assert s.default in s.choices


def test_session_yaml_names_real_parameters_at_their_defaults():
    loaded = load_params_file(SESSION)
    assert set(loaded) == set(NODE_PARAMETERS) - {"imu_replayer"}
    for node, values in loaded.items():
        defaults = {s.name: s.default for s in specs(NODE_PARAMETERS[node])}
        for name, value in values.items():
            assert value == defaults[name], f"{node}.{name} = {value!r}, default {defaults[name]!r}"
    # the /** body dimensions reach every node that declares them, and only those
    assert loaded["activity_monitor"]["thigh_length_m"] == 0.42
    assert "thigh_length_m" not in loaded["gait_events"]


def test_docs_list_every_parameter_as_declared():
    page = (REPO / "docs" / "parameters.md").read_text()
    assert PARAMETER_PAGE_MARKER in page
    generated = page.split(PARAMETER_PAGE_MARKER, 1)[1].strip("\n")
    assert generated == parameter_reference().strip("\n"), (
        "docs/parameters.md differs from the stage dataclasses; regenerate it with "
        "`.venv/bin/python scripts/parameter_tables.py`")
    for node in NODE_PARAMETERS:  # each node's table, whole, under its own heading
        table = "\n".join(parameter_table(node))
        assert f"## `{node}`\n\n{table}\n" in page
    assert "| `max_gap_s` | `0.15` |" in page  # one row by hand: the orientation filter's bridged holes


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "params.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(("text", "expected"), [
    ("/**/orientation_filtr:\n  ros__parameters:\n    max_gap_s: 1.0\n",
     r"entry '/\*\*/orientation_filtr': unknown node 'orientation_filtr'; did you mean 'orientation_filter'"),
    ("/**/orientation_filter:\n  ros__parameters:\n    max_gapp: 1.0\n",
     r"node orientation_filter: unknown parameter 'max_gapp'; did you mean 'max_gap_s'"),
    ("/**/orientation_filter:\n  ros__parameters:\n    max_gap_s: -1.0\n",
     r"node orientation_filter: parameter 'max_gap_s': -1\.0 is out of range; "
     r"allowed: a number in \[0\.01, 60\] s"),
    ("/**/orientation_filter:\n  ros__parameters:\n    max_gap_s: fast\n",
     r"parameter 'max_gap_s': got 'fast'; allowed: a number"),
    ("/**/gait_events:\n  ros__parameters:\n    sides: [left, middle]\n",
     r"node gait_events: parameter 'sides'.*'middle'.*"
     r"allowed: a list of strings, each one of 'left', 'right'"),
    ("/**/gait_events:\n  ros__parameters:\n    min_stride_s: 2.0\n    max_stride_s: 1.0\n",
     r"node gait_events: parameter 'min_stride_s' \(2\) must be below 'max_stride_s' \(1\)"),
    ("/**:\n  ros__parameters:\n    thigh_lenght: 0.5\n", r"entry '/\*\*': unknown parameter 'thigh_lenght'"),
    ("/**/orientation_filter:\n  ros__parameters:\n    max_gap: 1.0\n",
     r"node orientation_filter: parameter 'max_gap' was renamed 'max_gap_s' \(seconds\)$"),
    ("/**:\n  ros__parameters:\n    thigh_length: 0.5\n",
     r"entry '/\*\*': parameter 'thigh_length' was renamed 'thigh_length_m' \(metres\)$"),
    ("/**/biofeedback:\n  ros__parameters:\n    port: 8080.5\n", r"parameter 'port': got 8080\.5"),
    ("/**/recorder:\n  ros__parameters:\n    compression: gzip\n",
     r"parameter 'compression': got 'gzip'; allowed: a string, one of 'zstd', 'lz4', 'none'"),
    ("/**/recorder:\n  parameters:\n    compression: lz4\n", r"has no 'ros__parameters' mapping"),
    ("/**/recorder:\n  ros__parameters:\n    compression: [lz4\n", r"not valid YAML at line \d+, column \d+"),
])
def test_a_bad_params_file_is_refused_naming_file_node_parameter_and_allowed(tmp_path, text, expected):
    path = _write(tmp_path, text)
    with pytest.raises(ParameterError, match=expected) as caught:
        load_params_file(path)
    message = str(caught.value)
    assert message.startswith(str(path)) and "\n" not in message


UNIT_SUFFIXES = {"s": "_s", "Hz": "_hz", "m": "_m", "rad": "_rad", "B": "_bytes"}
"""A parameter in one of these units says it in its name (issue 46); compound units (rad/s, m/s^2, m/s^3,
rad^2) have no suffix, counts and ratios none."""


def test_every_parameter_in_a_plain_unit_says_it_in_its_name():
    for node, cls in NODE_PARAMETERS.items():
        for s in specs(cls):
            suffix = UNIT_SUFFIXES.get(s.unit)
            assert suffix is None or s.name.endswith(suffix), f"{node}.{s.name} [{s.unit}]: name it …{suffix}"


def test_the_renamed_table_names_old_names_nobody_declares_and_new_ones_somebody_does():
    declared = {s.name for cls in NODE_PARAMETERS.values() for s in specs(cls)}
    assert not set(RENAMED) & declared
    assert set(RENAMED.values()) <= declared


def test_every_renamed_parameter_is_refused_with_its_new_name(tmp_path):
    """An old name in a params file is never ignored nor taken: refused, naming the new name."""
    units = {"_s": "seconds", "_hz": "Hz", "_bytes": "bytes", "_rad": "radians", "_m": "metres"}
    for node, cls in NODE_PARAMETERS.items():
        for s in specs(cls):
            old = next((o for o, new in RENAMED.items() if new == s.name), None)
            if old is None:
                continue
            value = list(s.default) if isinstance(s.default, tuple) else s.default
            path = _write(tmp_path, f"/**/{node}:\n  ros__parameters:\n    {old}: {value}\n")
            unit = next(word for suffix, word in units.items() if s.name.endswith(suffix))
            with pytest.raises(ParameterError) as caught:
                load_params_file(path)
            assert str(caught.value) == (f"{path}, node {node}: parameter '{old}' was renamed '{s.name}' "
                                         f"({unit})")


def test_an_int_for_a_float_is_accepted_and_converted(tmp_path):
    path = _write(tmp_path,
                  "/**/orientation_filter:\n  ros__parameters:\n    max_gap_s: 1\n    rate_hz: 200\n")
    values = load_params_file(path)["orientation_filter"]
    assert values == {"max_gap_s": 1.0, "rate_hz": 200.0} and all(type(v) is float for v in values.values())
    assert stage_parameters("orientation_filter", values).max_gap_s == 1.0
    with pytest.raises(ParameterError, match=r"parameter 'skeleton_every': got 2\.5"):
        stage_parameters("joint_angles", {"skeleton_every": 2.5})


def test_per_segment_parameters_and_the_stage_dataclass():
    params = from_mapping(NODE_PARAMETERS["orientation_filter"], {"chest.algorithm": "madgwick"})
    assert params.algorithm_of("chest") == "madgwick" and params.algorithm_of("pelvis") == "inertial_cf"
    with pytest.raises(ParameterError, match=r"'chest\.algorithm': got 'kalman'"):
        from_mapping(NODE_PARAMETERS["orientation_filter"], {"chest.algorithm": "kalman"})


@pytest.mark.parametrize("command", [
    ["analyze", "BAG", "-o", "OUT"],
    ["replay", "BAG"],
    ["run", "--nodes", "orientation_filter"],
])
def test_cli_refuses_a_typo_before_anything_starts(tmp_path, capsys, command):
    from gait_biofeedback.cli import main

    path = _write(tmp_path, "/**/gait_events:\n  ros__parameters:\n    treshold: -0.3\n")
    args = [str(tmp_path / "missing_bag") if a == "BAG" else str(tmp_path / "out") if a == "OUT" else a
            for a in command]
    assert main([*args, "--params", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert re.fullmatch(rf"gait-biofeedback {command[0]}: {re.escape(str(path))}, node gait_events: unknown "
                        r"parameter 'treshold'; did you mean 'threshold'\? \(known: .*\)", err), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", [["analyze", "BAG", "-o", "OUT"], ["params", "--check"]])
def test_cli_refuses_a_parameter_by_its_old_name(tmp_path, capsys, command):
    """A parameter renamed to say its unit (issue 46), given by its old name: exit 2, the new name said."""
    from gait_biofeedback.cli import main

    path = _write(tmp_path, "/**/calibration:\n  ros__parameters:\n    default_standing_duration: 2.0\n")
    args = [str(tmp_path / "missing_bag") if a == "BAG" else str(tmp_path / "out") if a == "OUT" else a
            for a in command]
    argv = [*args, str(path)] if command[-1] == "--check" else [*args, "--params", str(path)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"gait-biofeedback {command[0]}: {path}, node calibration: parameter "
                   "'default_standing_duration' was renamed 'default_standing_duration_s' (seconds)"), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("setting", "expected"), [
    ("max_gap_s: -1.0", "out of range"),
    ("max_gap: 0.3", "parameter 'max_gap' was renamed 'max_gap_s' (seconds)"),
])
def test_console_script_refuses_a_bad_params_file(tmp_path, setting, expected):
    path = _write(tmp_path, f"/**/orientation_filter:\n  ros__parameters:\n    {setting}\n")
    run = subprocess.run([sys.executable, "-m", "gait_biofeedback.nodes.orientation_filter", "--ros-args",
                          "--params-file", str(path)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert "max_gap" in run.stderr and expected in run.stderr and "Traceback" not in run.stderr


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_every_node_reports_its_parameters_with_unit_and_range_over_ros(ros_context, tmp_path):
    from conftest import synthetic_imu
    from rclpy.parameter import Parameter

    from gait_biofeedback.graph import processing_nodes
    from gait_biofeedback.io.bag import write_imu_bag
    from gait_biofeedback.nodes.imu_driver import ImuDriverNode
    from gait_biofeedback.nodes.imu_replayer import ImuReplayer
    from gait_biofeedback.nodes.recorder import Recorder

    bag = write_imu_bag(tmp_path / "in", synthetic_imu(["chest"], duration=0.5))
    factories = {**processing_nodes(), "recorder": Recorder, "imu_replayer": ImuReplayer,
                 "imu_driver": ImuDriverNode}
    extra = {"biofeedback": {"port": 0}, "calibration": {"session_dir": str(tmp_path / "s")},
             "imu_driver": {"port": 0, "start": False},
             "recorder": {"output": str(tmp_path / "rec")}, "imu_replayer": {"bag": str(bag)}}
    for name, factory in factories.items():
        node = factory(ros_context, **extra.get(name, {}))
        try:
            for s in specs(NODE_PARAMETERS[name]):
                d = node.describe_parameter(s.name)
                assert d.description == s.describe() and d.read_only, f"{name}.{s.name}"
                if s.unit:
                    assert d.description.endswith(f"[{s.unit}]")
                if s.kind == "float":
                    (r,) = d.floating_point_range
                    assert (r.from_value, r.to_value) == (s.low, s.high)
            result = node.set_parameters([Parameter(specs(NODE_PARAMETERS[name])[0].name, value=None)])[0]
            assert not result.successful, "read-only: the node reads its parameters once, at start"
        finally:
            node.destroy_node()


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_node_refuses_a_bad_override_and_converts_an_int(ros_context):
    from gait_biofeedback.nodes.gait_events import GaitEventsNode

    node = GaitEventsNode(ros_context, max_gap_s=1)
    assert node.params.max_gap_s == 1.0 and node.get_parameter("max_gap_s").value == 1.0
    node.destroy_node()
    with pytest.raises(ParameterError, match=r"node /gait_events: parameter 'max_gap_s': -1 is out of range"):
        GaitEventsNode(ros_context, max_gap_s=-1)
    with pytest.raises(ParameterError, match=r"unknown parameter 'max_gapp'; did you mean 'max_gap_s'"):
        GaitEventsNode(ros_context, max_gapp=1.0)
    with pytest.raises(ParameterError,
                       match=r"^node /gait_events: parameter 'max_gap' was renamed 'max_gap_s' \(seconds\)$"):
        GaitEventsNode(ros_context, max_gap=1.0)


@pytest.mark.timeout(60)
def test_a_session_file_value_is_checked_once_on_its_way_to_its_node(monkeypatch):
    """config/session.yaml → the in-process graph → the node: each value the file sets is checked once,
    when the file is loaded (it was checked four times and built into its dataclass three times)."""
    from collections import Counter

    import gait_biofeedback.core.params as core_params
    import gait_biofeedback.nodes.parameters as node_parameters
    from gait_biofeedback.graph import running_graph

    calls: Counter = Counter()
    real = core_params.check

    def counting(spec, value):
        calls[spec.name] += 1
        return real(spec, value)

    monkeypatch.setattr(core_params, "check", counting)
    monkeypatch.setattr(node_parameters, "check", counting)
    params = load_params_file(REPO / "config" / "session.yaml")
    assert calls["buffer_s"] == 1 and calls["max_gap_s"] == 1
    with running_graph(["orientation_filter", "calibration"], node_parameters=params) as graph:
        assert graph.nodes["calibration"].params.buffer_s == params["calibration"]["buffer_s"]
        assert graph.nodes["calibration"].params is params["calibration"].stage
        assert graph.nodes["orientation_filter"].params.max_gap_s == params["orientation_filter"]["max_gap_s"]
    assert calls["buffer_s"] == 1 and calls["max_gap_s"] == 1, calls
    # a value changed on the way (the command line's) is checked where it is used, with the others
    changed = params["calibration"].copy()
    assert stage_parameters("calibration", changed) is params["calibration"].stage
    changed["buffer_s"] = 30.0
    assert stage_parameters("calibration", changed).buffer_s == 30.0 and calls["buffer_s"] == 2
    changed["buffer_s"] = -1.0
    with pytest.raises(ParameterError, match="buffer_s"):
        stage_parameters("calibration", changed)
