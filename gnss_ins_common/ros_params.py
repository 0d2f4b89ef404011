"""Declared, described and range-checked ROS parameters for the gnss_ins nodes.

A node lists its parameters as ``Param`` specs; ``declare_parameters`` declares each with a
ParameterDescriptor (description, numeric range, allowed values) and returns the validated
values, raising ``ParameterValueError`` with a message naming the parameter on any bad value, so
a node refuses to start instead of running with nonsense. The same specs are the single source
of the defaults that config/*.yaml and docs/parameters.md repeat (a test checks they agree).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

ParamValue = bool | int | float | str | list[str] | list[float] | list[int]


class ParameterValueError(ValueError):
    """A parameter given to a node is out of range, of the wrong type or not allowed."""


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
    #: ROS type for list parameters whose default is empty (the type cannot be inferred).
    empty_list_type: Parameter.Type = Parameter.Type.STRING_ARRAY

    def descriptor(self) -> ParameterDescriptor:
        """The ROS descriptor carrying the description and the range/choices."""
        constraints = []
        if self.choices:
            constraints.append("one of: " + ", ".join(self.choices))
        if self.low is not None or self.high is not None:
            constraints.append(f"range [{self.low}, {self.high}]")
        descriptor = ParameterDescriptor(
            description=self.description,
            additional_constraints="; ".join(constraints),
            read_only=True,
        )
        scalar_range = self.low is not None and self.high is not None
        if scalar_range and isinstance(self.default, float):
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(self.low), to_value=float(self.high))
            ]
        elif scalar_range and isinstance(self.default, int) and not isinstance(self.default, bool):
            descriptor.integer_range = [
                IntegerRange(from_value=int(self.low or 0), to_value=int(self.high or 0), step=1)
            ]
        return descriptor


def _range_error(spec: Param, value: Any) -> str | None:
    """Range check for list values (ROS ranges only cover scalars)."""
    if not isinstance(value, list) or (spec.low is None and spec.high is None):
        return None
    for item in value:
        if isinstance(item, str):
            continue
        too_low = spec.low is not None and item < spec.low
        if too_low or (spec.high is not None and item > spec.high):
            return f"element {item} outside [{spec.low}, {spec.high}]"
    return None


def declare_parameters(node: Node, specs: Sequence[Param]) -> dict[str, Any]:
    """Declare every spec on ``node`` and return {name: validated value}."""
    values: dict[str, Any] = {}
    for spec in specs:
        default: Any = spec.default
        if isinstance(default, list) and not default:
            default = spec.empty_list_type
        try:
            value = node.declare_parameter(spec.name, default, spec.descriptor()).value
        except (
            InvalidParameterValueException,
            InvalidParameterTypeException,
            ParameterException,
        ) as exc:
            raise ParameterValueError(
                f"parameter '{spec.name}': {exc} ({spec.description})"
            ) from exc
        if value is None:
            value = list(spec.default) if isinstance(spec.default, list) else spec.default
        elif isinstance(value, tuple | list) or type(value).__name__ == "ndarray":
            value = list(value)
        problem = None
        if spec.choices and value not in spec.choices:
            problem = f"'{value}' is not one of {', '.join(spec.choices)}"
        problem = problem or _range_error(spec, value)
        if problem is None and spec.check is not None:
            problem = spec.check(value)
        if problem:
            raise ParameterValueError(f"parameter '{spec.name}': {problem} ({spec.description})")
        values[spec.name] = value
    return values
