"""Error-state filter algebra (core.filter.eskf) and the measurement models (core.measurements)
against independent references.

- F against finite differences of the strapdown mechanization itself: perturb the true state
  by each error state in turn, mechanize both with the same raw IMU data, and compare the
  error after 50 ms with expm(F T) δx.
- The second-order discretisation against filterpy's Van Loan (exact) over 10 s.
- Joseph-form updates keep P symmetric positive definite (hypothesis) and gate outliers.
- Every measurement Jacobian H against finite differences of its own prediction.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from filterpy.common import van_loan_discretization
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.spatial.transform import Rotation
from support.paths import REPO

from ins_fusion.core.compiled import kernel_array
from ins_fusion.core.filter.eskf import (
    ATT,
    AXIS_ERROR_TIME_S,
    BA,
    BG,
    POS,
    VEL,
    ErrorStateFilter,
    StateLayout,
    gyro_asymmetry_sigma,
    gyro_misalignment_variance,
)
from ins_fusion.core.filter.propagation import corrected_gyro, covariance_step
from ins_fusion.core.filter.records import GnssFixMeasurement, GnssVelocityMeasurement, Prediction
from ins_fusion.core.filter.state import X_COV_DT, X_COV_DTH, X_COV_DV, X_COV_VEL0, FilterState
from ins_fusion.core.filter.update_algebra import chi2_threshold
from ins_fusion.core.measurements.attitude import attitude
from ins_fusion.core.measurements.common import euler_jacobian
from ins_fusion.core.measurements.gnss_position import gnss_position
from ins_fusion.core.measurements.gnss_velocity import gnss_velocity
from ins_fusion.core.measurements.nhc import nhc
from ins_fusion.core.measurements.stationary import zupt
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.rotation import MAT_ENU_NED, euler_rad, quat_from_euler
from ins_fusion.core.nav.strapdown import NavState, increment, propagate
from ins_fusion.core.settings.config import FusionConfig

NOISE = FusionConfig.default().imu_noise
LAYOUT = StateLayout(gyro_scale=True, accel_scale=True, gyro_asymmetry=True)
#: A car at 57° N turning left at 15 m/s on a slope, IMU yawed 90° and tilted in base_link.
LAT, LON, HEIGHT = math.radians(57.0), math.radians(9.987), 40.0
VEL_NED = np.array([12.0, -8.0, 0.6])
QUAT_NB = quat_from_euler(0.03, -0.05, 2.0)
MAT_BI = Rotation.from_euler("ZYX", [math.pi / 2, 0.02, -0.03]).as_matrix()
RATE_I = np.array([0.01, -0.02, 0.3])  # corrected rate, imu FRD [rad/s]
FORCE_I = np.array([0.8, -2.5, -9.7])  # corrected specific force, imu FRD [m/s²]


def _nav() -> NavState:
    return NavState(LAT, LON, HEIGHT, VEL_NED.copy(), QUAT_NB.copy())


def _plus(nav: NavState, dx: np.ndarray) -> NavState:
    """True state = nominal ⊕ δx (δp NED [m], δv, ψ with C_true = exp([ψ×]) C_nominal)."""
    r_m, r_n = earth.radii_m(nav.lat_rad)
    q = Rotation.from_rotvec(dx[ATT : ATT + 3]) * Rotation.from_quat(nav.quat_nb)
    return NavState(
        nav.lat_rad + dx[0] / (r_m + nav.height_m),
        nav.lon_rad + dx[1] / ((r_n + nav.height_m) * math.cos(nav.lat_rad)),
        nav.height_m - dx[2],
        nav.vel_ned_m_s + dx[VEL : VEL + 3],
        q.as_quat(),
    )


def _minus(true: NavState, nav: NavState) -> np.ndarray:
    """δx (9) = true ⊖ nominal."""
    r_m, r_n = earth.radii_m(nav.lat_rad)
    rot = Rotation.from_quat(true.quat_nb) * Rotation.from_quat(nav.quat_nb).inv()
    return np.concatenate(
        [
            [
                (true.lat_rad - nav.lat_rad) * (r_m + nav.height_m),
                (true.lon_rad - nav.lon_rad) * (r_n + nav.height_m) * math.cos(nav.lat_rad),
                nav.height_m - true.height_m,
            ],
            true.vel_ned_m_s - nav.vel_ned_m_s,
            rot.as_rotvec(),
        ]
    )


def _mechanize(nav: NavState, rate_i: np.ndarray, force_i: np.ndarray, steps: int, dt: float):
    """Strapdown with constant corrected imu rate/force, rotated into base_link."""
    inc = increment(dt, tuple(MAT_BI @ rate_i * dt), tuple(MAT_BI @ force_i * dt))
    prev = None
    for _ in range(steps):
        nav = propagate(nav, inc, prev)
        prev = inc
    return nav


def _covariance_steps(
    kf: ErrorStateFilter,
    nav: NavState,
    force_i: np.ndarray,
    rate_i: np.ndarray,
    dt_s: float,
    steps: int,
    mat_bi: np.ndarray = MAT_BI,
) -> None:
    """``steps`` covariance steps of ``dt_s`` [s] the engine's way (propagation.covariance_step)
    at a nominal state that stays ``nav``, with a constant corrected specific force and rate
    [imu FRD]: each interval holds their increments and the velocity change that makes the
    specific force in NED (nav.mat_nb · mat_bi · force_i)."""
    x = FilterState(0.0, nav, (0.0, 0.0, 0.0), True).x
    sin_lat, cos_lat = math.sin(nav.lat_rad), math.cos(nav.lat_rad)
    gravity = earth.normal_gravity_from_sin_cos(sin_lat, cos_lat, nav.height_m)
    force_n = nav.mat_nb @ mat_bi @ force_i
    vel0 = nav.vel_ned_m_s - (force_n + np.array([0.0, 0.0, gravity])) * dt_s
    for _ in range(steps):
        x[X_COV_DT] = dt_s
        x[X_COV_DTH : X_COV_DTH + 3] = rate_i * dt_s
        x[X_COV_DV : X_COV_DV + 3] = force_i * dt_s
        x[X_COV_VEL0 : X_COV_VEL0 + 3] = vel0
        kf.P, kf.phi = covariance_step(
            kernel_array(kf.P), x, mat_bi, kf.process_model(), kf.layout.columns, 60.0
        )


def test_error_dynamics_match_finite_differences_of_the_mechanization():
    steps, dt = 20, 0.0025
    horizon = steps * dt
    nav = _nav()
    mat_ni = nav.mat_nb @ MAT_BI
    F = (
        ErrorStateFilter(LAYOUT, NOISE)
        .dynamics(mat_ni, mat_ni @ FORCE_I, FORCE_I, RATE_I, LAT, HEIGHT, tuple(VEL_NED))
        .copy()
    )
    transition = expm(F * horizon)
    nominal_end = _mechanize(nav, RATE_I, FORCE_I, steps, dt)
    sizes = [1.0] * 3 + [0.1] * 3 + [1e-3] * 3 + [1e-4] * 3 + [1e-2] * 3 + [1e-3] * 9
    for j, size in enumerate(sizes):
        dx = np.zeros(LAYOUT.size)
        dx[j] = size
        # Sensor errors: the true sensor output corrected with the nominal estimates is off
        # by -δb (and -δs∘y, -δa∘|y|): ω_true = ω̂ - δb_g - δs_g∘ω̂ - δa_g∘|ω̂|.
        sg, sa, sr = LAYOUT.sg, LAYOUT.sa, LAYOUT.sr
        assert sg is not None and sa is not None and sr is not None
        rate = RATE_I - dx[BG : BG + 3] - dx[sg : sg + 3] * RATE_I - dx[sr : sr + 3] * abs(RATE_I)
        force = FORCE_I - dx[BA : BA + 3] - dx[sa : sa + 3] * FORCE_I
        true_end = _mechanize(_plus(nav, dx[:9]), rate, force, steps, dt)
        measured = _minus(true_end, nominal_end)
        predicted = (transition @ dx)[:9]
        # Allowances: the position terms core.filter.eskf leaves out (v/R in δṗ, ∂g/∂φ in δv̇, Ω/R
        # in ψ̇) and the resolution of a latitude in radians (2e-16 rad ≈ 1.4e-9 m).
        allowance = {
            POS: 5e-6 * horizon * size + 5e-9,
            VEL: 1e-8 * horizon * size + 1e-12,
            ATT: 1e-11 * horizon * size + 1e-14,
        }
        for block in (POS, VEL, ATT):  # each block against its own change: small terms count
            rows = slice(block, block + 3)
            change = np.abs(predicted[rows] - dx[rows]).max()
            error = np.abs(measured[rows] - predicted[rows]).max()
            assert error < 0.02 * change + allowance[block], (j, block, measured, predicted)


def _noise_root(q: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh(q)
    return vectors * np.sqrt(np.clip(values, 0.0, None))


@pytest.mark.parametrize("interval_s", [1.0 / 134.0, 0.1])
def test_discretisation_matches_van_loan_over_ten_seconds(interval_s):
    kf = ErrorStateFilter(LAYOUT, NOISE)
    mat_ni = _nav().mat_nb @ MAT_BI
    args = (mat_ni, mat_ni @ FORCE_I, FORCE_I, RATE_I, LAT, HEIGHT, tuple(VEL_NED))
    F = kf.dynamics(*args).copy()
    G = _noise_root(kf.noise_density(mat_ni, RATE_I).copy())
    sigmas = [0.02] * 3 + [0.02] * 3 + [1e-3] * 3 + [1e-4] * 3 + [1e-3] * 3 + [1e-3] * 9
    P0 = np.diag(np.square(sigmas))
    kf.P = P0
    steps = round(10.0 / interval_s)
    _covariance_steps(kf, _nav(), FORCE_I, RATE_I, interval_s, steps)
    phi, q = van_loan_discretization(F, G, steps * interval_s)
    exact = phi @ P0 @ phi.T + q
    scale = np.sqrt(np.outer(np.diag(exact), np.diag(exact)))
    assert (np.abs(kf.P - exact) / scale).max() < 5e-3


@settings(max_examples=60, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(1, 3),
    st.floats(1e-6, 1e2),
)
def test_joseph_updates_keep_the_covariance_symmetric_positive_definite(seed, rows, r_scale):
    rng = np.random.default_rng(seed)
    n = LAYOUT.size
    kf = ErrorStateFilter(LAYOUT, NOISE)
    root = rng.standard_normal((n, n)) * np.logspace(-4, 1, n)
    kf.P = root @ root.T + 1e-12 * np.eye(n)
    for _ in range(20):
        H = rng.standard_normal((rows, n))
        R = np.eye(rows) * r_scale
        prior = kf.P
        result = kf.update(rng.standard_normal(rows) * 0.1, H, R, math.inf)
        assert result.accepted
        assert np.array_equal(kf.P, kf.P.T)
        assert np.linalg.eigvalsh(kf.P).min() > -1e-12 * np.abs(prior).max()
        assert np.trace(kf.P) <= np.trace(prior) * (1 + 1e-9)


def test_gate_rejects_outliers_and_bad_numbers_without_touching_the_covariance():
    kf = ErrorStateFilter(LAYOUT, NOISE)
    kf.P = np.eye(LAYOUT.size) * 0.01
    H = np.zeros((3, LAYOUT.size))
    H[:, POS : POS + 3] = np.eye(3)
    R = np.eye(3) * 0.0004
    threshold = chi2_threshold(0.999, 3)
    assert threshold == pytest.approx(16.27, abs=0.01)
    before = kf.P
    outlier = kf.update(np.array([3.0, 0.0, 0.0]), H, R, threshold)
    assert not outlier.accepted and outlier.dx is None and outlier.nis > threshold
    assert kf.P is before
    assert not kf.update(np.array([math.nan, 0.0, 0.0]), H, R, threshold).accepted
    good = kf.update(np.array([0.05, 0.0, 0.0]), H, R, threshold)
    assert good.accepted and good.dx is not None
    assert good.nis == pytest.approx(0.05**2 / 0.0104, rel=1e-9)
    assert good.dx[POS] == pytest.approx(0.05 * 0.01 / 0.0104, rel=1e-9)


def test_problem_reports_bad_numbers():
    kf = ErrorStateFilter(LAYOUT, NOISE)
    kf.P = np.eye(LAYOUT.size)
    assert kf.problem() is None
    bad = np.eye(LAYOUT.size)
    bad[4, 4] = -1e-6
    kf.P = bad
    assert kf.problem() == "negative variance in state 4"
    bad = np.eye(LAYOUT.size)
    bad[2, 7] = math.inf
    kf.P = bad
    assert kf.problem() == "non-finite covariance"


# ------------------------------------------------------------------ measurement models

LAYOUT_GNSS = StateLayout(gyro_scale=True, gnss_error=True, gyro_asymmetry=True)


def _prediction(dx: np.ndarray, layout: StateLayout = LAYOUT_GNSS) -> Prediction:
    """Prediction of the true state nominal ⊕ δx (sensor errors make the corrected rate
    differ from the nominal one)."""
    nav = _plus(_nav(), dx[:9])
    sg = dx[layout.sg : layout.sg + 3] if layout.sg is not None else 0.0
    sr = dx[layout.sr : layout.sr + 3] if layout.sr is not None else 0.0
    rate_i = RATE_I - dx[BG : BG + 3] - sg * RATE_I - sr * abs(RATE_I)
    return Prediction(
        nav.lat_rad,
        nav.lon_rad,
        nav.height_m,
        nav.vel_ned_m_s,
        nav.mat_nb,
        MAT_BI @ rate_i,
        rate_i,
    )


def _check_jacobian(model, sizes, layout: StateLayout = LAYOUT_GNSS, rel: float = 1e-3):
    """z(nominal) - z(true) = H δx to first order, column by column."""
    z0, H, _ = model(_prediction(np.zeros(layout.size), layout), np.zeros(layout.size))
    for j, size in enumerate(sizes):
        dx = np.zeros(layout.size)
        dx[j] = size
        z1, _, _ = model(_prediction(dx, layout), dx)
        numeric = z0 - z1
        expected = H @ dx
        assert np.abs(numeric - expected).max() <= rel * max(np.abs(expected).max(), 1e-6), (
            j,
            numeric,
            expected,
        )


SIZES = [0.1] * 3 + [0.01] * 3 + [1e-4] * 3 + [1e-5] * 3 + [1e-3] * 3 + [1e-5] * 6 + [0.05] * 3
LEVER_B = np.array([-0.8, 0.1, -0.15])  # IMU -> antenna, base_link FRD [m]


def test_gnss_position_jacobian():
    fix = GnssFixMeasurement(0.0, 57.0001, 9.9871, 42.0, np.eye(3) * 1e-4)

    def model(pred, dx):
        # The true correlated receiver error is the estimate (0) plus its error δε_g.
        error = dx[LAYOUT_GNSS.gp : LAYOUT_GNSS.gp + 3]
        return gnss_position(
            pred, LAYOUT_GNSS, fix, LEVER_B, np.eye(3), (error[0], error[1], error[2])
        )

    _check_jacobian(model, SIZES)


def test_gnss_velocity_jacobian_and_horizontal_only_when_vertical_unknown():
    cov = np.diag([0.0025, 0.0025, 1e6])
    vel = GnssVelocityMeasurement(0.0, np.array([-8.0, 12.0, 0.0]), cov)

    def model(pred, _):
        out = gnss_velocity(pred, LAYOUT_GNSS, vel, LEVER_B, MAT_BI)
        assert out is not None
        return out

    z, H, R = model(_prediction(np.zeros(LAYOUT_GNSS.size)), None)
    assert z.shape == (2,) and H.shape == (2, LAYOUT_GNSS.size) and R.shape == (2, 2)
    full = GnssVelocityMeasurement(0.0, np.array([-8.0, 12.0, 0.0]), np.eye(3) * 0.0025)

    def model3(pred, _):
        out = gnss_velocity(pred, LAYOUT_GNSS, full, LEVER_B, MAT_BI)
        assert out is not None
        return out

    _check_jacobian(model3, SIZES)
    bad = GnssVelocityMeasurement(0.0, np.array([math.nan, 1.0, 0.0]), np.eye(3))
    assert (
        gnss_velocity(_prediction(np.zeros(LAYOUT_GNSS.size)), LAYOUT_GNSS, bad, LEVER_B, MAT_BI)
        is None
    )
    # A vertical velocity or variance that is not finite leaves the horizontal rows.
    for vertical, variance in ((math.nan, 0.0025), (0.0, math.nan), (0.0, math.inf)):
        cov_v = np.diag([0.0025, 0.0025, variance])
        partial = GnssVelocityMeasurement(0.0, np.array([-8.0, 12.0, vertical]), cov_v)
        out = gnss_velocity(
            _prediction(np.zeros(LAYOUT_GNSS.size)), LAYOUT_GNSS, partial, LEVER_B, MAT_BI
        )
        assert out is not None and out[0].shape == (2,) and np.isfinite(out[2]).all()


def test_nhc_jacobian():
    arm = np.array([-0.8, 0.0, 1.6])
    _check_jacobian(lambda pred, _: nhc(pred, LAYOUT_GNSS, arm, MAT_BI, 0.05), SIZES)


def test_zupt_is_the_negated_velocity():
    z, H, R = zupt(_prediction(np.zeros(LAYOUT_GNSS.size)), LAYOUT_GNSS, 0.02)
    assert z == pytest.approx(-VEL_NED)
    assert np.array_equal(H[:, VEL : VEL + 3], np.eye(3)) and np.count_nonzero(H) == 3
    assert np.allclose(R, np.eye(3) * 4e-4)


def test_euler_angles_and_jacobian():
    mat = _nav().mat_nb
    assert euler_rad(mat) == pytest.approx([0.03, -0.05, 2.0], abs=1e-12)
    J = euler_jacobian(mat)
    for j in range(3):
        psi = np.zeros(3)
        psi[j] = 1e-7
        turned = Rotation.from_rotvec(psi).as_matrix() @ mat
        assert (euler_rad(turned) - euler_rad(mat)) / 1e-7 == pytest.approx(J[:, j], abs=1e-6)


def test_attitude_model_converts_rep103_covariance_and_drops_unknown_angles():
    pred = _prediction(np.zeros(LAYOUT_GNSS.size))
    measured = Rotation.from_rotvec([0.0, 0.0, 0.01]).as_matrix() @ pred.mat_nb
    cov_flu = np.array([[4e-6, 1e-6, 0.0], [1e-6, 2e-6, 0.0], [0.0, 0.0, 1e-6]])
    z, H, R = attitude(pred, LAYOUT_GNSS, measured, cov_flu)
    assert z == pytest.approx([0.0, 0.0, 0.01], abs=1e-12)  # a turn about down is yaw only
    assert R[0, 1] == pytest.approx(-1e-6)  # FLU pitch is minus NED pitch
    heading_only = attitude(pred, LAYOUT_GNSS, measured, np.diag([1e6, 1e6, 1e-6]))
    assert heading_only is not None
    z, H, R = heading_only
    assert z.shape == (1,) and H.shape == (1, LAYOUT_GNSS.size)
    assert attitude(pred, LAYOUT_GNSS, measured, np.eye(3) * 1e6) is None
    # A variance that is not finite drops its angle only (no product spreads it).
    cov_nan = np.array([[math.nan, 0.0, 0.0], [0.0, 2e-6, 0.0], [0.0, 0.0, 1e-6]])
    partial = attitude(pred, LAYOUT_GNSS, measured, cov_nan)
    assert partial is not None and partial[0].shape == (2,)
    assert np.array_equal(partial[2], np.diag([2e-6, 1e-6]))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
    st.lists(st.sampled_from([1e-6, 4e-4, 1.0, 1e6, math.inf, math.nan]), min_size=3, max_size=3),
)
def test_attitude_model_keeps_the_measured_angles_with_their_variances(
    rotvec: list[float], variances: list[float]
) -> None:
    """Any attitude measured as predicted: no innovation, one row per angle with a finite
    variance below UNKNOWN_ANGLE_VARIANCE, and those variances (sign-flipped FLU -> FRD
    covariances: the diagonal stays) in R."""
    pred = _prediction(np.zeros(LAYOUT_GNSS.size))
    mat = Rotation.from_rotvec(rotvec).as_matrix()
    pred = pred._replace(mat_nb=mat)
    model = attitude(pred, LAYOUT_GNSS, mat, np.diag(variances))
    kept = [v for v in variances if math.isfinite(v) and v < 1.0]
    if not kept:
        assert model is None
        return
    assert model is not None
    z, H, R = model
    assert np.array_equal(np.abs(z), np.zeros(len(kept)))
    assert H.shape == (len(kept), LAYOUT_GNSS.size)
    assert np.array_equal(R, np.diag(kept))


def test_ned_enu_axis_swap_is_its_own_inverse():
    assert np.array_equal(MAT_ENU_NED @ MAT_ENU_NED, np.eye(3))


def test_misalignment_noise_matches_a_constant_misalignment_after_its_time():
    """The turn-rate-dependent noise standing for the gyro's misalignment: after
    AXIS_ERROR_TIME_S of a steady turn the attitude σ it builds about the other two axes equals
    the error a constant misalignment of that σ makes (σ ω t); none about the turn's own axis
    (a scale factor, estimated by states) and none without rate."""
    quiet = replace(
        NOISE,
        gyro_arw=(0.0, 0.0, 0.0),
        accel_vrw=(0.0, 0.0, 0.0),
        gyro_bias_instability=(0.0, 0.0, 0.0),
        accel_bias_instability=(0.0, 0.0, 0.0),
        gyro_misalignment=1e-3,
    )
    rate = np.array([0.0, 0.0, 0.25])  # a turn about imu z [rad/s]
    layout = StateLayout()
    kf = ErrorStateFilter(layout, quiet)
    assert np.count_nonzero(kf.noise_density(np.eye(3), np.zeros(3))) == 0
    kf.P = np.zeros((layout.size, layout.size))
    level = NavState(0.0, 0.0, 0.0, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    force = np.array([0.0, 0.0, -9.8])
    _covariance_steps(kf, level, force, rate, 0.01, round(AXIS_ERROR_TIME_S / 0.01), np.eye(3))
    variance = np.diagonal(kf.P)[ATT : ATT + 3]
    assert variance[:2] == pytest.approx([(1e-3 * 0.25 * AXIS_ERROR_TIME_S) ** 2] * 2, rel=0.01)
    assert variance[2] < 1e-10


def test_misalignment_variance_comes_from_the_calibration_when_it_corrects_one():
    """Without a calibration, or with one that leaves the misalignment alone (the IMU400CC
    file), the datasheet's σ on every off-diagonal element; a calibration that corrects a
    misalignment leaves its own σ."""
    noise = replace(NOISE, gyro_misalignment=2e-3)
    off = ~np.eye(3, dtype=bool)
    datasheet = gyro_misalignment_variance(noise)
    assert np.allclose(datasheet[off], 4e-6) and not np.diagonal(datasheet).any()
    file = ImuCalibration.from_yaml(REPO / "config" / "imu400cc_calibration.yaml").gyro
    assert np.array_equal(gyro_misalignment_variance(noise, file), datasheet)
    sigma = ((0.0, 3e-4, 0.0), (1e-4, 0.0, 0.0), (0.0, 0.0, 0.0))
    aligned = replace(file, misalignment_rad=((0.0, 1e-3, 0.0), (0.0,) * 3, (0.0,) * 3))
    aligned = replace(aligned, misalignment_sigma_rad=sigma)
    assert np.allclose(gyro_misalignment_variance(noise, aligned), np.square(sigma))


def test_asymmetry_sigma_comes_from_a_calibration_that_corrects_sign_dependent_scales():
    """Without a calibration the datasheet's σ on every axis; the IMU400CC file corrects
    sign-dependent gyro scale factors and leaves its own σ, √(σ₊² + σ₋²)/2 per axis; a
    calibration with the same scale for both signs leaves the asymmetry to the datasheet."""
    assert np.array_equal(gyro_asymmetry_sigma(NOISE), np.full(3, NOISE.gyro_asymmetry_sigma))
    file = ImuCalibration.from_yaml(REPO / "config" / "imu400cc_calibration.yaml").gyro
    expected = 0.5 * np.hypot(file.scale_positive_sigma, file.scale_negative_sigma)
    assert np.allclose(gyro_asymmetry_sigma(NOISE, file), expected)
    assert (expected > 0.0).all() and (expected < NOISE.gyro_asymmetry_sigma).all()
    symmetric = replace(file, scale_negative=file.scale_positive)
    assert np.array_equal(gyro_asymmetry_sigma(NOISE, symmetric), gyro_asymmetry_sigma(NOISE))


@given(
    rate=st.floats(-2.0, 2.0),
    bias=st.floats(-0.02, 0.02),
    scale=st.floats(-0.02, 0.02),
    asymmetry=st.floats(-0.02, 0.02),
)
def test_corrected_gyro_inverts_the_sensor_model(rate, bias, scale, asymmetry):
    """ω̃ = (1 + s)ω + a|ω| + b corrected back to ω; without an asymmetry the plain
    (ω̃ - b) / (1 + s), to the bit."""
    measured = (1.0 + scale) * rate + asymmetry * abs(rate) + bias
    corrected = corrected_gyro(measured, bias, scale, asymmetry)
    assert corrected == pytest.approx(rate, rel=1e-9, abs=1e-15)
    if asymmetry == 0.0:
        assert corrected == (measured - bias) / (1.0 + scale)
