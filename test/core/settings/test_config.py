"""Fusion parameters (one table), their YAML file, FusionConfig conversion, the calibration file,
levelling and the stop detector."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from support.config_checks import assert_file_holds_defaults
from support.paths import REPO

from gnss_ins_common.params import ParameterValueError, load_yaml
from ins_fusion.core.measurements.stop_detector import StopDetector
from ins_fusion.core.nav.calibration import CalibrationError, ImuCalibration
from ins_fusion.core.nav.levelling import Levelling, earth_rate_body_rad_s, level
from ins_fusion.core.nav.rotation import MAT_FLU_FRD, quat_from_euler
from ins_fusion.core.nav.strapdown import NavState
from ins_fusion.core.nav.units import DEG, STANDARD_GRAVITY_M_S2, mg
from ins_fusion.core.settings.config import NODE_NAME, FusionConfig, StopDetectorConfig
from ins_fusion.core.settings.imu_noise_params import IMU_NOISE_PARAMETERS
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.sim.imu_model import IMU400CC, ImuErrorModel, ImuProfile, TriadErrors

CONFIG = REPO / "config" / "ins_fusion.yaml"
CALIBRATION = REPO / "config" / "imu400cc_calibration.yaml"

#: The parameters issue 5 requires by name.
REQUIRED = {
    "imu_noise.gyro_arw",
    "imu_noise.accel_vrw",
    "imu_noise.gyro_bias_instability",
    "imu_noise.accel_bias_instability",
    "imu_noise.bias_correlation_time",
    "imu_noise.gyro_scale_sigma",
    "imu_noise.accel_scale_sigma",
    "imu_mounting_rpy_deg",
    "gnss_lever_arm",
    "datum",
    "calibration_file",
    "use_zupt",
    "use_nhc",
    "use_gnss_velocity",
    "use_attitude",
    "output_rate",
    "map_frame",
    "base_frame",
}


def test_config_file_matches_the_declared_defaults():
    assert_file_holds_defaults(CONFIG.name, NODE_NAME, PARAMETERS)
    declared = {p.name: p.default for p in PARAMETERS}
    assert declared.keys() >= REQUIRED
    assert load_yaml(CONFIG, NODE_NAME, PARAMETERS) == declared


def test_every_parameter_is_described_and_its_default_valid():
    names = [p.name for p in PARAMETERS]
    assert len(names) == len(set(names))
    for spec in PARAMETERS:
        assert spec.description and spec.problem(spec.default) is None, spec.name


def test_the_imu_noise_model_leads_the_table_and_is_all_of_imu_noise():
    noise = [p.name for p in IMU_NOISE_PARAMETERS]
    assert [p.name for p in PARAMETERS[: len(noise)]] == noise
    assert {p.name for p in PARAMETERS if p.name.startswith("imu_noise.")} == set(noise)


def test_noise_defaults_follow_the_aalborg_notes_and_match_the_simulated_imu400cc():
    noise = FusionConfig.default().imu_noise
    # (7.14) per-sample sigma with the bandwidths of §1.3 through (5.21): RW = 60 σ / √BW.
    assert noise.gyro_arw[0] == pytest.approx(0.0041 / math.sqrt(25.0), rel=2e-3)
    assert noise.accel_vrw[2] == pytest.approx(0.0036 / math.sqrt(75.0), rel=2e-3)
    assert np.mean(noise.gyro_arw) / DEG * 60.0 == pytest.approx(2.96, abs=0.01)
    # The simulator's imu400cc profile derives the same densities and instabilities.
    assert noise.gyro_arw == pytest.approx(IMU400CC.gyro.noise_density, rel=2e-3)
    assert noise.accel_vrw == pytest.approx(IMU400CC.accel.noise_density, rel=2e-3)
    assert noise.gyro_bias_instability == pytest.approx(IMU400CC.gyro.bias_instability, rel=3e-3)
    assert noise.accel_bias_instability == pytest.approx(IMU400CC.accel.bias_instability)
    assert noise.bias_correlation_time_s == IMU400CC.gyro.bias_correlation_time_s[0]


def test_from_parameters_converts_user_units_and_rejects_bad_values():
    cfg = FusionConfig.from_parameters(
        {
            "imu_noise.gyro_arw": [60.0, 60.0, 60.0],
            "imu_noise.gyro_scale_sigma": 1000,
            "imu_mounting_rpy_deg": [0.0, 0.0, 90.0],
            "datum": [57.0, 10.0, 40.0],
            "stop_detector.window": 2,
        }
    )
    assert cfg.imu_noise.gyro_arw == pytest.approx((DEG, DEG, DEG))  # 60 deg/√h = 1 deg/√s
    assert cfg.imu_noise.gyro_scale_sigma == pytest.approx(1e-3)
    assert cfg.imu_mounting_rpy_rad[2] == pytest.approx(math.pi / 2)
    assert cfg.datum_deg == (57.0, 10.0, 40.0)
    assert cfg.stop_detector.window_s == 2.0
    assert FusionConfig.default().datum_deg is None
    scalar = FusionConfig.from_parameters({"imu_noise.gyro_arw": 60.0})  # one value: every axis
    assert scalar.imu_noise.gyro_arw == pytest.approx((DEG, DEG, DEG))
    for bad in (
        {"imu_noise.gyro_arw": [1.0, float("nan"), 1.0]},
        {"imu_lever_arm": [0.0, float("inf"), 0.0]},
        {"imu_noise.gyro_arw": [1.0, 2.0]},
        {"datum": [91.0, 0.0, 0.0]},
        {"datum": [1.0, 2.0]},
        {"gate_probability": 1.5},
        {"use_nhc": "yes"},
        {"no_such_parameter": 1},
    ):
        with pytest.raises(ParameterValueError):
            FusionConfig.from_parameters(bad)


def test_from_yaml_applies_overrides():
    cfg = FusionConfig.from_yaml(CONFIG, {"use_nhc": False})
    assert not cfg.use_nhc and cfg.use_zupt


# --------------------------------------------------------------------------- calibration


def test_calibration_file_holds_the_selected_values_of_aalborg_notes_3_3():
    """The report's device-axis values, as imu_link sees them through the driver's defaults
    (FLU = device x, -y, -z; accelerometer sign -1): test_calibration_frame.py checks the rule."""
    cal = ImuCalibration.from_yaml(CALIBRATION)
    assert cal.gyro.bias == pytest.approx(np.radians([0.0246, 0.0343, 0.0153]))
    assert cal.gyro.bias_sigma == pytest.approx(np.radians([0.010, 0.0089, 0.0140]))
    assert cal.gyro.scale_positive == pytest.approx([0.000921, -0.008199, -0.001811])
    assert cal.gyro.scale_negative == pytest.approx([-0.001304, 0.008286, 0.002637])
    mg = STANDARD_GRAVITY_M_S2 * 1e-3
    assert cal.accel.bias == pytest.approx(np.array([-5.4, -3.1, 7.1]) * mg)
    assert cal.accel.scale_positive == pytest.approx([0.000172, 0.000309, -0.000202])
    assert cal.accel.scale_negative == pytest.approx([0.000652, 0.000340, 0.000846])
    assert cal.g_sensitivity == ((0.0, 0.0, 0.0),) * 3
    assert cal.temperature_range_c == (24.0, 28.0)
    assert cal.in_temperature_range(26.0) and not cal.in_temperature_range(30.0)


def test_correction_inverts_the_deterministic_error_model():
    # A simulated IMU with only deterministic errors (bias, asymmetric scale, misalignment,
    # g-dependent gyro bias) and a calibration holding exactly those values.
    misalign = ((0.0, 2e-3, -1e-3), (1.5e-3, 0.0, 0.5e-3), (-2e-3, 1e-3, 0.0))
    g_sens = ((1e-5, -2e-5, 3e-5), (0.0, 1e-5, 0.0), (-4e-5, 0.0, 2e-5))
    gyro = TriadErrors(
        bias=(1e-3, -2e-3, 3e-4),
        scale_pos=(1e-3, 8e-3, 2e-3),
        scale_neg=(-1e-3, -8e-3, -2e-3),
        misalignment_rad=misalign,
    )
    accel = TriadErrors(
        bias=(0.05, -0.03, 0.07),
        scale_pos=(6e-4, 3e-4, -2e-4),
        scale_neg=(2e-4, 3e-4, 8e-4),
        misalignment_rad=misalign,
    )
    profile = ImuProfile("deterministic", 100.0, gyro, accel, gyro_g_sensitivity=g_sens)
    rng = np.random.default_rng(3)
    rate = rng.uniform(-1.0, 1.0, (500, 3))
    force = rng.uniform(-12.0, 12.0, (500, 3))
    measured_rate, measured_force = ImuErrorModel(profile, 0).apply(
        np.arange(500) * 0.01, rate, force
    )
    section = {
        "gyro": {
            "bias_deg_s": list(np.degrees(gyro.bias)),
            "scale_positive_percent": [v * 100 for v in gyro.scale_pos],
            "scale_negative_percent": [v * 100 for v in gyro.scale_neg],
            "misalignment_mrad": [[v * 1e3 for v in row] for row in misalign],
            "g_sensitivity_deg_s_per_g": [
                [math.degrees(v) * STANDARD_GRAVITY_M_S2 for v in row] for row in g_sens
            ],
        },
        "accel": {
            "bias_mg": [v / (STANDARD_GRAVITY_M_S2 * 1e-3) for v in accel.bias],
            "scale_positive_percent": [v * 100 for v in accel.scale_pos],
            "scale_negative_percent": [v * 100 for v in accel.scale_neg],
            "misalignment_mrad": [[v * 1e3 for v in row] for row in misalign],
        },
    }
    cal = ImuCalibration.from_mapping(section)
    for k in range(500):
        r, f = cal.correct(tuple(measured_rate[k]), tuple(measured_force[k]))
        assert f == pytest.approx(force[k], abs=1e-12)
        assert r == pytest.approx(rate[k], abs=1e-12)


def test_two_range_accelerometer_scale_of_the_aalborg_report():
    """Report §9.1.1: the observation is corrected with the scale for its size. x: +0.0652 %
    at +0.2 g, +0.0172 % at -0.2 g (S1 mod, Fig. 5-33), -0.2953 % at ±1 g (S2, Fig. 5-35), bias
    5.4 mg (Fig. 5-34); the switch at 0.6 g is the file's (the report does not state it)."""
    x = {
        "bias_mg": [5.4, 0.0, 0.0],
        "scale_positive_percent": [0.0652, 0.0, 0.0],
        "scale_negative_percent": [0.0172, 0.0, 0.0],
        "scale_large_positive_percent": [-0.2953, 0.0, 0.0],
        "scale_large_negative_percent": [-0.2953, 0.0, 0.0],
        "large_input_g": 0.6,
    }
    cal = ImuCalibration.from_mapping({"accel": x})
    g, bias = STANDARD_GRAVITY_M_S2, mg(5.4)
    for true_g, scale in ((1.0, -0.002953), (-1.0, -0.002953), (0.2, 0.000652), (-0.2, 0.000172)):
        measured = bias + true_g * g * (1.0 + scale)
        _, force = cal.correct((0.0, 0.0, 0.0), (measured, 0.0, 0.0))
        assert force[0] == pytest.approx(true_g * g, abs=1e-12)
    # The same file without the large range (one scale per sign) leaves -3.60 mg at +1 g:
    # (1 - 0.002953) / (1 + 0.000652) - 1 = -0.003603.
    one = ImuCalibration.from_mapping({"accel": {k: v for k, v in x.items() if "large" not in k}})
    _, force = one.correct((0.0, 0.0, 0.0), (bias + g * (1.0 - 0.002953), 0.0, 0.0))
    assert (force[0] - g) / mg(1.0) == pytest.approx(-3.603, abs=1e-3)


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ({"accel": {"scale_large_positive_percent": [0.0, 0.0, 0.0]}}, "needs large_input_g"),
        ({"gyro": {"large_input_deg_s": -1.0}}, "must be positive"),
        ({"gyro": {"bias_deg_s": [1.0, 2.0]}}, "three values"),
        ({"gyro": {"bias": [1.0, 2.0, 3.0]}}, "unknown key"),
        ({"accel": {"misalignment_mrad": [[0, 0, 0], [0, 0]]}}, "three rows"),
        ({"temperature_range_c": [30.0, 20.0]}, "low, high"),
        ({"gyro": {"bias_deg_s": [1.0, "x", 3.0]}}, "finite numbers"),
        ({"gyro": "none"}, "mapping"),
    ],
)
def test_malformed_calibration_is_rejected_with_its_location(section, message):
    with pytest.raises(CalibrationError, match=message):
        ImuCalibration.from_mapping(section)


