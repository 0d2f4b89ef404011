"""Node parameters as data: name, default, description and what values are valid (no ROS).

A node declares its ``Param`` specs through ``gnss_ins_common.ros_params``; offline tools (the
replay tool reading the same YAML file as the fusion node) validate them with ``validate`` and
``load_yaml`` here, so both refuse the same bad values with the same messages.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence, Sized
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any, Literal

import yaml

ParamValue = bool | int | float | str | list[str] | list[float] | list[int]


class ParameterValueError(ValueError):
    """A parameter is out of range, of the wrong type, unknown or not allowed."""


@dataclass(frozen=True)
class Param:
    """One declared parameter: name, default, description and what values are valid."""

    name: str
    default: ParamValue
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    #: Extra check on the value: returns an error message, or None when the value is fine.
    check: Callable[[Any], str | None] | None = None
    #: Element type of a list parameter whose default is empty (it cannot be inferred).
    empty_list_of: Literal["str", "float"] = "str"
    #: A list parameter that also accepts one number, meaning that value for every element
    #: (e.g. a per-axis noise density given once for the three axes).
    broadcast: bool = False

    @property
    def is_frame(self) -> bool:
        """A TF frame name (``frame_id`` or ``*_frame``): without white space, and non-empty
        unless its default is empty (an optional frame: empty = none)."""
        return isinstance(self.default, str) and (
            self.name == "frame_id" or self.name.endswith("_frame")
        )

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is not acceptable, or None (type, choices, range, extra check)."""
        if isinstance(self.default, list):
            if not isinstance(value, list):
                return f"expected a list, got {value!r}"
            element = self.default[0] if self.default else _EMPTY_ELEMENT[self.empty_list_of]
            wrong = [item for item in value if not _same_type(element, item)]
            if wrong:
                return f"expected a list of {type(element).__name__}, got {wrong[0]!r}"
        elif not _same_type(self.default, value):
            return f"expected {type(self.default).__name__}, got {value!r}"
        if self.choices and value not in self.choices:
            return f"'{value}' is not one of {', '.join(self.choices)}"
        if self.is_frame and ((not value and self.default) or any(c.isspace() for c in value)):
            return f"{value!r} is not a frame name (non-empty, no spaces)"
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, str | bool):
                continue
            if not math.isfinite(item):
                return f"{item} is not a finite number"
            if (self.low is not None and not item >= self.low) or (
                self.high is not None and not item <= self.high
            ):
                return f"{item} is outside [{self.low}, {self.high}]"
        return self.check(value) if self.check is not None else None


#: The parameter that makes a managed driver node configure and activate itself at start
#: (gnss_ins_common.ros_lifecycle).
AUTOSTART = Param(
    "autostart",
    True,
    "configure and activate at start; false: wait for a lifecycle manager's transitions",
)

_EMPTY_ELEMENT: dict[str, ParamValue] = {"str": "", "float": 0.0}


def needs_values(count: int, names: str) -> Callable[[Sized], str | None]:
    """A ``Param.check`` for a list of ``count`` values; ``names`` says which (e.g. "x, y, z")."""

    def check(values: Sized) -> str | None:
        return None if len(values) == count else f"needs {count} values ({names})"

    return check


