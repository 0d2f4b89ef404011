"""imu400cc_driver.messages: the serialized messages imu400cc_node publishes decode, with
rclpy's own deserializer, to the messages ``sample_messages`` fills of the same samples."""

from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, Temperature

from imu400cc_driver.axes import ImuMeasurement
from imu400cc_driver.driver import DriverConfig, ImuDriver, ImuSample
from imu400cc_driver.messages import SampleWriter, sample_messages


@pytest.mark.parametrize("frame_id", ["imu_link", "vehicle_1/imu_link"])
def test_serialized_samples_equal_the_filled_messages(frame_id):
    rng = np.random.default_rng(len(frame_id))
    config = DriverConfig(
        gyro_noise_density=(1e-4, 2e-4, 3e-4), accel_noise_density=(4e-4, 5e-4, 6e-4)
    )
    driver = ImuDriver(config)
    writer = SampleWriter(driver, frame_id, Imu, Temperature, serialize_message)
    # Stamps with sub-ns fractions and one a rounding error below a whole second.
    stamps = (1_717_236_000.123456789, 1_717_236_000.99999999995, 12.5, 0.0)
    for i, stamp_s in enumerate(stamps):
        measurement = ImuMeasurement(
            rng.normal(size=3), rng.normal(size=3) * 10.0, float(rng.uniform(-40, 85)), i
        )
        sample = ImuSample(stamp_s, measurement, with_temperature=i % 2 == 1)
        imu, temperature = writer.write(sample)
        expected_imu, expected_temperature = sample_messages(
            sample, driver, frame_id, Imu, Temperature
        )
        assert deserialize_message(imu, Imu) == expected_imu
        if expected_temperature is None:
            assert temperature is None
        else:
            assert temperature is not None
            assert deserialize_message(temperature, Temperature) == expected_temperature
