"""Stage parameters, declared once (``docs/conventions.md``, Parameters).

A stage's parameters are a frozen dataclass whose fields are made with :func:`param`: default, unit,
a one-line description, and the allowed (inclusive) range or choices. From that one declaration

* the nodes declare their ROS parameters with descriptors (:mod:`gait_biofeedback.nodes.parameters`);
* the offline path and the params-file check build the same dataclass with :func:`from_mapping`,
  which refuses an unknown name, a wrong type or a value out of range with one line that names it
  (a name renamed to say its unit, :data:`RENAMED`, with its new name).

Types: ``bool``, ``int``, ``float`` (an int is accepted and converted), ``str``, ``tuple[str, ...]``,
``tuple[float, ...]``, and ``dict[str, str]`` for one string per key (``keys``), whose ROS names are
``name.format(key=...)``, e.g. ``left_foot.algorithm``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any

from gait_biofeedback.core.safe_yaml import shown

_META = "gait_biofeedback.param"
_KINDS = {bool: "bool", int: "int", float: "float", str: "str", tuple[str, ...]: "str_list",
          tuple[float, ...]: "float_list", dict[str, str]: "str_per_key"}


class ParameterError(ValueError):
    """A parameter value or name that is refused; the message names it and what is allowed."""


@dataclass(frozen=True)
class Spec:
    """One ROS parameter of a stage: its dataclass ``field`` and ROS ``name`` (they differ only for
    per-key fields), ``kind`` (see module docstring), default, description, unit, allowed values."""

    field: str
    name: str
    kind: str
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] | None = None
    length: int | None = None
    key: str | None = None

    def allowed(self) -> str:
        """What a value must be, in words."""
        unit = f" {self.unit}" if self.unit and self.unit != "1" else ""
        what = {"bool": "true or false", "int": "an integer", "float": "a number", "str": "a string",
                "str_list": "a list of strings", "float_list": "a list of numbers",
                "str_per_key": "a string"}[self.kind]
        if self.length is not None:
            what = f"{what[:-1]} of {self.length} numbers" if self.kind == "float_list" else what
        if self.choices is not None:
            element = "each one of" if self.kind == "str_list" else "one of"
            what = f"{what}, {element} {', '.join(repr(c) for c in self.choices)}"
        if self.low is not None and self.high is not None:
            what += f" in [{self.low:g}, {self.high:g}]{unit}"
        elif self.low is not None:
            what += f" >= {self.low:g}{unit}"
        elif unit:
            what += f" ({unit.strip()})"
        return what

    def describe(self) -> str:
        """Description with the unit, as ROS reports it: ``"max gap before reset [s]"``."""
        return f"{self.description} [{self.unit}]" if self.unit else self.description


def param(default: Any, description: str, unit: str = "", *, low: float | None = None,
          high: float | None = None, choices: Sequence[Any] | None = None, length: int | None = None,
          keys: Sequence[str] | None = None, name: str | None = None) -> Any:
    """A dataclass field that declares one parameter (``keys``: one per key, named ``name``)."""
    meta = {"description": description, "unit": unit, "low": low, "high": high,
            "choices": None if choices is None else tuple(choices), "length": length,
            "keys": None if keys is None else tuple(keys), "name": name, "default": default}
    if keys is not None:
        return dataclasses.field(default_factory=lambda: dict.fromkeys(keys, default), metadata={_META: meta})
    if isinstance(default, (list, tuple)):
        value = tuple(default)
        return dataclasses.field(default_factory=lambda: value, metadata={_META: meta})
    return dataclasses.field(default=default, metadata={_META: meta})


def same_as(cls: type, field_name: str) -> Any:
    """The field ``field_name`` of the stage dataclass ``cls`` again (same default, unit, description,
    range): one declaration serves every stage that needs the same quantity."""
    f = next(f for f in dataclasses.fields(cls) if f.name == field_name)
    if f.default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=f.default_factory, metadata=f.metadata)
    return dataclasses.field(default=f.default, metadata=f.metadata)


@cache
def specs(cls: type) -> tuple[Spec, ...]:
    """Every ROS parameter of the stage dataclass ``cls``, in declaration order."""
    hints = typing.get_type_hints(cls)
    out: list[Spec] = []
    for f in dataclasses.fields(cls):
        meta = f.metadata.get(_META)
        if meta is None:
            raise TypeError(f"{cls.__name__}.{f.name} is not declared with param()")
        kind = _KINDS.get(hints[f.name])
        if kind is None:
            raise TypeError(f"{cls.__name__}.{f.name}: unsupported parameter type {hints[f.name]}")
        given = ("default", "description", "unit", "low", "high", "choices", "length")
        common = {"field": f.name, "kind": kind, **{k: meta[k] for k in given}}
        if kind == "str_per_key":
            out.extend(Spec(name=meta["name"].format(key=key), key=key, **{**common, "kind": "str"})
                       for key in meta["keys"])
        else:
            if isinstance(common["default"], list):
                common["default"] = tuple(common["default"])
            out.append(Spec(name=meta["name"] or f.name, **common))
    return tuple(out)


def spec_by_name(cls: type) -> dict[str, Spec]:
    """ROS name → spec of the stage dataclass ``cls``."""
    return {s.name: s for s in specs(cls)}


def check(spec: Spec, value: Any) -> Any:
    """``value`` converted to the spec's type (int → float, list → tuple); ParameterError if it is
    of another type, out of range or not one of the choices."""
    problem = _problem(spec, value)
    if problem:
        raise ParameterError(f"parameter {spec.name!r}: {problem}; allowed: {spec.allowed()}")
    if spec.kind == "float":
        return float(value)
    if spec.kind == "float_list":
        return tuple(float(v) for v in value)
    if spec.kind == "str_list":
        return tuple(value)
    return value


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _problem(spec: Spec, value: Any) -> str:
    kind = spec.kind
    if kind == "bool":
        return "" if isinstance(value, bool) else f"got {shown(value)}"
    if kind == "int":
        if not isinstance(value, int) or isinstance(value, bool):
            return f"got {shown(value)}"
        return _range_problem(spec, value)
    if kind == "float":
        if not _is_number(value) or not math.isfinite(value):
            return f"got {shown(value)}"
        return _range_problem(spec, value)
    if kind == "str":
        if not isinstance(value, str):
            return f"got {shown(value)}"
        return "" if spec.choices is None or value in spec.choices else f"got {shown(value)}"
    if not isinstance(value, (list, tuple)):
        return f"got {shown(value)}"
    if kind == "str_list":
        bad = [v for v in value
               if not isinstance(v, str) or (spec.choices is not None and v not in spec.choices)]
        return f"got {shown(list(value))} ({shown(bad)} not allowed)" if bad else ""
    if not all(_is_number(v) and math.isfinite(v) for v in value):
        return f"got {shown(list(value))}"
    if spec.length is not None and len(value) != spec.length:
        return f"got {len(value)} numbers"
    return ""


def _range_problem(spec: Spec, value: float) -> str:
    if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
        return f"{shown(value)} is out of range"
    return ""


_SECONDS = (
    "reorder_window", "clock_bin", "clock_window", "stale_after", "diagnostics_period",  # imu_driver
    "start_offset", "stop_offset", "clock_period", "wait_for_subscribers",  # imu_replayer
    "max_gap", "mag_max_age",  # orientation_filter (and reorder_window, stale_after, diagnostics_period)
    "default_standing_duration", "apply_delay",  # calibration
    "max_wait", "heading_time_constant", "heading_position_window",  # joint_angles
    "dropout_gap", "spatial_wait", "provisional_after", "bias_rest", "close_after", "min_swing",
    "max_swing",  # gait_events
    "publish_period",  # activity_monitor
    "stride_wait",  # biofeedback
    "split_duration", "flush_period", "discovery_period",  # recorder
)
RENAMED: dict[str, str] = {
    **{old: f"{old}_s" for old in _SECONDS},
    "sim_rate": "sim_rate_hz", "frame_rate": "frame_rate_hz", "split_size": "split_size_bytes",
    "standing_max_tilt": "standing_max_tilt_rad", "toe_lever_arm": "toe_lever_arm_m",
    "provisional_tolerance": "provisional_tolerance_m",
    **{old: f"{old}_m" for old in ("thigh_length", "shank_length", "hip_width", "foot_length",
                                   "ankle_height")},
}
"""Node parameters renamed to say their unit (issue 46), old name → new name: one in a params file or
a ROS override is refused naming the new one (:func:`unknown_name`), never ignored."""
_UNIT_WORDS = {"_s": "seconds", "_hz": "Hz", "_bytes": "bytes", "_rad": "radians", "_m": "metres"}


def unknown_name(name: str, known: Sequence[str], where: str) -> ParameterError:
    """The refusal of a parameter (or node) name nobody declares: the new name of a renamed one
    (:data:`RENAMED`), else the nearest known names."""
    prefix = f"{where}: " if where else ""
    new = RENAMED.get(name)
    if new is not None:
        unit = next(word for suffix, word in _UNIT_WORDS.items() if new.endswith(suffix))
        return ParameterError(f"{prefix}parameter {shown(name)} was renamed {shown(new)} ({unit})")
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
    return ParameterError(f"{prefix}unknown parameter {shown(name)}{hint} "
                          f"(known: {', '.join(sorted(known))})")


def from_mapping(cls: type, values: Mapping[str, Any] | None = None, where: str = "") -> Any:
    """The stage dataclass ``cls`` from ROS-named ``values`` (the rest at their defaults), checked.

    ``where`` (e.g. ``"config/session.yaml, node gait_events"``) starts every error message."""
    by_name = spec_by_name(cls)
    prefix = f"{where}: " if where else ""
    kwargs: dict[str, Any] = {}
    for name, value in (values or {}).items():
        spec = by_name.get(name)
        if spec is None:
            raise unknown_name(name, list(by_name), where)
        try:
            checked = check(spec, value)
        except ParameterError as exc:
            raise ParameterError(f"{prefix}{exc}") from None
        if spec.key is not None:
            per_key = kwargs.setdefault(spec.field, dict.fromkeys(_keys(cls, spec.field), spec.default))
            per_key[spec.key] = checked
        else:
            kwargs[spec.field] = checked
    try:
        return cls(**kwargs)
    except ParameterError as exc:
        raise ParameterError(f"{prefix}{exc}") from None


def _keys(cls: type, field_name: str) -> tuple[str, ...]:
    return tuple(s.key for s in specs(cls) if s.field == field_name)


def as_mapping(instance: Any) -> dict[str, Any]:
    """ROS name → value of a stage dataclass instance (lists for sequences, as ROS takes them)."""
    out: dict[str, Any] = {}
    for spec in specs(type(instance)):
        value = getattr(instance, spec.field)
        if spec.key is not None:
            value = value[spec.key]
        out[spec.name] = list(value) if isinstance(value, tuple) else value
    return out


def require(condition: bool, message: str) -> None:
    """A check across fields in a stage's ``__post_init__``: ParameterError(message) unless ``condition``."""
    if not condition:
        raise ParameterError(message)
