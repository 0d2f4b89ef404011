"""gnss_ins_common.params: the pure parameter specs shared by nodes and offline tools."""

from __future__ import annotations

import pytest

from gnss_ins_common.params import Param, ParameterValueError, load_yaml, validate, validate_all

SPECS = (
    Param("rate", 5.0, "a rate [Hz]", 0.1, 100.0),
    Param("count", 3, "a count", 1, 10),
    Param("mode", "a", "a mode", choices=("a", "b")),
    Param("flag", True, "a flag"),
    Param(
        "gains", [1.0, 2.0, 3.0], "gains", 0.0, 10.0, check=lambda v: None if len(v) == 3 else "3"
    ),
    Param("names", [], "names"),
    Param("imu_noise.gyro_arw", 0.5, "deg/sqrt(h)", 0.0, 100.0),
    Param("axes", [1.0, 2.0, 3.0], "per axis", 0.0, 10.0, broadcast=True),
)


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("rate", 0.0, "outside"),
        ("rate", "fast", "expected float"),
        ("count", 2.5, "expected int"),
        ("count", True, "expected int"),
        ("mode", "c", "not one of"),
        ("flag", 1, "expected bool"),
        ("gains", [1.0, 20.0, 3.0], "outside"),
        ("gains", [1.0, 2.0], "3"),
        ("gains", 1.0, "expected a list"),
        ("names", [1.0], "expected a list of str"),
        ("rate", float("nan"), "not a finite number"),
        ("rate", float("inf"), "not a finite number"),
        ("gains", [1.0, float("nan"), 3.0], "not a finite number"),
        ("axes", [1.0, float("-inf"), 3.0], "not a finite number"),
        ("axes", float("nan"), "not a finite number"),
        ("axes", 20.0, "outside"),
        ("axes", "1.0", "expected a list"),
    ],
)
def test_bad_values_name_the_parameter(name, value, message):
    spec = next(s for s in SPECS if s.name == name)
    with pytest.raises(ParameterValueError, match=f"parameter '{name}'.*{message}"):
        validate(spec, value)


def test_ints_are_widened_where_floats_are_expected():
    assert validate(SPECS[0], 7) == 7.0 and isinstance(validate(SPECS[0], 7), float)
    assert validate(SPECS[4], [1, 2, 3]) == [1.0, 2.0, 3.0]
    assert validate(SPECS[5], []) == []


def test_a_broadcast_list_takes_one_number_for_every_element():
    spec = next(s for s in SPECS if s.name == "axes")
    assert validate(spec, 0.3) == [0.3, 0.3, 0.3]
    assert validate(spec, 2) == [2.0, 2.0, 2.0]
    assert validate(spec, [1, 2, 3]) == [1.0, 2.0, 3.0]


def test_validate_all_fills_defaults_and_rejects_unknown_names():
    values = validate_all(SPECS, {"rate": 10})
    assert values["rate"] == 10.0 and values["mode"] == "a" and values["gains"] == [1.0, 2.0, 3.0]
    with pytest.raises(ParameterValueError, match="unknown parameter"):
        validate_all(SPECS, {"rat": 1.0})


def test_load_yaml_reads_a_ros_parameter_file_with_nested_names(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(
        "my_node:\n  ros__parameters:\n    count: 4\n    imu_noise:\n      gyro_arw: 1.5\n"
    )
    values = load_yaml(path, "my_node", SPECS)
    assert values["count"] == 4 and values["imu_noise.gyro_arw"] == 1.5
    path.write_text("my_node:\n  ros__parameters:\n    count: 40\n")
    with pytest.raises(ParameterValueError, match="count"):
        load_yaml(path, "my_node", SPECS)
    with pytest.raises(ParameterValueError, match="cannot read"):
        load_yaml(tmp_path / "missing.yaml", "my_node", SPECS)


def test_load_yaml_reads_a_wildcard_section(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("/**:\n  ros__parameters:\n    count: 7\n")
    assert load_yaml(path, "any_node", SPECS)["count"] == 7


def _node_specs() -> list[Param]:
    from gnss_driver.node import PARAMETERS as GNSS
    from imu400cc_driver.node import PARAMETERS as IMU
    from ins_fusion.core.settings.params import PARAMETERS as FUSION

    return [*IMU, *GNSS, *FUSION]


def _non_finite_variants(spec: Param) -> list[object]:
    """``spec``'s value with a NaN / an infinity in each number (none for non-numeric specs)."""
    default = spec.default
    if isinstance(default, float):
        return [float("nan"), float("inf"), float("-inf")]
    if isinstance(default, list) and (
        (default and isinstance(default[0], float))
        or (not default and spec.empty_list_of == "float")
    ):
        base = list(default) or [0.0, 0.0, 0.0]
        return [[bad, *base[1:]] for bad in (float("nan"), float("inf"))]
    return []


@pytest.mark.parametrize(
    "spec", [s for s in _node_specs() if _non_finite_variants(s)], ids=lambda s: s.name
)
def test_every_numeric_node_parameter_refuses_nan_and_inf(spec):
    for value in _non_finite_variants(spec):
        with pytest.raises(ParameterValueError, match=f"parameter '{spec.name}'"):
            validate(spec, value)


@pytest.mark.parametrize(
    "spec",
    [s for s in _node_specs() if s.name == "frame_id" or s.name.endswith("_frame")],
    ids=lambda s: s.name,
)
@pytest.mark.parametrize("value", ["", "  ", "imu link"])
def test_frame_names_must_be_non_empty_without_spaces(spec, value):
    if value == "" and spec.default == "":  # an optional frame: empty = none
        assert validate(spec, value) == ""
        return
    with pytest.raises(ParameterValueError, match=f"parameter '{spec.name}'.*frame name"):
        validate(spec, value)


def test_load_yaml_refuses_a_file_without_the_node_section(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("other_node:\n  ros__parameters:\n    count: 7\n")
    with pytest.raises(ParameterValueError, match=r"no section for my_node \(top keys: other"):
        load_yaml(path, "my_node", SPECS)
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ParameterValueError, match="must be a mapping of node names"):
        load_yaml(path, "my_node", SPECS)
    path.write_text("")
    assert load_yaml(path, "my_node", SPECS)["count"] == validate_all(SPECS, {})["count"]
