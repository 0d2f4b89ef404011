"""Axis maps and counts <-> imu_link (FLU, SI) conversion.

Device model under test (notes §1.4, §12 items 1-2): FRD axes, right-hand-rule rates, and an
accelerometer that reports the direction of gravity (+1 g on z when level and at rest, App. D.5),
i.e. minus the specific force. REP-145 wants (0, 0, +9.81) m/s^2 for a level unit at rest.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from support.imu_strategies import raw_packets

from gnss_ins_common.axes import AxisMap
from imu400cc_driver.axes import (
    DEFAULT_ACCEL_SIGN,
    DEFAULT_AXIS_SPEC,
    STANDARD_GRAVITY_M_S2,
    PacketConverter,
    measurement_to_packet,
)
from imu400cc_driver.protocol import RawPacket, Scaling

G = STANDARD_GRAVITY_M_S2
SCALING = Scaling()
DEFAULT_MAP = AxisMap.from_spec(DEFAULT_AXIS_SPEC)
ACCEL_COUNT_M_S2 = float(SCALING.accel_g(1)) * G  # one accelerometer count [m/s^2]
#: Frame changes, both proper rotations: FRD -> FLU body and NED -> ENU world.
FLU_FROM_FRD = np.diag([1.0, -1.0, -1.0])
ENU_FROM_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _device_packet(gravity_direction_frd_g, rates_frd_dps=(0.0, 0.0, 0.0)) -> RawPacket:
    """What the device sends for a gravity direction (in g) and rates in its own FRD axes."""
    accels = SCALING.accel_counts(gravity_direction_frd_g).counts.tolist()
    rates = SCALING.rate_counts(rates_frd_dps).counts.tolist()
    return RawPacket(tuple(rates), tuple(accels), 1514, 0)  # type: ignore[arg-type]


def _measure(raw: RawPacket, accel_sign: float = DEFAULT_ACCEL_SIGN):
    return PacketConverter(SCALING, DEFAULT_MAP, accel_sign)(raw)


def test_defaults_are_the_frd_device():
    assert DEFAULT_AXIS_SPEC == ("x", "-y", "-z")
    assert DEFAULT_ACCEL_SIGN == -1.0
    np.testing.assert_array_equal(DEFAULT_MAP.matrix, FLU_FROM_FRD)
    assert DEFAULT_MAP.proper


def test_level_resting_device_reads_plus_g_on_z():
    m = _measure(_device_packet((0.0, 0.0, 1.0)))
    np.testing.assert_allclose(m.specific_force_flu_m_s2, [0.0, 0.0, G], atol=ACCEL_COUNT_M_S2)
    np.testing.assert_array_equal(m.rate_flu_rad_s, [0.0, 0.0, 0.0])


def test_golden_row_1_reads_plus_g_on_z():
    raw = RawPacket((18, 12, -40), (-5, 182, 11233), 1514, 41606)
    m = _measure(raw)
    assert m.specific_force_flu_m_s2[2] == pytest.approx(1.028411865 * G, abs=1e-8)
    assert m.temperature_c == pytest.approx(21.027, abs=5e-4)
    assert m.timer == 41606
    np.testing.assert_allclose(
        m.rate_flu_rad_s, np.radians([0.082397461, -0.054931641, 0.183105469]), atol=1e-11
    )


def test_accel_sign_plus_one_takes_the_device_output_as_specific_force():
    m = _measure(_device_packet((0.0, 0.0, 1.0)), accel_sign=1.0)
    np.testing.assert_allclose(m.specific_force_flu_m_s2, [0.0, 0.0, -G], atol=ACCEL_COUNT_M_S2)


@pytest.mark.parametrize("degrees", [5.0, 30.0, 80.0])
def test_nose_up_tilt_gives_positive_x(degrees):
    theta = math.radians(degrees)
    # Nose up: the device's forward axis points partly against gravity.
    m = _measure(_device_packet((-math.sin(theta), 0.0, math.cos(theta))))
    expected = [G * math.sin(theta), 0.0, G * math.cos(theta)]
    np.testing.assert_allclose(m.specific_force_flu_m_s2, expected, atol=ACCEL_COUNT_M_S2)


def test_right_side_down_bank_gives_positive_y():
    phi = math.radians(20.0)
    # Right side down (positive bank, §7.4): the device's right axis points partly along gravity.
    m = _measure(_device_packet((0.0, math.sin(phi), math.cos(phi))))
    expected = [0.0, G * math.sin(phi), G * math.cos(phi)]
    np.testing.assert_allclose(m.specific_force_flu_m_s2, expected, atol=ACCEL_COUNT_M_S2)


@pytest.mark.parametrize("accel_sign", [1.0, -1.0])
def test_rates_follow_the_right_hand_rule_about_flu_axes(accel_sign):
    # Device: roll right, pitch nose up, yaw to the right (all positive about FRD axes).
    m = _measure(_device_packet((0.0, 0.0, 1.0), (10.0, 10.0, 10.0)), accel_sign)
    step = float(SCALING.rate_dps(SCALING.rate_counts(10.0).counts))
    # FLU: roll right is +x; nose up and yaw right are negative about +y (left) and +z (up).
    np.testing.assert_allclose(m.rate_flu_rad_s, np.radians([step, -step, -step]), atol=1e-12)


@given(
    st.tuples(*[st.floats(-math.pi, math.pi)] * 3),
    st.tuples(*[st.floats(-1.0, 1.0)] * 3),
)
def test_any_attitude_matches_an_independent_frame_chain(euler_zyx, omega_ned_rad_s):
    """Device in any attitude at rest on a turning platform, worked out in NED/FRD, compared with
    the same physics worked out directly in ENU/FLU."""
    ned_from_frd = Rotation.from_euler("ZYX", euler_zyx).as_matrix()
    omega_ned = np.asarray(omega_ned_rad_s)
    device_gravity_g = ned_from_frd.T @ [0.0, 0.0, 1.0]  # device reads the gravity direction
    device_rate_dps = np.degrees(ned_from_frd.T @ omega_ned)
    raw = RawPacket(
        tuple(SCALING.rate_counts(device_rate_dps).counts.tolist()),  # type: ignore[arg-type]
        tuple(SCALING.accel_counts(device_gravity_g).counts.tolist()),  # type: ignore[arg-type]
        0,
        0,
    )
    m = _measure(raw)
    enu_from_flu = ENU_FROM_NED @ ned_from_frd @ FLU_FROM_FRD.T
    expected_force = enu_from_flu.T @ [0.0, 0.0, G]  # specific force at rest: up in ENU
    expected_rate = enu_from_flu.T @ (ENU_FROM_NED @ omega_ned)
    np.testing.assert_allclose(m.specific_force_flu_m_s2, expected_force, atol=ACCEL_COUNT_M_S2)
    np.testing.assert_allclose(m.rate_flu_rad_s, expected_rate, atol=math.radians(0.005))


@pytest.mark.parametrize(
    "spec",
    [
        ["x", "y"],
        ["x", "y", "z", "x"],
        ["x", "x", "z"],
        ["x", "-x", "z"],
        ["x", "y", "w"],
        ["+-x", "y", "z"],
        ["x", "y", "--z"],
        ["x", "y", ""],
        ["x", "y", "z1"],
        "xyz",
        [],
    ],
)
def test_bad_specs_are_rejected(spec):
    with pytest.raises(ValueError, match="axis spec"):
        AxisMap.from_spec(spec)


def test_spec_terms_may_be_signed_spaced_and_upper_case():
    axis_map = AxisMap.from_spec(["+X", " -z ", "y"])
    assert axis_map.spec == ("x", "-z", "y")
    assert axis_map.indices == (0, 2, 1)
    assert axis_map.signs == (1.0, -1.0, 1.0)


def test_direct_construction_is_validated():
    with pytest.raises(ValueError, match="signed permutation"):
        AxisMap((0, 0, 2), (1.0, 1.0, 1.0))
    with pytest.raises(ValueError, match="signed permutation"):
        AxisMap((0, 1, 2), (1.0, 2.0, 1.0))


ALL_SPECS = [
    [sign + axis for sign, axis in zip(signs, perm, strict=True)]
    for perm in itertools.permutations("xyz")
    for signs in itertools.product(["", "-"], repeat=3)
]


@pytest.mark.parametrize("spec", ALL_SPECS, ids=lambda s: ",".join(s))
def test_every_signed_permutation(spec):
    axis_map = AxisMap.from_spec(spec)
    assert list(axis_map.spec) == spec
    matrix = axis_map.matrix
    np.testing.assert_array_equal(matrix @ matrix.T, np.eye(3))
    assert axis_map.proper == (np.linalg.det(matrix) > 0)
    vectors = np.arange(12.0).reshape(4, 3) - 5.0
    np.testing.assert_array_equal(axis_map.to_flu(vectors), vectors @ matrix.T)
    np.testing.assert_array_equal(axis_map.from_flu(axis_map.to_flu(vectors)), vectors)
    for i, term in enumerate(spec):  # spec[i] names the device axis that is FLU axis i
        device = np.zeros(3)
        device["xyz".index(term[-1])] = 1.0
        assert axis_map.to_flu(device)[i] == (-1.0 if term.startswith("-") else 1.0)


def test_half_of_the_signed_permutations_are_rotations():
    assert sum(AxisMap.from_spec(s).proper for s in ALL_SPECS) == 24


def test_vector_shape_is_checked():
    with pytest.raises(ValueError, match="3-vectors"):
        DEFAULT_MAP.to_flu([1.0, 2.0])
    with pytest.raises(ValueError, match="3-vectors"):
        DEFAULT_MAP.from_flu(1.0)


@given(raw_packets, st.sampled_from(ALL_SPECS), st.sampled_from([1.0, -1.0]))
def test_measurement_to_packet_inverts_the_packet_conversion(raw, spec, accel_sign):
    axis_map = AxisMap.from_spec(spec)
    m = PacketConverter(SCALING, axis_map, accel_sign, 9.81)(raw)
    back = measurement_to_packet(
        m.rate_flu_rad_s,
        m.specific_force_flu_m_s2,
        m.temperature_c,
        m.timer,
        SCALING,
        axis_map,
        accel_sign,
        9.81,
    )
    assert back == raw


def test_measurement_to_packet_of_a_resting_level_unit():
    raw = measurement_to_packet(
        [0.0, 0.0, 0.0], [0.0, 0.0, G], 21.027, 41606, SCALING, DEFAULT_MAP, -1.0
    )
    assert raw == RawPacket((0, 0, 0), (0, 0, 10923), 1514, 41606)


def test_measurement_to_packet_saturates():
    raw = measurement_to_packet(
        [10.0, 0.0, -10.0], [0.0, -100.0, G], 25.0, 0, SCALING, DEFAULT_MAP, -1.0
    )
    assert raw.rates == (32767, 0, 32767)
    assert raw.accels == (0, -32768, 10923)


def test_measurement_to_packet_checks_its_inputs():
    args = (25.0, 0, SCALING, DEFAULT_MAP)
    with pytest.raises(ValueError, match="rate_flu_rad_s"):
        measurement_to_packet([0.0, 0.0], [0.0, 0.0, G], *args, -1.0)
    with pytest.raises(ValueError, match="specific_force_flu_m_s2"):
        measurement_to_packet([0.0, 0.0, 0.0], np.zeros((2, 3)), *args, -1.0)
    with pytest.raises(ValueError, match="accel_sign"):
        measurement_to_packet([0.0, 0.0, 0.0], [0.0, 0.0, G], *args, 0.5)
    with pytest.raises(ValueError, match="gravity"):
        measurement_to_packet([0.0, 0.0, 0.0], [0.0, 0.0, G], *args, -1.0, 0.0)


@pytest.mark.parametrize("accel_sign", [0.0, 2.0, math.nan])
def test_packet_conversion_rejects_bad_accel_sign(accel_sign):
    with pytest.raises(ValueError, match="accel_sign"):
        PacketConverter(SCALING, DEFAULT_MAP, accel_sign)


@pytest.mark.parametrize("spec", ALL_SPECS, ids=lambda s: ",".join(s))
@pytest.mark.parametrize("scaling", [SCALING, Scaling(gyro_range_dps=300.0, accel_range_g=1.7)])
def test_packet_conversion_is_the_element_wise_one_to_the_bit(spec, scaling):
    """PacketConverter against Scaling and AxisMap on arrays: every count of each field on the
    default axes, every 61st on the others (the axes only move and sign whole values)."""
    axis_map = AxisMap.from_spec(spec)
    counts = np.arange(-(2**15), 2**15)[:: 1 if axis_map == DEFAULT_MAP else 61]
    rates = np.stack([counts, np.roll(counts, 1), np.roll(counts, 2)], axis=1)
    accels = np.stack([np.roll(counts, 3), counts[::-1], np.roll(counts, 5)], axis=1)
    temperatures = counts + 2**15
    expected_rate = axis_map.to_flu(np.radians(scaling.rate_dps(rates)))
    expected_celsius = scaling.temperature_c(temperatures)
    for accel_sign, gravity in ((-1.0, G), (1.0, 9.81)):
        convert = PacketConverter(scaling, axis_map, accel_sign, gravity)
        measurements = [
            convert(RawPacket(tuple(w), tuple(a), t, 7))  # type: ignore[arg-type]
            for w, a, t in zip(rates.tolist(), accels.tolist(), temperatures.tolist(), strict=True)
        ]
        expected_force = axis_map.to_flu(scaling.accel_g(accels)) * accel_sign * gravity
        rate = np.array([m.rate_flu_rad_s for m in measurements])
        force = np.array([m.specific_force_flu_m_s2 for m in measurements])
        celsius = np.array([m.temperature_c for m in measurements])
        assert rate.tobytes() == expected_rate.tobytes()
        assert force.tobytes() == expected_force.tobytes()
        assert celsius.tobytes() == expected_celsius.tobytes()
