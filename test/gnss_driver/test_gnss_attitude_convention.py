"""ADU5 angle conventions (issue 14 item 2): the default is the geometric reading of an attitude
receiver's angles, the report's fixed-axes reading (Aalborg §7.5) is a parameter. Numbers are
the report's (calibrated antenna vectors on the car, App. F) and the issue's example."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from gnss_driver.attitude import (
    ANGLE_CONVENTIONS,
    AttitudeConfig,
    AttitudeConverter,
    brf_angles,
    brf_rotation,
)

#: Calibrated antenna vectors on the report's car, BRF X right, Y forward, Z up [m] (App. F).
V12 = np.array([0.000, 3.939, 0.000])
V13 = np.array([-1.172, 4.010, -0.025])


def _elementary(axis: str, angle_deg: float) -> np.ndarray:
    return Rotation.from_euler(axis, angle_deg, degrees=True).as_matrix()


@given(
    heading=st.floats(0.0, 359.9),
    pitch=st.floats(-60.0, 60.0),
    roll=st.floats(-60.0, 60.0),
)
def test_default_heading_and_pitch_are_the_azimuth_and_elevation_of_v12(
    heading: float, pitch: float, roll: float
) -> None:
    v = brf_rotation(heading, pitch, roll).apply(V12)  # ENU
    azimuth = math.degrees(math.atan2(v[0], v[1])) % 360.0  # clockwise from north
    elevation = math.degrees(math.asin(v[2] / np.linalg.norm(v)))
    assert elevation == pytest.approx(pitch, abs=1e-9)
    assert min(abs(azimuth - heading), 360.0 - abs(azimuth - heading)) < 1e-7


def test_report_reading_is_rotation_about_fixed_axes_in_the_order_heading_pitch_roll() -> None:
    """Report §7.5: the ADU frame turns about fixed axes, first φ (Z, clockwise from north),
    then κ (X), then ε (Y): later rotations multiply from the left."""
    heading, pitch, roll = 90.0, 2.0, 3.0
    fixed = _elementary("y", roll) @ _elementary("x", pitch) @ _elementary("z", -heading)
    got = brf_rotation(heading, pitch, roll, "report_fixed_axes").as_matrix()
    assert got == pytest.approx(fixed, abs=1e-12)
    moving = _elementary("z", -heading) @ _elementary("x", pitch) @ _elementary("y", roll)
    assert brf_rotation(heading, pitch, roll).as_matrix() == pytest.approx(moving, abs=1e-12)
    apart = (brf_rotation(heading, pitch, roll).inv() * Rotation.from_matrix(got)).magnitude()
    assert math.degrees(apart) == pytest.approx(5.1, abs=0.05)


def test_report_reading_turns_pitch_into_roll_at_heading_90() -> None:
    """With the fixed-axes reading a 'pitch' at heading 90° tilts the antenna plane about V12
    (east): V12 stays level, V13 leaves the horizontal."""
    rotation = brf_rotation(90.0, 2.0, 0.0, "report_fixed_axes")
    assert rotation.apply(V12)[2] == pytest.approx(0.0, abs=1e-12)
    # Rz(-90°) takes V13 to (y, -x, z) = (4.010, 1.172, -0.025); Rx(2°) lifts its north part.
    expected = -V13[0] * math.sin(math.radians(2.0)) + V13[2] * math.cos(math.radians(2.0))
    assert rotation.apply(V13)[2] == pytest.approx(expected, abs=1e-12)
    assert rotation.apply(V13)[2] - V13[2] > 0.04  # the antenna plane rolled by 2°


@pytest.mark.parametrize("convention", ANGLE_CONVENTIONS)
def test_angles_round_trip_and_offsets_removed_in_either_convention(convention: str) -> None:
    for angles in [(0.0, 0.0, 0.0), (359.5, -12.0, 7.5), (123.4, 45.0, -30.0)]:
        assert brf_angles(brf_rotation(*angles, convention), convention) == pytest.approx(angles)
    # The report's installation offsets (pitch 1.14°, roll -1.48°) on a level car heading north.
    conv = AttitudeConverter(AttitudeConfig(offsets_deg=(0.0, 1.14, -1.48), convention=convention))
    got = Rotation.from_quat(conv.convert(0.0, 1.14, -1.48).quat_enu_flu_xyzw)
    assert (got * Rotation.from_euler("z", 90, degrees=True).inv()).magnitude() < 1e-12


def test_unknown_convention_is_refused() -> None:
    with pytest.raises(ValueError, match="heading_pitch_roll, report_fixed_axes"):
        AttitudeConfig(convention="zyx")
