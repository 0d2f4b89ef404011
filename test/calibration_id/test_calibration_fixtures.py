"""The calibration estimators against numbers published in shared/reference.

- NTNU notes §11 Table 4.7: six mean accelerations of the Q-Free OBU at rest, one axis vertical
  each, give the per-axis offsets and scales of notes §5 / D2 (and of the simulator's profile).
- Aalborg notes §3.3 (report §5.5): readings built with the report's own equations (5.2)/(5.3)
  and (5.9)-(5.18) from its published means give those means back.
- Aalborg notes §4.4 (Fig. 5-10 to 5-14): the predicted accuracies follow from the stated noise
  by the estimators' error propagation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gnss_ins_common.axes import AxisMap
from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id import axes, rotation, static
from ins_fusion.calibration_id.lsq import EstimationError
from ins_fusion.calibration_id.model import BiasInstability, Site
from ins_fusion.calibration_id.result import Quantity
from ins_fusion.calibration_id.segments import Kind, Means, Segment
from ins_fusion.core.nav.earth import EARTH_RATE_RAD_S
from ins_fusion.sim.imu_model import L3G4200D_LIS331DLH

#: Aalborg §5.2.2: g_l^LL = -1.0017 g; its "g" is 9.8 m/s² (notes §10).
AALBORG_G = 1.0017
AALBORG_LAT_DEG = 57.0


def _segment(
    force,
    rate=(0.0, 0.0, 0.0),
    sigma_f=1e-6,
    sigma_w=1e-9,
    t=0.0,
    duration=120.0,
    kind=Kind.STATIC,
    record=0,
):
    means = Means(
        np.array(force, dtype=float),
        np.full(3, sigma_f),
        np.array(rate, dtype=float),
        np.full(3, sigma_w),
    )
    return Segment(record, 0, 2, t, t + duration, kind, means)


def _estimate(result, quantity, written=True):
    return next(e for e in result.estimates if e.quantity is quantity and e.written is written)


def test_ntnu_table_4_7_six_position():
    g = 9.82171  # the thesis' local gravity (NTNU notes §5)
    table = {  # orientation -> mean acceleration [m/s²] on that axis
        ("x", -1): -10.005,
        ("x", 1): 10.047,
        ("y", 1): 10.204,
        ("y", -1): -9.9949,
        ("z", 1): -10.197,
        ("z", -1): 10.163,
    }
    segments = []
    for k, ((axis, _), value) in enumerate(table.items()):
        force = [0.0, 0.0, 0.0]
        force[static.AXES.index(axis)] = value
        segments.append(_segment(force, t=200.0 * k, record=k))  # one bag each
    options = static.StaticOptions(
        Site(math.radians(63.4), g), 0.0, BiasInstability(), static.Scale.SYMMETRIC
    )
    result = static.six_position(segments, options)
    bias = _estimate(result, Quantity.ACCEL_BIAS)
    scale = _estimate(result, Quantity.ACCEL_SCALE_POSITIVE)
    # notes §5 (rounded there): offsets +0.021, +0.1046, -0.017 m/s²; scales 10.026, 10.0995,
    # 10.18 m/s² per g
    np.testing.assert_allclose(bias.value, [0.021, 0.10455, -0.017], atol=1e-9)
    np.testing.assert_allclose((1.0 + scale.value) * g, [10.026, 10.09945, 10.18], atol=1e-9)
    profile = L3G4200D_LIS331DLH.accel  # the simulator's profile of that unit
    np.testing.assert_allclose(bias.value, profile.bias, atol=1e-4)
    np.testing.assert_allclose(scale.value, profile.scale_pos, atol=1e-5)
    # the table's z reads -g when labelled +1 g: the z accelerometer is inverted against x, y
    declared = [axes.parse_position(("+" if s > 0 else "-") + a) for a, s in table]
    check = axes.check_axes([], segments, declared, AxisMap.from_spec(["x", "y", "z"]), 1.0, g)
    np.testing.assert_array_equal(check.accel_matrix, np.diag([1.0, 1.0, -1.0]))
    assert not check.agrees


def _aalborg_accel_readings(bias_g, scale):
    """(5.2)/(5.3) per axis (position 1 up, position 2 down; horizontal axes read B, (5.1));
    in the report's unit g with g_l^LL = -1.0017 g."""
    g_l = -AALBORG_G
    readings = []
    for axis in range(3):
        for up in (True, False):
            f = np.array(bias_g, dtype=float)
            sign = 1.0 if up else -1.0
            f[axis] = sign * (-g_l - scale[axis] * g_l) + bias_g[axis]
            readings.append(f)
    return readings


