"""The messages of one IMU sample, for imu400cc_node and ``gnss_ins redecode`` alike (no ROS).

``new_imu`` and ``new_temperature`` make empty messages: rclpy's classes in the node, rosbags'
(``ins_fusion.bags.messages.new_message``) offline; the fields are set by
``gnss_ins_common.message_fields`` either way, so a redecoded message is the node's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from gnss_ins_common.message_fields import fill_imu, fill_temperature, stamp_ns
from imu400cc_driver.driver import ImuDriver, ImuSample
from imu400cc_driver.protocol import TEMPERATURE_VARIANCE_C2


def sample_messages(
    sample: ImuSample,
    driver: ImuDriver,
    frame_id: str,
    new_imu: Callable[[], Any],
    new_temperature: Callable[[], Any],
) -> tuple[Any, Any | None]:
    """imu/data_raw of ``sample`` (covariances from ``driver``) and, on the samples that carry
    it, imu/temperature (else None)."""
    stamp = stamp_ns(sample.stamp_s)
    meas = sample.measurement
    imu = fill_imu(
        new_imu(),
        stamp,
        frame_id,
        meas.rate_flu_rad_s,
        meas.specific_force_flu_m_s2,
        driver.gyro_variance,
        driver.accel_variance,
    )
    if not sample.with_temperature:
        return imu, None
    temperature = fill_temperature(
        new_temperature(), stamp, frame_id, meas.temperature_c, TEMPERATURE_VARIANCE_C2
    )
    return imu, temperature
