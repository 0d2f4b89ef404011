"""Parameter settings from the command line, checked with the node's own Param specs.

``name=value`` (``--set``) and ``name=v1,v2,...`` (``--sweep``). A value is read as YAML, the
way it would be written in config/ins_fusion.yaml (``1.5``, ``true``, ``[0.1, 0.2, 0.3]``);
string parameters take the text as it is. Sweep values are separated by commas outside
brackets, so list values work: ``imu_lever_arm=[0.8,0,1.6],[0.9,0,1.6]``. Each value is
validated with gnss_ins_common.params.validate against ins_fusion.core.settings.params.PARAMETERS,
so the replay tool refuses exactly what ins_fusion_node refuses, with the same message.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import yaml

from gnss_ins_common.params import Param, ParameterValueError, validate, validate_all
from ins_fusion.core.settings.params import PARAMETERS

SPECS: dict[str, Param] = {spec.name: spec for spec in PARAMETERS}


def _spec(name: str) -> Param:
    spec = SPECS.get(name)
    if spec is None:
        raise ParameterValueError(f"unknown parameter '{name}' (docs/parameters.md lists them)")
    return spec


def _split_assignment(text: str) -> tuple[str, str]:
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise ParameterValueError(f"{text!r} is not name=value")
    return name.strip(), value.strip()


def parse_value(spec: Param, text: str) -> Any:
    """One value of a parameter from its text, validated (ParameterValueError if bad)."""
    if isinstance(spec.default, str):
        return validate(spec, text)
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        raise ParameterValueError(f"parameter '{spec.name}': cannot read {text!r}") from None
    return validate(spec, value)


def parse_setting(text: str) -> tuple[str, Any]:
    """``name=value`` -> (name, validated value)."""
    name, value = _split_assignment(text)
    return name, parse_value(_spec(name), value)


def _split_top_level(text: str) -> list[str]:
    """Split on commas that are not inside brackets."""
    items: list[str] = []
    current: list[str] = []
    depth = 0
    for char in text:
        depth += {"[": 1, "]": -1}.get(char, 0)
        if char == "," and depth == 0:
            items.append("".join(current))
            current = []
        else:
            current.append(char)
    items.append("".join(current))
    return [item.strip() for item in items]


def parse_sweep(text: str) -> tuple[str, list[Any]]:
    """``name=v1,v2,...`` -> (name, validated values); at least one value, no duplicates."""
    name, values_text = _split_assignment(text)
    spec = _spec(name)
    values = [parse_value(spec, item) for item in _split_top_level(values_text)]
    if any(values[i] in values[:i] for i in range(len(values))):
        raise ParameterValueError(f"sweep of '{name}' repeats a value")
    return name, values


def grid(sweeps: Sequence[tuple[str, list[Any]]]) -> list[dict[str, Any]]:
    """Every combination of the swept values (first sweep varies slowest)."""
    names = [name for name, _ in sweeps]
    if len(set(names)) != len(names):
        raise ParameterValueError("a parameter is swept twice")
    return [
        dict(zip(names, combination, strict=True))
        for combination in itertools.product(*(values for _, values in sweeps))
    ]


def changed_parameters(parameters: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters (validated, defaults filled in) whose values differ from the defaults."""
    values, defaults = validate_all(PARAMETERS, parameters), validate_all(PARAMETERS, {})
    return {name: value for name, value in values.items() if value != defaults[name]}