def test_aalborg_fig_5_34_5_35_s2_accelerometers():
    bias_mg = [5.4, -3.1, 7.1]  # Fig. 5-34
    scale_percent = [-0.2953, -0.0803, -0.0002]  # Fig. 5-35
    readings = _aalborg_accel_readings(
        [b * 1e-3 for b in bias_mg], [s * 1e-2 for s in scale_percent]
    )
    segments = [_segment(f, t=150.0 * k) for k, f in enumerate(readings)]
    # the estimators work in any unit: here g (1 g = 9.8 m/s²) as the report's tables
    options = static.StaticOptions(
        Site(math.radians(AALBORG_LAT_DEG), AALBORG_G),
        0.0,
        BiasInstability(),
        static.Scale.SYMMETRIC,
    )
    for method in (static.six_position, lambda s, o: static.six_position(s, o, salychev=True)):
        result = method(segments, options)
        bias = _estimate(result, Quantity.ACCEL_BIAS)
        np.testing.assert_allclose(bias.value * 1e3, bias_mg, atol=1e-9)
        for q in (Quantity.ACCEL_SCALE_POSITIVE, Quantity.ACCEL_SCALE_NEGATIVE):
            np.testing.assert_allclose(_estimate(result, q).value * 1e2, scale_percent, atol=1e-9)
        # S1 (5.1) from the horizontal axes gives the same bias here (no asymmetry)
        s1_bias = _estimate(result, Quantity.ACCEL_BIAS, written=False)
        np.testing.assert_allclose(s1_bias.value * 1e3, bias_mg, atol=1e-9)


def _frd_to_flu(v):
    return np.array([v[0], -v[1], -v[2]])


@pytest.mark.filterwarnings("ignore:Gimbal lock:UserWarning")  # setups with an axis vertical
def test_aalborg_fig_5_36_5_37_gyro_through_the_s2_setups():
    """Setups 1/2 of §5.2.3 (z_FRD down with x east, then z up with x west: a flip about the
    north-south axis) and the same pattern for x and y; readings from (5.9)-(5.18), whose
    g-dependent term is f·B_fω with f = ±g_l^LL on the vertical axis."""
    bias = np.array([0.0246, -0.0343, -0.0153])  # Fig. 5-36 [deg/s]
    gsens = np.array(
        [  # Fig. 5-37, row = gyro, column = acceleration axis [(deg/s)/g]
            [-0.0003, -0.0002, 0.0006],
            [-0.0005, 0.0021, -0.0001],
            [-0.0076, -0.0004, 0.0030],
        ]
    )
    omega = math.degrees(EARTH_RATE_RAD_S)
    lat = math.radians(AALBORG_LAT_DEG)
    g_l = -AALBORG_G
    # FRD axis of each setup pointing (down-axis, east-axis, south-axis); setup 2 flips about
    # the south-pointing axis: down-axis up, east-axis west.
    triads = [(2, 0, 1), (0, 1, 2), (1, 2, 0)]
    segments, attitudes = [], []
    for down, east, south in triads:
        for flipped in (False, True):
            s_down = -1.0 if flipped else 1.0  # +1: the down-axis points down
            # earth rate on FRD axes, (5.17)/(5.18): down-axis -sin(φ)Ω, south-axis -cos(φ)Ω
            w_e = np.zeros(3)
            w_e[down] = -s_down * math.sin(lat) * omega
            w_e[south] = -math.cos(lat) * omega
            f = np.zeros(3)
            f[down] = s_down * g_l  # specific force on the down-axis: g_l^LL = -1.0017 g
            w = bias + gsens @ f + w_e  # (5.9)-(5.16)
            segments.append(
                _segment(_frd_to_flu(f), _frd_to_flu(np.radians(w)), t=200.0 * len(segments))
            )
            # the setup's attitude: imu_link (FLU) axes in ENU
            enu = np.zeros((3, 3))  # rows: ENU direction of FRD x, y, z
            enu[down] = [0.0, 0.0, -s_down]
            enu[east] = [s_down, 0.0, 0.0]
            enu[south] = [0.0, -1.0, 0.0]
            flu = np.diag([1.0, -1.0, -1.0]) @ enu  # FLU axes = x, -y, -z of FRD
            yaw, pitch, roll = Rotation.from_matrix(flu.T).as_euler("ZYX")
            attitudes.append((roll, pitch, yaw))
    site = Site(lat, AALBORG_G)
    options = static.StaticOptions(site, 0.0, BiasInstability(), static.Scale.SYMMETRIC)
    # S3 needs the accelerometer rows too: an error-free accelerometer
    result = static.known_attitude(segments, attitudes, options)
    flip = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(
        np.degrees(_estimate(result, Quantity.GYRO_BIAS).value), flip @ bias, atol=1e-12
    )
    g_unit = np.degrees(_estimate(result, Quantity.GYRO_G_SENSITIVITY).value)
    np.testing.assert_allclose(g_unit, flip @ gsens @ flip, atol=1e-12)


