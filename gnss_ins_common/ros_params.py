"""Declaring ``gnss_ins_common.params.Param`` specs as ROS parameters.

``declare_parameters`` declares each spec with a ParameterDescriptor (description, numeric range,
allowed values; read-only, as the nodes read them once at start-up) and returns the validated
values, raising ``ParameterValueError`` with a message naming the parameter on any bad value, so a
node refuses to start instead of running with nonsense.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from gnss_ins_common.params import Param, ParameterValueError, validate

_EMPTY_LIST_TYPES = {"str": Parameter.Type.STRING_ARRAY, "float": Parameter.Type.DOUBLE_ARRAY}


def descriptor(spec: Param) -> ParameterDescriptor:
    """The ROS descriptor carrying the description and the range/choices of ``spec``."""
    constraints = []
    if spec.choices:
        constraints.append("one of: " + ", ".join(spec.choices))
    if spec.low is not None or spec.high is not None:
        constraints.append(f"range [{spec.low}, {spec.high}]")
    result = ParameterDescriptor(
        description=spec.description,
        additional_constraints="; ".join(constraints),
        read_only=True,
        # A broadcast list also takes one number (validate() expands it).
        dynamic_typing=spec.broadcast,
    )
    if spec.low is not None and spec.high is not None:
        if isinstance(spec.default, float):
            result.floating_point_range = [
                FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high))
            ]
        elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
            result.integer_range = [
                IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)
            ]
    return result


def declare_parameters(node: Node, specs: Sequence[Param]) -> dict[str, Any]:
    """Declare every spec on ``node`` and return {name: validated value}."""
    values: dict[str, Any] = {}
    for spec in specs:
        default: Any = spec.default
        if isinstance(default, list) and not default:
            default = _EMPTY_LIST_TYPES[spec.empty_list_of]
        try:
            value = node.declare_parameter(spec.name, default, descriptor(spec)).value
        except (
            InvalidParameterValueException,
            InvalidParameterTypeException,
            ParameterException,
        ) as exc:
            raise ParameterValueError(
                f"parameter '{spec.name}': {exc} ({spec.description})"
            ) from exc
        if value is None:  # an empty-list parameter nobody set
            value = []
        values[spec.name] = validate(spec, list(value) if _is_sequence(value) else value)
    return values


def _is_sequence(value: Any) -> bool:
    return not isinstance(value, str) and hasattr(value, "__len__")
