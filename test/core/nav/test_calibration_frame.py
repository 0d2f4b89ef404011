"""The shipped IMU400CC calibration is in the unit's own axes (Aalborg report §5.6 tables, per
device axis) and is carried into imu_link by the driver's axis map and accelerometer sign
(issue 14 item 1). Numbers are the report's printed values, not read from our files."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.paths import REPO

from gnss_ins_common.axes import AxisMap
from imu400cc_driver.axes import DEFAULT_ACCEL_SIGN, DEFAULT_AXIS_SPEC
from ins_fusion.core.nav.calibration import CalibrationError, ImuCalibration
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2, deg_s, mg
from ins_fusion.sim.imu_model import IMU400CC

CONFIG = REPO / "config" / "imu400cc_calibration.yaml"
DRIVER = AxisMap.from_spec(DEFAULT_AXIS_SPEC)
#: Report Fig. 5-36 (gyro S2 bias, °/s) and Fig. 5-34 (accelerometer S2 bias, mg), device axes.
GYRO_BIAS_DEG_S = (0.0246, -0.0343, -0.0153)
ACCEL_BIAS_MG = (5.4, -3.1, 7.1)
#: Report Fig. 5-30 (gyro D2 at ±15 °/s), scale factor error for positive / negative input, %.
GYRO_SCALE_POS = (0.0921, 0.8286, 0.2637)
GYRO_SCALE_NEG = (-0.1304, -0.8199, -0.1811)


def _driver_rate(device_deg_s: np.ndarray) -> tuple[float, float, float]:
    """imu400cc_node's conversion of a device rate reading [°/s] to imu_link [rad/s]."""
    flu = DRIVER.to_flu(np.radians(device_deg_s))
    return (float(flu[0]), float(flu[1]), float(flu[2]))


def _driver_force(device_g: np.ndarray) -> tuple[float, float, float]:
    flu = DRIVER.to_flu(device_g) * DEFAULT_ACCEL_SIGN * STANDARD_GRAVITY_M_S2
    return (float(flu[0]), float(flu[1]), float(flu[2]))


def test_a_unit_reading_the_report_biases_is_corrected_to_zero() -> None:
    calibration = ImuCalibration.from_yaml(CONFIG)
    rate, force = calibration.correct(
        _driver_rate(np.array(GYRO_BIAS_DEG_S)), _driver_force(np.array(ACCEL_BIAS_MG) * 1e-3)
    )
    assert rate == pytest.approx((0.0, 0.0, 0.0), abs=deg_s(1e-9))
    assert force == pytest.approx((0.0, 0.0, 0.0), abs=mg(1e-9))


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("rate_deg_s", [15.0, -15.0])
def test_gyro_scale_factor_of_the_input_sign_is_removed(axis: int, rate_deg_s: float) -> None:
    """A device input of ±15 °/s reads (1 + S±) times it plus the bias; the FLU axis reading
    minus it (y, z) must take the device's own S± (the ones printed for its input sign)."""
    true_device = np.zeros(3)
    true_device[axis] = rate_deg_s
    scale = (GYRO_SCALE_POS if rate_deg_s > 0 else GYRO_SCALE_NEG)[axis] / 100.0
    reading = true_device * (1.0 + scale * (np.arange(3) == axis)) + np.array(GYRO_BIAS_DEG_S)
    calibration = ImuCalibration.from_yaml(CONFIG)
    rate, _ = calibration.correct(_driver_rate(reading), (0.0, 0.0, STANDARD_GRAVITY_M_S2))
    assert rate == pytest.approx(_driver_rate(true_device), abs=deg_s(1e-9))


def test_the_simulated_imu400cc_has_the_errors_the_calibration_removes() -> None:
    """The simulator's profile and the shipped file carry the same device values into FLU."""
    calibration = ImuCalibration.from_yaml(CONFIG)
    for triad, errors in ((calibration.gyro, IMU400CC.gyro), (calibration.accel, IMU400CC.accel)):
        assert triad.bias == pytest.approx(errors.bias, abs=1e-15)
        assert triad.scale_positive == pytest.approx(errors.scale_pos, abs=1e-15)
        assert triad.scale_negative == pytest.approx(errors.scale_neg, abs=1e-15)
    assert np.array(IMU400CC.gyro.bias) == pytest.approx(
        [deg_s(0.0246), deg_s(0.0343), deg_s(0.0153)]
    )
    assert np.array(IMU400CC.accel.bias) == pytest.approx([-mg(5.4), -mg(3.1), mg(7.1)])


SPECS = st.permutations(["x", "y", "z"]).flatmap(
    lambda axes: st.tuples(*(st.sampled_from(["", "-"]).map(lambda s, a=a: s + a) for a in axes))
)


@given(
    spec=SPECS,
    sign=st.sampled_from([1.0, -1.0]),
    device=st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3),
)
def test_device_axes_calibration_inverts_any_driver_mapping(
    spec: tuple[str, str, str], sign: float, device: list[float]
) -> None:
    """For any signed axis map and accelerometer sign, a device-axis calibration applied in
    imu_link recovers the true specific force from the mapped device reading."""
    axes = AxisMap.from_spec(spec)
    section = {
        "axes": "device",
        "device_axes": list(spec),
        "device_accel_sign": int(sign),
        "accel": {
            "bias_mg": [5.4, -3.1, 7.1],
            "scale_positive_percent": [0.0652, 0.0309, -0.0202],
            "scale_negative_percent": [0.0172, 0.0340, 0.0846],
            "misalignment_mrad": [[0.0, 1.0, -2.0], [0.5, 0.0, 1.5], [-1.0, 2.0, 0.0]],
        },
    }
    calibration = ImuCalibration.from_mapping(section)
    true = np.array(device)
    scale = np.where(true >= 0, [0.0652, 0.0309, -0.0202], [0.0172, 0.0340, 0.0846]) / 100.0
    mis = np.array([[0.0, 1.0, -2.0], [0.5, 0.0, 1.5], [-1.0, 2.0, 0.0]]) * 1e-3
    reading = (np.eye(3) + np.diag(scale) + mis) @ true + np.array([5.4, -3.1, 7.1]) * 1e-3
    flu_reading = sign * axes.to_flu(reading) * STANDARD_GRAVITY_M_S2
    _, force = calibration.correct((0.0, 0.0, 0.0), tuple(flu_reading))
    expected = sign * axes.to_flu(true) * STANDARD_GRAVITY_M_S2
    assert np.array(force) == pytest.approx(expected, abs=1e-3 * abs(true).max() + 1e-9)


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ({"axes": "device"}, "needs device_axes"),
        ({"axes": "device", "device_axes": ["x", "y", "z"], "device_accel_sign": 2}, "needs"),
        ({"axes": "device", "device_axes": ["x", "x", "z"], "device_accel_sign": -1}, "once"),
        ({"axes": "body"}, "'imu_link' or 'device'"),
        ({"device_axes": ["x", "-y", "-z"]}, "needs 'axes: device'"),
    ],
)
def test_bad_axes_keys_are_refused(section: dict[str, object], message: str) -> None:
    with pytest.raises(CalibrationError, match=message):
        ImuCalibration.from_mapping(section)