def test_aalborg_section_4_4_predicted_accuracies():
    """Fig. 5-6 inputs: σ_f 0.352 mg at 75, σ_ω 0.248 deg/s at 25 independent samples/s,
    cross-level 0.009°, table rate σ 0.015 deg/s, angle σ 0.1°; results Fig. 5-10 to 5-14."""
    sigma_f = lambda seconds: 0.352e-3 / math.sqrt(75.0 * seconds)  # noqa: E731 [g]
    sigma_w = lambda seconds: math.radians(0.248) / math.sqrt(25.0 * seconds)  # noqa: E731
    site = Site(math.radians(AALBORG_LAT_DEG), AALBORG_G)

    def six(seconds, level_deg, scale):
        segments = []
        for axis in range(3):
            for sign in (1.0, -1.0):
                f = np.zeros(3)
                f[axis] = sign * AALBORG_G
                segments.append(
                    _segment(
                        f,
                        sigma_f=sigma_f(seconds),
                        sigma_w=sigma_w(seconds),
                        t=1000.0 * len(segments),
                    )
                )
        options = static.StaticOptions(site, math.radians(level_deg), BiasInstability(), scale)
        return static.six_position(segments, options, salychev=True)

    s2 = six(120.0, 0.0, static.Scale.SYMMETRIC)  # 120 s per position, vertical levelling free
    assert round(_estimate(s2, Quantity.ACCEL_BIAS).sigma[0] * 1e3, 3) == 0.003  # mg
    assert round(_estimate(s2, Quantity.ACCEL_SCALE_POSITIVE).sigma[0] * 1e6, 1) == 2.6  # 1e-4 %
    assert round(math.degrees(_estimate(s2, Quantity.GYRO_BIAS).sigma[0]), 3) == 0.002
    g_sigma = math.degrees(_estimate(s2, Quantity.GYRO_G_SENSITIVITY).sigma[2, 2])
    assert round(g_sigma, 3) == 0.003  # (deg/s)/g
    s1 = six(45.0, 0.009, static.Scale.ASYMMETRIC)  # S1: four horizontal positions, 45 s
    assert round(_estimate(s1, Quantity.ACCEL_BIAS).sigma[0] * 1e3, 2) == 0.08  # mg

    # D1: 100 s at 15 deg/s after a 120 s S1 bias (Fig. 5-14: 0.11 %)
    rate = math.radians(15.0)
    before = _segment([0, 0, -1.0], sigma_w=sigma_w(120.0), t=0.0, duration=120.0)
    spin = _segment(
        [0, 0, -1.0],
        [0, 0, rate],
        sigma_w=sigma_w(100.0),
        t=130.0,
        duration=100.0,
        kind=Kind.ROTATION,
    )
    d1 = rotation.rate_table([before, spin], rate, math.radians(0.015), 0.0, BiasInstability())
    assert round(100.0 * _estimate(d1, Quantity.GYRO_SCALE_POSITIVE).sigma[2], 2) == 0.11

    # D2: 4 revolutions at 15 deg/s (96 s) after a 120 s S1 bias (Fig. 5-14: 0.05 %)
    hz = 25.0
    t = np.arange(0.0, 336.0, 1.0 / hz)
    w = np.zeros((len(t), 3))
    w[(t >= 120.0) & (t < 216.0), 2] = rate
    record = ImuRecord(t, w, np.tile([0.0, 0.0, -1.0], (len(t), 1)), name="d2")
    a, b = int(120.0 * hz), int(216.0 * hz)
    statics = [
        Segment(
            0,
            0,
            a,
            0.0,
            t[a - 1],
            Kind.STATIC,
            Means(np.zeros(3), np.zeros(3), np.zeros(3), np.full(3, sigma_w(120.0))),
        ),
        Segment(
            0,
            b,
            len(t),
            t[b],
            t[-1],
            Kind.STATIC,
            Means(np.zeros(3), np.zeros(3), np.zeros(3), np.full(3, sigma_w(120.0))),
        ),
    ]
    d2 = rotation.known_angle(
        [record], statics, 8.0 * math.pi, math.radians(0.1), 0.0, BiasInstability()
    )
    scale = _estimate(d2, Quantity.GYRO_SCALE_POSITIVE)
    assert abs(scale.value[2]) < 1e-3  # noise-free data: the 1440° come back
    assert round(100.0 * scale.sigma[2], 2) == 0.05


@pytest.mark.parametrize("missing", range(6))
def test_six_position_names_the_missing_position(missing):
    segments = [
        _segment(np.eye(3)[axis] * sign * 9.81, t=100.0 * (2 * axis + k))
        for axis in range(3)
        for k, sign in enumerate((1.0, -1.0))
    ]
    name = [f"{s}{a}" for a in "xyz" for s in "+-"][missing]
    del segments[missing]
    options = static.StaticOptions(Site.at(45.0))
    with pytest.raises(EstimationError, match=f"missing \\{name} up"):
        static.six_position(segments, options)
