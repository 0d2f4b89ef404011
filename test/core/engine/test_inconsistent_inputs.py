"""The engine on inconsistent inputs for a long time: an IMU at rest under GNSS receivers that
report a vehicle moving at 5 m/s (what the README's three emulators give, and a faulty installation
can: the IMU of another vehicle, a frozen IMU stream). Every gate recovery fades the covariance;
before issue 38's fix the fadings multiplied the bias variances until the state overflowed (the
live soak: a non-finite state and a reset after 15 min). The filter must reject or adapt, never
overflow: every solution publishable, no reset, the biases within what they can be."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation
from support.paths import REPO

from gnss_ins_common.params import load_yaml
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.filter import eskf
from ins_fusion.core.filter.eskf import BG
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)
from ins_fusion.core.output.output_numbers import FAULTS, row_fault
from ins_fusion.core.output.solution import GYRO
from ins_fusion.core.settings.config import NODE_NAME, FusionConfig
from ins_fusion.core.settings.params import PARAMETERS

pytestmark = pytest.mark.slow

IMU_RATE_HZ = 134.0
VELOCITY_ENU = np.array([3.0, 4.0, 0.0])  # the README's emulators: 5 m/s
DATUM = (57.014871838333335, 9.986598768333334, 50.0)  # the emulators' start (Aalborg)
#: The IMU400CC's per-sample white noise (the emulator's, notes §1.3) [rad/s], [m/s²].
GYRO_SIGMA, ACCEL_SIGMA = 0.0045, 0.0035
#: What the emulated receivers of the soak sent: the Leica's RTK σ [m] (ENU) and velocity
#: covariance [m²/s²] (vertical unknown); the ADU5's roll, pitch, yaw [deg] (its antenna
#: geometry on a level car: 1.5° from the level IMU) and their σ [rad].
FIX_SIGMA_ENU_M = np.array([0.014, 0.014, 0.03])
VELOCITY_COV = np.diag([0.05**2, 0.05**2, 1e6])
ADU5_RPY_DEG = (1.48, 1.14, 53.16)
ADU5_SIGMA_RAD = np.sqrt([1.75e-05, 5.97e-06, 1.49e-06])


def _node_config() -> FusionConfig:
    """What ins_fusion_node runs with: config/ins_fusion.yaml."""
    return FusionConfig.from_parameters(
        load_yaml(REPO / "config" / "ins_fusion.yaml", NODE_NAME, PARAMETERS)
    )


def _run(duration_s: float, seed: int) -> tuple[InsEngine, list[str], float]:
    """Feed the inconsistent inputs; returns the engine, the faults of unpublishable solutions
    (one per second checked) and the largest |gyro bias| estimate [rad/s]."""
    rng = np.random.default_rng(seed)
    engine = InsEngine(_node_config())
    quat = Rotation.from_euler("xyz", ADU5_RPY_DEG, degrees=True).as_quat()
    faults: list[str] = []
    largest_bias = 0.0
    n = int(duration_s * IMU_RATE_HZ)
    rates = rng.normal(0.0, GYRO_SIGMA, (n, 3))
    forces = rng.normal(0.0, ACCEL_SIGMA, (n, 3)) + np.array([0.0, 0.0, 9.81])
    next_fix, next_attitude = 0.0, 0.0
    for i in range(n):
        t = i / IMU_RATE_HZ
        if t >= next_attitude:  # the ADU5 at 5 Hz
            engine.add_attitude(AttitudeMeasurement(t, quat, np.diag(ADU5_SIGMA_RAD**2)))
            next_attitude += 0.2
        if t >= next_fix:  # the Leica at 1 Hz, RTK fixed
            east, north, up = VELOCITY_ENU * t + rng.normal(0.0, FIX_SIGMA_ENU_M)
            lat, lon, height = pymap3d.enu2geodetic(east, north, up, *DATUM)
            engine.add_gnss_fix(
                GnssFixMeasurement(t, lat, lon, height, np.diag(FIX_SIGMA_ENU_M**2))
            )
            engine.add_gnss_velocity(GnssVelocityMeasurement(t, VELOCITY_ENU, VELOCITY_COV))
            next_fix += 1.0
            row = engine.solution_row()
            if row is not None:
                if fault := row_fault(row):
                    faults.append(FAULTS[fault])
                largest_bias = max(largest_bias, float(np.abs(row[GYRO]).max()))
        engine.add_imu(t, rates[i], forces[i])
    return engine, faults, largest_bias


#: An hour: without the bound, seed 1 overflowed (a reset for a non-finite covariance, the gyro
#: bias at 331 rad/s) and seed 2 held a gyro bias of 0.12 rad/s, 7σ of the datasheet's.
HOUR_S = 3600.0


def _prior_gyro_bias_sigma(engine: InsEngine) -> float:
    """The datasheet's gyro bias σ [rad/s]: turn-on and instability (no calibration)."""
    noise = engine.config.imu_noise
    return math.hypot(noise.gyro_turn_on_bias, max(noise.gyro_bias_instability))


@pytest.mark.parametrize("seed", [1, 2])
def test_an_imu_at_rest_under_a_moving_antenna_never_overflows(seed):
    engine, faults, largest_bias = _run(HOUR_S, seed)
    status = engine.status()
    assert faults == []
    assert status.resets == 0, status.last_reset_reason
    assert status.measurements["gnss_position"]["recoveries"] > 100  # the inputs do disagree
    prior_sigma = _prior_gyro_bias_sigma(engine)
    assert largest_bias < 2.0 * prior_sigma  # not hundreds of rad/s
    covariance = engine.covariance
    assert covariance is not None
    assert np.diagonal(covariance)[BG : BG + 3].max() <= prior_sigma**2


def test_without_the_bound_the_same_inputs_overflow(monkeypatch):
    """The scenario is hard enough to show the failure: the fading unbounded, as before."""
    monkeypatch.setattr(eskf, "faded_covariance", lambda P, factor, _ceiling: P * factor)
    engine, _, largest_bias = _run(HOUR_S, 1)
    assert engine.status().resets > 0 or largest_bias > 2.0 * _prior_gyro_bias_sigma(engine)
