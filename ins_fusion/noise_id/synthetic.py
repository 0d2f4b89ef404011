"""Static records of a simulated IMU and their bags: known noise for the tests, the benchmark and
trying ``gnss_ins allan`` without a unit.

The truth is the simulator's survey car standing still at the Aalborg start (ins_fusion.sim:
earth rate and normal gravity in imu_link, docs/simulator.md); the errors are an ImuErrorModel of
any profile, sampled at any rate (its noise is stored as densities, so a record at 10 Hz has the
same Allan deviation as one at the profile's rate for τ well above the sample period). Bags hold
imu/data_raw as the driver publishes it (ins_fusion.bags.imu), stamped k/rate after start_ns and
logged a packet's transmission time later, like ``gnss_ins simulate``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S
from ins_fusion.bags.imu import ImuRecord, write_imu_bag
from ins_fusion.bags.topics import IMU_DATA
from ins_fusion.sim.drive import DEFAULT_START_NS
from ins_fusion.sim.imu_model import ImuErrorModel, ImuProfile
from ins_fusion.sim.route import Route
from ins_fusion.sim.scenarios import AALBORG_START, SURVEY_CAR
from ins_fusion.sim.vehicle import VehicleTruth

#: Samples simulated at a time (bounds the error model's temporaries).
_BLOCK = 200_000
_TRANSMISSION_NS = round(PACKET_TRANSMISSION_S * 1e9)


def static_record(
    profile: ImuProfile,
    duration_s: float,
    rate_hz: float | None = None,
    seed: int = 0,
    band_limited: bool = False,
    start_ns: int = DEFAULT_START_NS,
) -> ImuRecord:
    """duration_s [s] of a resting unit of ``profile`` sampled at rate_hz (default: the
    profile's rate), samples k / rate_hz after ``start_ns``."""
    rate = profile.rate_hz if rate_hz is None else rate_hz
    n = round(duration_s * rate)
    # Standing still, the truth is the same at every time: one second of route gives it.
    vehicle = VehicleTruth(Route(AALBORG_START).stand(1.0).build(), SURVEY_CAR)
    rate_truth, force_truth = vehicle.imu_truth(0.0)
    model = ImuErrorModel(profile, seed, band_limited)
    t = np.arange(n) / rate
    # One sample before the record, dropped: the model takes its first interval as the
    # profile's period, which at another rate would make the first sample an outlier.
    model.apply(t[:1] - 1.0 / rate, rate_truth[None, :], force_truth[None, :])
    gyro = np.empty((n, 3))
    accel = np.empty((n, 3))
    for start in range(0, n, _BLOCK):
        block = t[start : start + _BLOCK]
        ones = np.ones((len(block), 1))
        gyro[start : start + len(block)], accel[start : start + len(block)] = model.apply(
            block, ones * rate_truth, ones * force_truth
        )
    return ImuRecord(t, gyro, accel, start_ns=start_ns)


def write_static_bag(
    path: Path, record: ImuRecord, topic: str = IMU_DATA, storage: str = "mcap"
) -> None:
    """A bag with the record on ``topic`` as ``gnss_ins simulate`` times the driver's messages:
    stamped at the record's times, logged a packet's transmission time later.

    The stamps are ``start_ns + round(t·1e9)`` summed in float64, i.e. rounded to the 256-ns
    steps of float64 at today's epoch times: the bags of the tests, the benchmark and
    docs/allan.md were made so, and the Allan fit of a short record can flip with 100 ns."""
    stamps = (record.start_ns + np.rint(record.t_s * 1e9)).astype(np.int64)
    write_imu_bag(
        path, record, topic=topic, delay_ns=_TRANSMISSION_NS, storage=storage, stamps_ns=stamps
    )
