"""Readying the engine's compiled kernels (core.compiled) before the first IMU sample.

numba compiles a kernel at its first call (once per install, ~30 s for all of them, then from
its on-disk cache in ~0.3 s), for the argument types of that call. ``warm_up`` makes those
first calls through the engine's own code, so that neither happens on a live sample and no
kernel's arguments are written out a second time: a short synthetic drive (``synthetic_drive``:
a standstill, a start, a drive, late GNSS data and an IMU gap) through two engines, one with
every optional error state (the vehicle speed's too) and the smoother's history attached
(every update the general way, sample by sample) and one with the defaults fed as a replay
feeds it (compiled runs, the fused updates, re-propagations), and the output kernel on a row of
each. Building an engine does not call it: the node calls it before it builds its engine, a
replay before its first engine (ins_fusion.replay.run.run_fusion), ``make venv`` once after the
install; an engine used without it compiles each kernel at its first call. A kernel called
later with other argument types would compile again (test_compiled.py checks that a drive adds
no signature).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.engine.smoothed_solution import attach_history
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    VehicleSpeedMeasurement,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2
from ins_fusion.core.output.output_numbers import NUMBERS, output_numbers
from ins_fusion.core.output.solution_rows import RowBuffer
from ins_fusion.core.settings.config import FusionConfig

#: The synthetic drive (``synthetic_drive``): IMU and GNSS rates [Hz], how late the GNSS data
#: arrive [s], the standstill, acceleration and cruise [s], the forward acceleration [m/s²].
_IMU_HZ, _GNSS_HZ, _GNSS_LATENCY_S = 100.0, 10.0, 0.05
_STILL_S, _ACCELERATE_S, _CRUISE_S, _ACCEL_M_S2 = 3.0, 2.0, 2.0, 2.0
#: Samples left out in the cruise: an IMU gap the engine bridges.
_GAP_SAMPLES = 3
#: Where the drive starts: latitude, longitude [deg], height [m].
_ORIGIN = (57.0, 10.0, 40.0)
#: Parameters of the two engines: a short levelling for both; every optional error state.
_QUICK = {"alignment.duration": 1.0}
_EVERY_STATE = {
    **_QUICK,
    "self_calibration.mounting": True,
    "self_calibration.time_offset": True,
    "imu_noise.gyro_scale_sigma": 0.001,
    "imu_noise.accel_scale_sigma": 0.001,
    "imu_noise.gyro_asymmetry_sigma": 0.001,
    "speed.use": True,
}

#: A measurement of the drive.
Measurement = (
    GnssFixMeasurement | GnssVelocityMeasurement | AttitudeMeasurement | VehicleSpeedMeasurement
)

_ready = False


def warm_up() -> float:
    """Compile or load every kernel once per process; returns the seconds it took (0 when
    done already)."""
    global _ready
    if _ready:
        return 0.0
    _ready = True
    start = time.perf_counter()
    try:
        _drive_engines()
    except BaseException:
        _ready = False
        raise
    return time.perf_counter() - start


def _drive_engines() -> None:
    """The synthetic drive through both engines (module docstring) and the output kernel."""
    imu, measurements = synthetic_drive()
    for parameters, smooth in ((_EVERY_STATE, True), (_QUICK, False)):
        config = FusionConfig.from_parameters(parameters)
        engine = InsEngine(config)
        if smooth:
            attach_history(engine)
        rows = RowBuffer()
        start = 0
        for index, measurement in measurements:
            engine.add_imu_series(*imu, (start, index), rows)
            if isinstance(measurement, GnssFixMeasurement):
                engine.add_gnss_fix(measurement)
            elif isinstance(measurement, GnssVelocityMeasurement):
                engine.add_gnss_velocity(measurement)
            elif isinstance(measurement, AttitudeMeasurement):
                engine.add_attitude(measurement)
            elif config.use_speed:
                engine.add_vehicle_speed(measurement)
            start = index
        engine.add_imu_series(*imu, (start, len(imu[0])), rows)
        row = engine.solution_row()
        assert row is not None  # the filter runs from the standstill on
        output_numbers(row, 1e-6, np.empty(NUMBERS))  # as the node and a fused bag call it


def synthetic_drive() -> tuple[
    tuple[FloatArray, FloatArray, FloatArray, BoolArray], list[tuple[int, Measurement]]
]:
    """A level vehicle facing east: a standstill, a forward acceleration and a cruise. Returns
    the IMU samples (stamps [s], rates [rad/s] and specific forces [m/s²] imu_link FLU, output
    ticks) and the GNSS fixes, velocities, attitudes and vehicle speeds each with the index of
    the IMU sample before which it arrives."""
    n = round((_STILL_S + _ACCELERATE_S + _CRUISE_S) * _IMU_HZ)
    t_s = np.arange(n) / _IMU_HZ
    accelerating = (t_s >= _STILL_S) & (t_s < _STILL_S + _ACCELERATE_S)
    force = np.zeros((n, 3))
    force[:, 0] = np.where(accelerating, _ACCEL_M_S2, 0.0)
    force[:, 2] = STANDARD_GRAVITY_M_S2
    gap = n - round(_CRUISE_S * _IMU_HZ / 2)
    kept = np.ones(n, dtype=np.bool_)
    kept[gap : gap + _GAP_SAMPLES] = False
    ticks = np.arange(n) % 2 == 0
    imu = (t_s[kept], np.zeros((int(kept.sum()), 3)), force[kept], ticks[kept])
    measurements = [
        (int(np.searchsorted(imu[0], t + _GNSS_LATENCY_S)), measurement)
        for t in np.arange(0.0, t_s[-1] - _GNSS_LATENCY_S, 1.0 / _GNSS_HZ)
        for measurement in _epoch(float(t))
    ]
    return imu, measurements


def _epoch(t: float) -> Iterator[Measurement]:
    """The fix, velocity, attitude and vehicle speed of the drive at ``t`` [s]."""
    moving = min(max(t - _STILL_S, 0.0), _ACCELERATE_S)
    speed = _ACCEL_M_S2 * moving
    east = 0.5 * _ACCEL_M_S2 * moving**2 + speed * max(t - _STILL_S - _ACCELERATE_S, 0.0)
    lat, lon, height = earth.displace(
        math.radians(_ORIGIN[0]), math.radians(_ORIGIN[1]), _ORIGIN[2], 0.0, east, 0.0
    )
    yield GnssFixMeasurement(
        t, math.degrees(lat), math.degrees(lon), height, np.diag([0.01, 0.01, 0.04])
    )
    yield GnssVelocityMeasurement(t, np.array([speed, 0.0, 0.0]), np.eye(3) * 1e-4)
    yield AttitudeMeasurement(t, np.array([0.0, 0.0, 0.0, 1.0]), np.eye(3) * 1e-4)
    yield VehicleSpeedMeasurement(t, speed, 1e-4)