def serial_link_params(
    device: str, baud: int, baud_description: str, stall_timeout_s: float, min_stall_s: float
) -> tuple[Param, ...]:
    """The parameters of a driver node's serial link and its status: ``port``, ``baud``,
    ``stall_timeout`` and ``diagnostics_period``."""
    return (
        Param("port", "/dev/ttyUSB0", f"serial device of the {device}"),
        Param("baud", baud, baud_description, 1200, 921600),
        Param(
            "stall_timeout",
            stall_timeout_s,
            "reconnect when no byte arrives for this long [s]",
            min_stall_s,
            60.0,
        ),
        Param("diagnostics_period", 1.0, "period of the /diagnostics status [s]", 0.1, 60.0),
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _same_type(default: Any, value: Any) -> bool:
    """``value`` has the type of ``default``; an int is accepted where a float is expected."""
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if isinstance(default, float):
        return isinstance(value, int | float)
    return isinstance(value, type(default))


def validate(spec: Param, value: Any) -> Any:
    """``value`` (ints widened to float where the default is a float), or ParameterValueError."""
    if isinstance(value, tuple):
        value = list(value)
    if spec.broadcast and isinstance(spec.default, list) and _is_number(value):
        value = [value] * len(spec.default)
    problem = spec.problem(value)
    if problem:
        raise ParameterValueError(f"parameter '{spec.name}': {problem} ({spec.description})")
    if isinstance(spec.default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    default = spec.default
    if isinstance(value, list) and isinstance(default, list) and default:
        return [float(v) for v in value] if isinstance(default[0], float) else value
    return value


def validate_all(specs: Sequence[Param], values: Mapping[str, Any]) -> dict[str, Any]:
    """Defaults overridden by ``values``; unknown names and bad values raise."""
    by_name = {spec.name: spec for spec in specs}
    unknown = sorted(set(values) - set(by_name))
    if unknown:
        raise ParameterValueError(f"unknown parameter(s): {', '.join(unknown)}")
    result = {}
    for spec in specs:
        default = list(spec.default) if isinstance(spec.default, list) else spec.default
        result[spec.name] = validate(spec, values[spec.name]) if spec.name in values else default
    return result


def read_parameter_file(path: Path) -> dict[str, Any]:
    """The top-level mapping of a ROS parameter file, or ParameterValueError saying why not:
    unreadable, not YAML, or not ``{node: {ros__parameters: {...}}}`` (namespaces may nest)."""
    try:
        with path.open() as stream:  # a stream, so that YAML errors name the file
            document = yaml.safe_load(stream) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise ParameterValueError(f"cannot read parameter file {path}: {exc}") from exc
    problem = _layout_problem(document, "")
    if problem:
        raise ParameterValueError(f"parameter file {path}: {problem}")
    return dict(document)


def _layout_problem(section: Any, where: str) -> str | None:
    """Why ``section`` is not a node or namespace mapping of a parameter file, or None."""
    if not isinstance(section, Mapping):
        return f"{where or 'the file'} must be a mapping of node names, got {section!r}"
    for key, value in section.items():
        name = f"{where}/{key}".lstrip("/") if key != "/**" else key
        if key == "ros__parameters":
            if not isinstance(value, Mapping):
                return f"{name} must be a mapping of parameter names, got {value!r}"
        elif (problem := _layout_problem(value, name)) is not None:
            return problem
    return None


def check_parameter_files(ros_args: Sequence[str]) -> None:
    """Read every ``--params-file FILE`` of a node's command line (``read_parameter_file``) so
    that a missing or malformed file is refused with a message, not by rcl with a traceback."""
    for flag, value in pairwise(ros_args):
        if flag == "--params-file":
            read_parameter_file(Path(value))


def file_values(path: Path, node_name: str) -> dict[str, Any]:
    """The parameters a ROS parameter file gives ``node_name`` (its ``NAME``, ``/NAME`` or ``/**``
    section), nested maps flattened to dotted names; nothing validated or defaulted. A file with
    none of these sections (a foreign file: its values would silently not apply) is refused; an
    empty file gives no parameters."""
    document = read_parameter_file(path)
    keys = (node_name, f"/{node_name}", "/**")
    for key in keys:
        if key in document:
            return _flatten((document[key] or {}).get("ros__parameters", {}))
    if not document:
        return {}
    found = ", ".join(map(str, document))
    raise ParameterValueError(
        f"parameter file {path} has no section for {node_name} (top keys: {found});"
        f" expected one of {', '.join(keys)}"
    )


def load_yaml(path: Path, node_name: str, specs: Sequence[Param]) -> dict[str, Any]:
    """Validated parameters of ``node_name`` from a ROS parameter file (``ros__parameters``)."""
    return validate_all(specs, file_values(path, node_name))


def _flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested YAML maps to dotted ROS names: {imu_noise: {gyro_arw: 1}} -> imu_noise.gyro_arw."""
    flat: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(_flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat
