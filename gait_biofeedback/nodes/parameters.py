"""ROS parameters of a node, declared from its stage dataclass (:mod:`gait_biofeedback.core.params`).

Every parameter gets a ``ParameterDescriptor``: the description with its unit, the allowed range
(``FloatingPointRange`` / ``IntegerRange``) or choices (``additional_constraints``), and
``read_only`` (the nodes read their parameters once, at start: a later ``ros2 param set`` is
refused instead of silently ignored). The node's overrides (``--ros-args -p``/``--params-file``,
``parameter_overrides``) are checked with the stage's own rules before they are declared: an int
for a float is converted, anything else wrong raises :class:`~gait_biofeedback.core.params.ParameterError`
naming the node, the parameter and what is allowed; an override that no node of the project declares
is refused too (one that another node declares, e.g. ``/**`` body dimensions, is left alone as ROS
does).
"""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from gait_biofeedback.core.params import (
    ParameterError,
    Spec,
    as_mapping,
    check,
    from_mapping,
    specs,
    unknown_name,
)
from gait_biofeedback.parameters import NODE_PARAMETERS, is_ros_parameter

_TYPES = {"bool": Parameter.Type.BOOL, "int": Parameter.Type.INTEGER, "float": Parameter.Type.DOUBLE,
          "str": Parameter.Type.STRING, "str_list": Parameter.Type.STRING_ARRAY,
          "float_list": Parameter.Type.DOUBLE_ARRAY}


def descriptor(spec: Spec) -> ParameterDescriptor:
    """The ROS descriptor of one parameter."""
    d = ParameterDescriptor(name=spec.name, type=_TYPES[spec.kind].value, description=spec.describe(),
                            read_only=True, additional_constraints=f"allowed: {spec.allowed()}")
    if spec.kind == "float" and spec.low is not None and spec.high is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high))]
    if spec.kind == "int" and spec.low is not None and spec.high is not None:
        d.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high))]
    return d


def _ros(value: Any) -> Any:
    """A parameter value as rclpy takes it (lists, not tuples)."""
    return list(value) if isinstance(value, tuple) else value


def node_overrides(overrides: dict[str, object]) -> list[Parameter]:
    """``parameter_overrides`` of a node class's ``**overrides`` keyword arguments."""
    return [Parameter(k, value=_ros(v)) for k, v in overrides.items()]


def declare_parameters(node: Node, cls: type, checked: Any = None) -> Any:
    """Declare every parameter of the stage dataclass ``cls`` on ``node``; return the instance built
    from their values (see module docstring). ``checked``: an instance of ``cls`` whose values were
    checked already (the in-process graph checks a params file once,
    :func:`~gait_biofeedback.parameters.load_params_file`): they
    are declared as they are, and only a value the node's own overrides change is checked here."""
    where = f"node {node.get_fully_qualified_name()}"
    overrides = node._parameter_overrides
    preset = as_mapping(checked) if checked is not None else {}
    values: dict[str, Any] = {}
    changed = False
    for spec in specs(cls):
        given = overrides.get(spec.name)
        if given is not None:
            try:
                value = check(spec, given.value)
            except ParameterError as exc:
                raise ParameterError(f"{where}: {exc}") from None
            overrides[spec.name] = Parameter(spec.name, value=_ros(value))
            changed = True
        default = preset.get(spec.name, spec.default)
        if isinstance(default, (tuple, list)) and not default:
            declared = node.declare_parameters("", [(spec.name, _TYPES[spec.kind], descriptor(spec))])[0]
        else:
            declared = node.declare_parameter(spec.name, _ros(default), descriptor(spec))
        if declared.type_ != Parameter.Type.NOT_SET:
            values[spec.name] = declared.value
    _refuse_unknown(node, cls, overrides, where)
    if checked is not None and not changed:
        return checked
    return from_mapping(cls, values, where)


def _refuse_unknown(node: Node, cls: type, overrides: dict[str, Parameter], where: str) -> None:
    everyone = {s.name for c in NODE_PARAMETERS.values() for s in specs(c)}
    for name in overrides:
        if not node.has_parameter(name) and not is_ros_parameter(name) and name not in everyone:
            raise unknown_name(name, [s.name for s in specs(cls)], where)
