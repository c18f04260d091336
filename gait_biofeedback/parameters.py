"""Every node's parameters, by node name, and the params files that set them (``config/session.yaml``).

Each node's parameters are one stage dataclass (``docs/conventions.md``, Parameters; their tables in
``docs/parameters.md``, made by :func:`parameter_reference`). A params file is in the ROS 2 format
(``/**/<node>: ros__parameters: {...}``; ``/**:`` applies to every node that declares the parameter,
the body dimensions for instance) and is checked here before anything starts: a node name or
parameter nobody declares, a value of the wrong type (an int where a float is expected is accepted
and converted) or out of range is refused with one line naming the file, the node, the parameter and
what is allowed.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from gait_biofeedback.core.activity.stream import ActivityParams
from gait_biofeedback.core.biofeedback.evaluator import BiofeedbackParams
from gait_biofeedback.core.calibration.stream import CalibrationParams
from gait_biofeedback.core.driver.stream import DriverParams
from gait_biofeedback.core.gait.stream import GaitEventsParams
from gait_biofeedback.core.joints.stream import JointAnglesParams
from gait_biofeedback.core.orientation.stream import OrientationParams
from gait_biofeedback.core.params import (
    ParameterError,
    Spec,
    from_mapping,
    spec_by_name,
    specs,
    unknown_name,
)
from gait_biofeedback.core.safe_yaml import YamlRefusedError, describe, load_yaml_file, shown
from gait_biofeedback.io.params import FoxgloveParams, RecorderParams, ReplayerParams

NODE_PARAMETERS: dict[str, type] = {
    "imu_driver": DriverParams,
    "imu_replayer": ReplayerParams,
    "orientation_filter": OrientationParams,
    "calibration": CalibrationParams,
    "joint_angles": JointAnglesParams,
    "gait_events": GaitEventsParams,
    "activity_monitor": ActivityParams,
    "biofeedback": BiofeedbackParams,
    "recorder": RecorderParams,
    "foxglove": FoxgloveParams,
}
"""Node name → its parameters' dataclass (the node classes declare their ROS parameters from it)."""

EVERY_NODE = "**"
PATIENT_BLOCK = "patient"  # the report's pseudonymous patient id and session label, no node's parameters
PATIENT_KEYS = ("id", "session")
ROS_PARAMETERS = ("use_sim_time",)
"""Parameters rclpy itself declares on every node (accepted and handed on unchecked)."""


def is_ros_parameter(name: str) -> bool:
    return name in ROS_PARAMETERS or name.startswith("qos_overrides.")


class StageValues(dict):
    """A node's parameter values as checked (ROS name → value), holding the stage dataclass they were
    checked into (:attr:`stage`): handed on unchanged (to the graph, a node, ``analyze``), they are not
    checked again (:func:`stage_parameters`). Any change forgets the stage, so changed values are checked
    where they are used."""

    stage: Any = None

    @classmethod
    def checked(cls, values: Mapping[str, Any], stage: Any) -> StageValues:
        """``values`` with the stage dataclass instance they were checked into."""
        out = cls(values)
        out.stage = stage
        return out

    def copy(self) -> StageValues:
        """A copy that keeps the checked stage (until it is changed)."""
        return StageValues.checked(self, self.stage)


def _forgetting(method: str) -> Any:
    """``dict.<method>`` that forgets the checked stage first."""
    base = getattr(dict, method)

    def changed(self: StageValues, *args: Any, **kwargs: Any) -> Any:
        self.stage = None
        return base(self, *args, **kwargs)

    changed.__name__ = method
    return changed


for _method in ("__setitem__", "__delitem__", "update", "pop", "popitem", "setdefault", "clear", "__ior__"):
    setattr(StageValues, _method, _forgetting(_method))


def stage_parameters(node: str, values: Mapping[str, Any] | None = None, where: str = "") -> Any:
    """The parameters dataclass of ``node`` from ROS-named ``values`` (the rest default), checked; values
    already checked into their stage (:class:`StageValues`, as :func:`load_params_file` gives them) are
    not checked again."""
    if node not in NODE_PARAMETERS:
        raise ParameterError(f"{where + ': ' if where else ''}unknown node {shown(node)}; nodes: "
                             f"{', '.join(NODE_PARAMETERS)}")
    if isinstance(values, StageValues) and isinstance(values.stage, NODE_PARAMETERS[node]):
        return values.stage
    given = {k: v for k, v in (values or {}).items() if not is_ros_parameter(k)}
    return from_mapping(NODE_PARAMETERS[node], given, where or f"node {node}")


def _flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested ``ros__parameters`` mappings → dotted names, as rcl reads them."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(_flatten(value, f"{name}."))
        else:
            out[name] = value
    return out


