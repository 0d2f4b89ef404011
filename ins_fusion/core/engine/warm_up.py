"""Readying the engine's compiled kernels (core.compiled) before the first IMU sample.

numba compiles a kernel at its first call (once per install, ~30 s for all of them, then from
its on-disk cache in ~0.3 s). ``warm_up`` makes those first calls with the argument types the
engine passes, so that neither happens on a live sample: InsEngine calls it when it is built,
``make venv`` once after the install. A kernel called later with other argument types would
compile again (test_compiled.py checks that a drive adds no signature).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ins_fusion.core.engine.intake import new_intake, record_sample, take_sample
from ins_fusion.core.engine.sample_runs import STEPS_PER_RUN, advance_run, take_run
from ins_fusion.core.filter.adaptation import ImuNoiseMonitor
from ins_fusion.core.filter.eskf import ErrorStateFilter, StateLayout, projected_variance
from ins_fusion.core.filter.propagation import advance, covariance_step, predicted_state
from ins_fusion.core.filter.records import GnssFixMeasurement, GnssVelocityMeasurement, Prediction
from ins_fusion.core.filter.state import X_COV_DT, X_SIZE, FilterState, Geometry, inject_nominal
from ins_fusion.core.measurements.attitude import attitude_apply
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.measurements.gnss_position import position_apply
from ins_fusion.core.measurements.gnss_velocity import velocity_apply
from ins_fusion.core.measurements.models import (
    attitude,
    gnss_position,
    gnss_velocity,
    nhc,
    zaru,
    zupt,
)
from ins_fusion.core.measurements.nhc import nhc_apply
from ins_fusion.core.measurements.stationary import zaru_apply, zupt_apply
from ins_fusion.core.measurements.stop_detector import StopDetector, window_statistics
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.strapdown import INCREMENT_SIZE, NavState, SampleIntegrator, increment
from ins_fusion.core.output.output_numbers import NUMBERS, output_numbers
from ins_fusion.core.output.solution import WIDTH, SolutionBuilder
from ins_fusion.core.settings.config import FusionConfig

_ready = False


def warm_up() -> float:
    """Compile or load every kernel once per process; returns the seconds it took (0 when
    done already)."""
    global _ready
    if _ready:
        return 0.0
    start = time.perf_counter()
    config = FusionConfig.from_parameters({})
    layout = StateLayout(True, True, True, True, True, True)  # every block: every branch typed
    zero = (0.0, 0.0, 0.0)
    nav = NavState(1.0, 0.2, 40.0, np.zeros(3), np.array((0.0, 0.0, 0.0, 1.0)))
    s = FilterState(0.0, nav, zero, True)
    integrator = SampleIntegrator()
    integrator.push(0.0, zero, (0.0, 0.0, -9.8))
    detector = StopDetector(config.stop_detector, np.eye(3))
    detector.push(0.0, zero, (0.0, 0.0, -9.8))
    window_statistics(detector.ring, np.eye(3))
    monitor = ImuNoiseMonitor()
    intake = new_intake(10.0, 100.0, True)
    table = ImuCalibration().table
    r_bi = np.eye(3).ravel()
    stores = (intake, table, integrator.buffer, detector.ring, monitor.block, s.x, r_bi)
    for t in (0.0, 0.01):  # the first sample, then an interval with the calibration
        take_sample(*stores, np.empty(INCREMENT_SIZE), t, *zero, *zero, True)
    record_sample(intake, detector.ring, monitor.block, 0.02)
    advance(s.x, increment(0.01, zero, (0.0, 0.0, -0.098)), np.eye(3).ravel(), False, 0.01)
    kf = ErrorStateFilter(layout, config.imu_noise, config.gnss_correlation_time_s or 60.0)
    kf.P = np.eye(layout.size) * 1e-2
    s.x[X_COV_DT] = 0.01
    geometry_of = Geometry(config, layout)
    mat_bi = geometry_of.mat_bi
    kf.P, kf.phi = covariance_step(kf.P, s.x, mat_bi, kf.process_model(), layout.columns, 60.0)
    kf.update(np.zeros(3), np.eye(3, layout.size), np.eye(3), math.inf)
    constants = (60.0, 0.1, math.inf, layout.size)
    geometry = (mat_bi, np.zeros(3))
    nhc_apply(kf.P, s.x, 0.015, kf.process_model(), geometry, layout.columns, constants)
    zupt_apply(kf.P, s.x, 0.015, kf.process_model(), mat_bi, layout.columns, constants)
    rest, gate = (0.015, np.zeros(3), np.ones(3)), (60.0, 1.0, layout.size)
    zaru_apply(kf.P, s.x, rest, kf.process_model(), mat_bi, layout.columns, gate)
    measured = (0.015, np.zeros(3), np.eye(3))
    gates = (60.0, (1.0, 1.0, 1.0), layout.size)
    velocity_apply(kf.P, s.x, measured, kf.process_model(), geometry, layout.columns, gates)
    attitude_apply(
        kf.P,
        s.x,
        (0.015, (0.0, 0.0, 0.0, 1.0), np.eye(3)),
        kf.process_model(),
        (mat_bi, geometry_of.q_a_base),
        layout.columns,
        gates,
    )
    gnss_noise = GnssNoise(config, layout)
    gnss_noise.set_correlated_variance(s, kf, np.ones(3))
    position_apply(
        kf.P,
        s.x,
        s.gnss_white.values.copy(),
        (0.015, 1.0, 0.2, 40.0, np.eye(3)),
        kf.process_model(),
        geometry,
        layout.columns,
        gnss_noise.settings(s),
        (60.0, 1.0, layout.size),
    )
    kf.problem()
    inject_nominal(s.x, np.zeros(layout.size), layout.columns)
    prediction = Prediction(*predicted_state(s.x, 0.015), layout=layout)
    nhc(prediction, np.zeros(3), np.eye(3), 0.1, (0.0, 0.0))
    attitude(prediction, np.eye(3), np.eye(3), 0.0, (0.0, 0.0))
    zupt(prediction, 0.1)
    zaru(prediction, (np.zeros(3), s.x[:3]), mat_bi, np.ones(3), True)
    fix = GnssFixMeasurement(0.015, 57.0, 10.0, 40.0, np.eye(3))
    white, _, reported, _ = GnssNoise(config, layout).position_noise(s, fix)
    z, H, _ = gnss_position(prediction, fix, np.zeros(3), white, zero)
    predicted = projected_variance(H, kf.P)
    s.gnss_white.pushed_fix(0.015, z, H, None, kf.P, predicted, reported)
    gnss_velocity(prediction, GnssVelocityMeasurement(0.015, np.zeros(3), np.eye(3)), z, np.eye(3))
    output = SolutionBuilder(geometry_of, layout)
    row = output.row(s, kf, (57.0, 10.0, 40.0), np.zeros(3), "navigating")
    output_numbers(row, 1e-5, np.empty(NUMBERS))
    model = output.model(s, kf, (57.0, 10.0, 40.0))
    series = (np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1, dtype=np.bool_))
    limits = (0.0, math.inf, math.inf, 0.01, 1.0)
    advance_run(s.x, np.zeros((0, INCREMENT_SIZE)), np.zeros(0), r_bi, 0.01, np.empty((0, X_SIZE)))
    (J, P, states, arm_b, arm_bi, plane), _, origin = model
    take_run(
        stores[:6],
        r_bi,
        series,
        (0, 0),
        limits,
        (
            np.empty((1, INCREMENT_SIZE)),
            np.empty((1, X_SIZE)),
            np.empty((1, WIDTH)),
            np.empty(1, dtype=np.int64),
            np.empty((1, 7)),
        ),
        (J, P, states, arm_b, arm_bi, plane),
        origin,
        (mat_bi, kf.process_model(), (config.imu_noise.gyro_psd, config.imu_noise.accel_psd)),
        (layout.columns, 60.0, 0.1, math.inf, layout.size),
        (0.1, 0.5, 1.0, True, True),
        (
            np.empty(1, dtype=np.int64),
            np.empty((STEPS_PER_RUN, *kf.P.shape)),
            np.empty(kf.P.shape),
            np.empty((2, 3)),
            np.empty((1, 3)),
            np.array([math.inf, math.nan]),
        ),
    )
    assert s.x.shape == (X_SIZE,)
    _ready = True
    return time.perf_counter() - start
