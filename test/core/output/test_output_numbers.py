"""core.output.output_numbers: the compiled output numbers against numpy's formulas on the same
row."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ins_fusion.core.output.output_numbers import (
    FAULTS,
    FIX,
    IMU,
    NUMBERS,
    ODOMETRY,
    PSD_TOLERANCE,
    fault_report,
    output_numbers,
    row_fault,
)
from ins_fusion.core.output.solution import COV_ATT, COV_POS, COV_VEL, POS, QUAT, RATE, VEL, WIDTH


def _row(seed: int, shift: float) -> np.ndarray:
    """A row with random state and covariances; the velocity covariance's eigenvalues are
    shifted by ``shift`` (negative: possibly indefinite)."""
    rng = np.random.default_rng(seed)
    row = rng.normal(size=WIDTH)
    row[QUAT] = Rotation.random(random_state=rng).as_quat()
    for block, scale in ((COV_POS, 1.0), (COV_VEL, 0.1), (COV_ATT, 1e-3)):
        a = rng.normal(size=(3, 3)) * scale
        row[block] = (a @ a.T).ravel()
    row[COV_VEL] += (np.eye(3) * shift).ravel()
    return row


def _numpy_psd(cov: np.ndarray) -> bool:
    eigenvalues = np.linalg.eigvalsh(cov)
    return bool(eigenvalues.min() >= -PSD_TOLERANCE * max(1.0, eigenvalues.max()))


@settings(max_examples=200, deadline=None)  # the first call loads the kernel
@given(st.integers(0, 2**32 - 1), st.floats(-0.05, 0.05), st.floats(1e-7, 1e-3))
def test_numbers_equal_numpy_formulas(seed, shift, rate_variance):
    row = _row(seed, shift)
    out = np.full(NUMBERS, np.nan)
    valid = output_numbers(row, rate_variance, out)
    assert valid == _numpy_psd(row[COV_VEL].reshape(3, 3))
    if not valid:
        assert np.isnan(out).all()  # untouched
        return
    mat = Rotation.from_quat(row[QUAT]).as_matrix()  # FLU -> ENU
    odometry = out[ODOMETRY]
    pose = odometry[7:43].reshape(6, 6)
    twist = odometry[49:85].reshape(6, 6)
    np.testing.assert_array_equal(odometry[:3], row[POS])
    np.testing.assert_array_equal(odometry[3:7], row[QUAT])
    np.testing.assert_array_equal(pose[:3, :3].ravel(), row[COV_POS])
    np.testing.assert_array_equal(pose[3:, 3:].ravel(), row[COV_ATT])
    assert not pose[:3, 3:].any() and not pose[3:, :3].any()
    np.testing.assert_allclose(odometry[43:46], mat.T @ row[VEL], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(odometry[46:49], row[RATE])
    velocity_cov = mat.T @ row[COV_VEL].reshape(3, 3) @ mat
    np.testing.assert_allclose(twist[:3, :3], velocity_cov, rtol=1e-10, atol=1e-13)
    np.testing.assert_array_equal(twist[3:, 3:], np.eye(3) * rate_variance)
    fix, imu = out[FIX], out[IMU]
    np.testing.assert_array_equal(fix, np.r_[row[1:4], row[COV_POS]])
    np.testing.assert_array_equal(imu[:16], np.r_[row[QUAT], row[COV_ATT], row[RATE]])
    np.testing.assert_array_equal(imu[16:25], (np.eye(3) * rate_variance).ravel())
    np.testing.assert_array_equal(imu[25:], np.r_[np.zeros(3), -1.0, np.zeros(8)])


def test_rounding_below_the_tolerance_is_still_psd():
    row = _row(7, 0.0)
    cov = np.diag([2.0, 1.0, 0.0])
    cov[2, 2] = -0.5 * PSD_TOLERANCE * 2.0  # a rounding-sized negative eigenvalue
    row[COV_VEL] = cov.ravel()
    assert output_numbers(row, 1e-5, np.empty(NUMBERS))
    row[COV_VEL.start + 8] = -4.0 * PSD_TOLERANCE * 2.0
    assert not output_numbers(row, 1e-5, np.empty(NUMBERS))


def test_symmetry_is_judged_against_the_variances_not_the_element():
    # A smoothed attitude covariance (variances ~1e-6 rad²) whose roll-yaw term, 6.4e-14, differs
    # from its mirror by 1e-9 of itself: rounding, publishable; the same difference in a term
    # as large as the variances' scale times 1e-8 is not.
    row = _row(5, 0.0)
    cov = np.diag([7.5e-7, 8.7e-7, 2.7e-7])
    cov[0, 2], cov[2, 0] = -6.4134561118640142e-14, -6.4134561187171026e-14
    row[COV_ATT] = cov.ravel()
    assert row_fault(row) == 0
    cov[0, 2] = cov[2, 0] + 1e-8 * np.sqrt(cov[0, 0] * cov[2, 2])
    row[COV_ATT] = cov.ravel()
    assert FAULTS[row_fault(row)] == "attitude covariance not symmetric"


def test_fault_names_the_first_check_that_fails():
    row = _row(3, 0.0)
    assert row_fault(row) == 0 and fault_report(row) == "publishable"
    broken = row.copy()
    broken[COV_ATT.start + 1] += 1.0  # asymmetric attitude covariance
    assert FAULTS[row_fault(broken)] == "attitude covariance not symmetric"
    broken[COV_VEL.start + 4] = -1.0  # indefinite velocity covariance: checked before attitude
    assert FAULTS[row_fault(broken)] == "velocity covariance not positive semi-definite"
    report = fault_report(broken)
    assert report.startswith("velocity covariance not positive semi-definite: ")
    assert "eigenvalues [-1." in report
    broken[COV_POS.start] = np.inf
    assert FAULTS[row_fault(broken)] == "position covariance not finite"
    broken[VEL.start] = np.nan
    assert fault_report(broken).startswith("a non-finite number in the state: [")
