"""Axis/sign mapping of a unit from a six-position record (calibration_id.axes): a unit whose
axes the driver maps differently is detected, and the mapping to configure is found."""

from __future__ import annotations

import pytest

from gnss_ins_common.axes import AxisMap
from imu400cc_driver.axes import DEFAULT_ACCEL_SIGN, DEFAULT_AXIS_SPEC
from ins_fusion.calibration_id import procedures
from ins_fusion.calibration_id.axes import DEFAULT_POSITIONS, check_axes, parse_position
from ins_fusion.calibration_id.lsq import EstimationError
from ins_fusion.calibration_id.model import Site
from ins_fusion.calibration_id.segments import DetectorSettings, detect
from ins_fusion.sim.imu_model import IMU400CC

SITE = Site.at(57.0)
DRIVER = (AxisMap.from_spec(DEFAULT_AXIS_SPEC), DEFAULT_ACCEL_SIGN)
DECLARED = [parse_position(p) for p in DEFAULT_POSITIONS]


def _check(device_spec, device_sign, declared=DECLARED, seed=21):
    device = (AxisMap.from_spec(device_spec), device_sign)
    steps = procedures.six_position(15.0, 4.0)
    record, _ = procedures.simulate(
        steps, IMU400CC, SITE, seed, device_map=device, driver_map=DRIVER
    )
    segments = detect(record, 0, DetectorSettings())
    return check_axes([record], segments, declared, *DRIVER, SITE.gravity_m_s2)


def test_the_driver_defaults_agree_with_a_unit_that_has_them():
    check = _check(DEFAULT_AXIS_SPEC, DEFAULT_ACCEL_SIGN)
    assert check.agrees
    assert check.evidence.startswith("gyro turns")


@pytest.mark.parametrize(
    ("spec", "sign"),
    [
        (["y", "x", "-z"], 1.0),  # mounted rotated: x and y swapped, accelerometer sign +1
        (["-x", "y", "-z"], -1.0),  # turned 180° about z
        (["x", "-y", "-z"], 1.0),  # only the accelerometer sign differs
        (["z", "x", "y"], -1.0),  # a cyclic permutation
    ],
)
def test_a_unit_with_another_mapping_is_detected_and_its_mapping_found(spec, sign):
    check = _check(spec, sign)
    assert not check.agrees
    assert check.found == AxisMap.from_spec(spec)
    assert check.found_accel_sign == sign


def test_a_mirror_image_device_frame_is_told_by_the_gyro_turns():
    check = _check(["x", "y", "-z"], 1.0)  # left-handed: det -1
    assert check.gyro_mirrored
    assert check.found == AxisMap.from_spec(["x", "y", "-z"])
    assert not check.found.proper


def test_positions_in_separate_bags_fall_back_on_handedness():
    device = (AxisMap.from_spec(["y", "x", "-z"]), 1.0)
    records, segments = [], []
    for k, (axis, sign) in enumerate(DECLARED):
        steps = [procedures.Hold(procedures.up_attitude(axis, sign), 15.0)]
        record, _ = procedures.simulate(
            steps, IMU400CC, SITE, 30 + k, device_map=device, driver_map=DRIVER
        )
        records.append(record)
        segments += detect(record, k, DetectorSettings())
    check = check_axes(records, segments, DECLARED, *DRIVER, SITE.gravity_m_s2)
    assert check.evidence.startswith("handedness")
    assert check.found == device[0] and check.found_accel_sign == device[1]


def test_positions_that_contradict_each_other_are_refused():
    declared = list(DECLARED)
    declared[1] = parse_position("+z")  # -z up declared as +z up again
    with pytest.raises(EstimationError, match="contradict"):
        _check(DEFAULT_AXIS_SPEC, DEFAULT_ACCEL_SIGN, declared)


def test_the_number_of_positions_must_match_the_segments():
    with pytest.raises(EstimationError, match=r"6 static segments found .* lists 5"):
        _check(DEFAULT_AXIS_SPEC, DEFAULT_ACCEL_SIGN, DECLARED[:5])


@pytest.mark.parametrize("text", ["+w", "++x", "", "x1"])
def test_bad_position_names(text):
    with pytest.raises(ValueError, match="expected"):
        parse_position(text)