def test_unreadable_calibration_file(tmp_path):
    with pytest.raises(CalibrationError):
        ImuCalibration.from_yaml(tmp_path / "missing.yaml")
    other = tmp_path / "other.yaml"
    other.write_text("something: 1\n")
    with pytest.raises(CalibrationError, match="imu_calibration"):
        ImuCalibration.from_yaml(other)


# ---------------------------------------------------------------- levelling, stop detector


def test_levelling_recovers_the_ntnu_mount_tilt():
    # NTNU notes "Implications" D4a: a static IMU pitched 25.10° and rolled -1.04°.
    roll, pitch = math.radians(-1.04), math.radians(25.10)
    mat_nb = NavState(0.0, 0.0, 0.0, np.zeros(3), quat_from_euler(roll, pitch, 1.0)).mat_nb
    force_b = mat_nb.T @ np.array([0.0, 0.0, -9.81])
    assert level(force_b) == pytest.approx((roll, pitch), abs=1e-12)
    lev = Levelling()
    for k in range(100):
        lev.push(k * 0.01, (1e-4, 0.0, 0.0), tuple(force_b))
    assert lev.duration_s == pytest.approx(0.99)
    assert lev.mean_force_i == pytest.approx(force_b)


def test_earth_rate_seen_at_rest_without_heading_is_the_vertical_part():
    lat = math.radians(57.0)
    mat_nb = NavState(0.0, 0.0, 0.0, np.zeros(3), quat_from_euler(0.0, 0.0, 0.7)).mat_nb
    known = earth_rate_body_rad_s(mat_nb, lat, heading_known=True)
    vertical = earth_rate_body_rad_s(mat_nb, lat, heading_known=False)
    assert np.linalg.norm(known) == pytest.approx(7.292115e-5)
    assert vertical == pytest.approx([0.0, 0.0, -7.292115e-5 * math.sin(lat)])


