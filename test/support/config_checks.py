"""The check that a config/*.yaml file holds exactly a node's declared parameters."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import pytest

from gnss_ins_common.params import Param, file_values
from support.paths import CONFIG


def assert_file_holds_defaults(
    name: str, node_name: str, specs: Sequence[Param], differing: Mapping[str, Any] = {}
) -> dict[str, Any]:
    """config/NAME sets every declared parameter, and to its default except for ``differing``
    (values a profile file sets on purpose); returns the file's values."""
    values = file_values(CONFIG / name, node_name)
    declared = {spec.name: spec.default for spec in specs}
    assert values.keys() == declared.keys()
    for key, expected in {**declared, **differing}.items():
        if isinstance(expected, float) or (
            isinstance(expected, list) and expected and isinstance(expected[0], float)
        ):
            assert values[key] == pytest.approx(expected, rel=1e-9), key
        else:
            assert values[key] == expected, key
    return values
