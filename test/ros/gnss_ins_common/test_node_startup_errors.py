"""Node executables refuse missing or malformed parameter and calibration files with a one-line
reason and exit code 2, never a traceback (real executables, real files)."""

from __future__ import annotations

import subprocess

import pytest
from support.ros_harness import node_executable

pytestmark = pytest.mark.ros

NODES = ("imu400cc_node", "gnss_node", "ins_fusion_node")
#: File contents that are not a usable parameter file, and a fragment of the reason given.
BAD_FILES = {
    "yaml_syntax": ("{node}:\n  ros__parameters:\n    port: [unclosed\n", "line 3"),
    "not_a_mapping": ("- just\n- a list\n", "must be a mapping"),
    "parameters_not_a_mapping": ("{node}:\n  ros__parameters: 5\n", "ros__parameters"),
    # Well-formed YAML that rcl refuses (mixed array): its own message, without a traceback.
    "mixed_array": ("{node}:\n  ros__parameters:\n    names: [1, a]\n", "same type"),
}


def _refused(name: str, *ros_args: str) -> str:
    result = subprocess.run(
        [node_executable(name), "--ros-args", *ros_args],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert "Traceback" not in result.stderr, result.stderr
    assert result.returncode == 2, result.stderr
    return result.stderr


@pytest.mark.parametrize("name", NODES)
def test_a_missing_parameter_file_is_refused(name, tmp_path):
    missing = tmp_path / "nowhere.yaml"
    stderr = _refused(name, "--params-file", str(missing))
    assert f"cannot read parameter file {missing}" in stderr


@pytest.mark.parametrize(
    ("name", "kind"),
    [(name, "yaml_syntax") for name in NODES]
    + [("imu400cc_node", kind) for kind in sorted(BAD_FILES) if kind != "yaml_syntax"],
)
def test_a_malformed_parameter_file_is_refused(name, kind, tmp_path):
    text, fragment = BAD_FILES[kind]
    path = tmp_path / f"{kind}.yaml"
    path.write_text(text.format(node=name))
    stderr = _refused(name, "--params-file", str(path))
    assert str(path) in stderr
    assert fragment in stderr


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        (None, "cannot read calibration file"),
        ("imu_calibration:\n  gyro: [1, 2\n", "cannot read calibration file"),
        ("imu_calibration:\n  gyro: 5\n", "'gyro' must be a mapping"),
        ("other: 1\n", "no 'imu_calibration' section"),
        ("imu_calibration:\n  accel:\n    bias_mg: [1, .nan, 2]\n", "finite numbers"),
    ],
)
def test_a_missing_or_malformed_calibration_file_is_refused(text, fragment, tmp_path):
    path = tmp_path / "calibration.yaml"
    if text is not None:
        path.write_text(text)
    stderr = _refused("ins_fusion_node", "-p", f"calibration_file:={path}")
    assert "parameter 'calibration_file'" in stderr
    assert fragment in stderr