STOP = StopDetectorConfig(1.0, 0.048, 5e-4, 0.05, 0.2, 1.5, 0.5)


def _feed(detector: StopDetector, t0: float, seconds: float, accel_var: float, rng) -> float:
    """134 Hz samples whose var(a_x)+var(a_y) is accel_var (NTNU Table 4.5 levels)."""
    sigma = math.sqrt(accel_var / 2.0)
    t = t0
    for _ in range(round(seconds * 134)):
        t += 1.0 / 134.0
        force = (rng.normal(0.0, sigma), rng.normal(0.0, sigma), -9.81)
        detector.push(t, (0.0, 0.0, 0.0), force)
    return t


def test_stop_detector_on_ntnu_table_4_5_levels_with_speed_veto_and_hysteresis():
    rng = np.random.default_rng(0)
    det = StopDetector(STOP, np.eye(3))
    t = _feed(det, 0.0, 1.2, 3.08e-3, rng)  # "stopped (engine on)"
    assert not det.evaluate(t, None, None)  # candidate, but not yet for min_duration
    t = _feed(det, t, 0.6, 3.08e-3, rng)
    assert det.evaluate(t, None, None)
    assert det.accel_variance == pytest.approx(3.08e-3, rel=0.25)
    # Hysteresis: a speed of 0.25 m/s (above 0.2, below 1.5 x 0.2) does not end the stop...
    assert det.evaluate(t, 0.25, 0.0)
    # ...but a GNSS speed of 1 m/s does, and so does the vibration of "driving straight".
    assert not det.evaluate(t, 1.0, 0.0)
    det.reset()
    t = _feed(det, t, 2.0, 0.146, rng)
    assert not det.evaluate(t, 0.0, 0.0) and not det.evaluate(t + 1.0, 0.0, 0.0)
    # A vibration-free cruise (simulated data) is vetoed by the speed alone.
    det.reset()
    t = _feed(det, t, 2.0, 1e-5, rng)
    assert not det.evaluate(t, 8.0, None) and not det.evaluate(t + 1.0, None, 8.0)


