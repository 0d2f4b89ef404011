"""The messages of one IMU sample, for imu400cc_node and ``gnss_ins redecode`` alike (no ROS).

``sample_messages`` fills message objects: ``new_imu`` and ``new_temperature`` make empty ones,
rclpy's classes or rosbags' (``ins_fusion.bags.messages.new_message``), and
``gnss_ins_common.message_fields`` sets their fields either way. The node publishes the same
messages serialized (``SampleWriter``): templates made by ``sample_messages`` and serialized
once, with each sample's stamp and numbers written into them in place
(``gnss_ins_common.cdr_messages``), so a redecoded message is still the node's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from gnss_ins_common.cdr_messages import CDR_HEADER, ImuWriter, SerializedMessage
from gnss_ins_common.message_fields import fill_imu, fill_temperature, stamp_ns
from imu400cc_driver.axes import ImuMeasurement
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


class SampleWriter:
    """``sample_messages`` of each sample as serialized messages (CDR bytes)."""

    def __init__(
        self,
        driver: ImuDriver,
        frame_id: str,
        new_imu: Callable[[], Any],
        new_temperature: Callable[[], Any],
        serialize: Callable[[Any], bytes],
    ) -> None:
        """Templates of ``driver``'s messages in ``frame_id``: ``sample_messages`` of a zero
        sample with a temperature, ``serialize``d."""
        zero = np.zeros(3)
        sample = ImuSample(0.0, ImuMeasurement(zero, zero, 0.0, 0), with_temperature=True)
        imu, temperature = sample_messages(sample, driver, frame_id, new_imu, new_temperature)
        self._imu = ImuWriter(serialize(imu))
        self._temperature = SerializedMessage(serialize(temperature), CDR_HEADER, 2)

    def write(self, sample: ImuSample) -> tuple[bytes, bytes | None]:
        """imu/data_raw of ``sample`` and, on the samples that carry it, imu/temperature (else
        None), serialized."""
        stamp = stamp_ns(sample.stamp_s)
        meas = sample.measurement
        imu = self._imu.write(stamp, meas.rate_flu_rad_s, meas.specific_force_flu_m_s2)
        if not sample.with_temperature:
            return imu, None
        values = (meas.temperature_c, TEMPERATURE_VARIANCE_C2)
        return imu, self._temperature.write(stamp, values)