def read_params_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """A params file as node name (or ``"**"``) → flat parameter values, unchecked; ParameterError
    for a file that is missing, not YAML, or not in the ROS 2 params-file layout. The ``patient:``
    block (:func:`patient_block`) is checked and left out."""
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"parameter file {path} not found (see config/session.yaml for the format)")
    try:
        document = load_yaml_file(path)
    except YamlRefusedError as exc:
        raise ParameterError(f"{path}: {describe(exc)}") from None
    except yaml.YAMLError as exc:
        raise ParameterError(f"{path}: not valid YAML {describe(exc)}") from None
    if document is None:
        return {}
    if not isinstance(document, Mapping):
        raise ParameterError(f"{path}: expected '/**/<node>: {{ros__parameters: ...}}' entries, "
                             f"got {type(document).__name__}")
    out: dict[str, dict[str, Any]] = {}
    for key, entry in document.items():
        if key == PATIENT_BLOCK:
            patient_block(path, entry)
            continue
        node = str(key).rstrip("/").split("/")[-1]
        if node != EVERY_NODE and node not in NODE_PARAMETERS:
            raise unknown_node(path, str(key), node)
        values = entry.get("ros__parameters") if isinstance(entry, Mapping) else None
        if not isinstance(values, Mapping):
            raise ParameterError(f"{path}: entry {shown(key)} has no 'ros__parameters' mapping")
        out.setdefault(node, {}).update(_flatten(values))
    return out


def patient_block(path: str | Path, entry: Any) -> dict[str, str]:
    """The ``patient: {ros__parameters: {id: ..., session: ...}}`` block of a params file as strings.

    It is written in the ROS 2 layout (a "node" no node is named after) because rcl refuses a file with
    plain values at the top (``ros2 run --params-file`` would fail); an unknown key is refused."""
    values = entry.get("ros__parameters") if isinstance(entry, Mapping) else None
    if not isinstance(values, Mapping):
        raise ParameterError(f"{path}: write the patient block as 'patient: {{ros__parameters: {{id: ..., "
                             "session: ...}}}}' (ROS 2 refuses plain values at the top of a params file)")
    unknown = sorted(set(map(str, values)) - set(PATIENT_KEYS))
    if unknown:
        raise ParameterError(f"{path}: patient block: unknown key(s) {shown(unknown)}; "
                             f"it takes {', '.join(PATIENT_KEYS)}")
    return {str(k): str(v) for k, v in values.items()}


def unknown_node(path: Path, key: str, node: str) -> ParameterError:
    error = unknown_name(node, list(NODE_PARAMETERS), f"{path}")
    return ParameterError(str(error).replace("unknown parameter", f"entry {shown(key)}: unknown node", 1))


def load_params_file(path: str | Path, nodes: list[str] | None = None) -> dict[str, dict[str, Any]]:
    """A params file checked against every node's parameters → node → the values it sets (converted),
    each node's as :class:`StageValues` (checked once, here).

    ``/**`` values go to every node (of ``nodes``, default all) that declares them; a node's own
    entry wins over them. Raises ParameterError (module docstring)."""
    path = Path(path)
    raw = read_params_file(path)
    shared = raw.pop(EVERY_NODE, {})
    for name in shared:
        if not is_ros_parameter(name) and not any(name in spec_by_name(c) for c in NODE_PARAMETERS.values()):
            known = sorted({n for c in NODE_PARAMETERS.values() for n in spec_by_name(c)})
            raise unknown_name(name, known, f"{path}, entry '/**'")
    out: dict[str, dict[str, Any]] = {}
    for node in nodes if nodes is not None else list(NODE_PARAMETERS):
        declared = spec_by_name(NODE_PARAMETERS[node])
        values = {k: v for k, v in shared.items() if k in declared or is_ros_parameter(k)}
        values.update(raw.get(node, {}))
        stage = stage_parameters(node, values, f"{path}, node {node}")
        if values:
            out[node] = StageValues.checked({k: v if is_ros_parameter(k) else _value(stage, declared[k])
                                             for k, v in values.items()}, stage)
    for node in raw:
        if nodes is not None and node not in nodes:
            stage_parameters(node, raw[node], f"{path}, node {node}")
    return out


def _value(stage: Any, spec: Spec) -> Any:
    """The checked value of one parameter in a stage dataclass instance."""
    value = getattr(stage, spec.field)
    return value[spec.key] if spec.key is not None else value


def _shown(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_shown(v) for v in value) + "]"
    if isinstance(value, str):
        return value if value else "''"
    return repr(value) if isinstance(value, float) else str(value)


def parameter_table(node: str) -> list[str]:
    """Markdown rows (parameter, default, allowed, description) of one node's parameters: its table in
    ``docs/parameters.md`` (:func:`parameter_reference`) and ``gait-biofeedback params``."""
    rows = ["| parameter | default | allowed | what it does |", "|---|---|---|---|"]
    seen: set[str] = set()
    for s in specs(NODE_PARAMETERS[node]):
        if s.key is not None:  # one row for the per-key family, e.g. <segment>.algorithm
            if s.field in seen:
                continue
            seen.add(s.field)
            name = s.name.replace(s.key, "<segment>", 1)
        else:
            name = s.name
        rows.append(f"| `{name}` | `{_shown(s.default)}` | {s.allowed()} | {s.description} |")
    return rows


PARAMETER_PAGE_MARKER = ("<!-- generated by scripts/parameter_tables.py from gait_biofeedback.parameters: "
                         "do not edit below -->")
"""The line of ``docs/parameters.md`` below which the page is :func:`parameter_reference`."""


def parameter_reference() -> str:
    """Every node's parameter table under its name, in :data:`NODE_PARAMETERS` order: the generated part
    of ``docs/parameters.md`` (``scripts/parameter_tables.py`` writes it, a test keeps it equal)."""
    return "\n".join(f"## `{node}`\n\n" + "\n".join(parameter_table(node)) + "\n" for node in NODE_PARAMETERS)