def test_stop_detector_rotates_the_specific_force_into_base_link():
    # imu_link yawed 90°: the variance of imu x is base_link y; imu z stays out of it.
    mat_bi = MAT_FLU_FRD @ Rotation.from_euler("z", 90, degrees=True).as_matrix() @ MAT_FLU_FRD
    det = StopDetector(STOP, mat_bi)
    rng = np.random.default_rng(1)
    t = 0.0
    for _ in range(200):
        t += 1.0 / 134.0
        det.push(t, (0.0, 0.0, 0.0), (0.0, 0.0, rng.normal(-9.81, 0.3)))
    assert not det.evaluate(t, None, None)
    assert det.accel_variance < 1e-20


@settings(max_examples=25, deadline=None)
@given(
    rate_hz=st.floats(50.0, 2000.0),
    window_s=st.floats(0.1, 3.0),
    seconds=st.floats(0.0, 4.0),
)
def test_stop_detector_window_holds_exactly_the_last_window_of_samples(
    rate_hz: float, window_s: float, seconds: float
) -> None:
    """The detector's sample ring keeps every sample of the last window, oldest first, at any
    IMU rate (a rate above what the ring was sized for makes it grow, dropping nothing)."""
    config = StopDetectorConfig(window_s, 0.048, 5e-4, 0.05, 0.2, 1.5, 0.5)
    det = StopDetector(config, np.eye(3))
    times = np.arange(1, int(seconds * rate_hz) + 2) / rate_hz
    for k, t in enumerate(times):
        det.push(float(t), (float(k), 0.0, 0.0), (0.0, float(-k), -9.81))
    window = det.window()
    kept = np.flatnonzero(times >= times[-1] - window_s)
    np.testing.assert_array_equal(window[:, 0], times[kept])
    np.testing.assert_array_equal(window[:, 1], kept)
    np.testing.assert_array_equal(window[:, 5], -kept)
    det.reset()
    assert len(det.window()) == 0
