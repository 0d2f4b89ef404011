"""imu400cc_node's Python work per packet, in one process: what its serial thread runs for each
18-byte packet of a 134 Hz stream before the DDS publish. Prints µs per packet, asserts nothing.

Fed one packet per read (as the node reads them live): the driver core (``ImuDriver.feed``:
framer, device clock, conversion) and its parts, the read's stamp on the node's ROS clock, the
serialized messages the node publishes (``SampleWriter.write``) against the Python messages it
built before (``sample_messages`` with rclpy's classes), and ``publish`` on a publisher without
subscribers, of the bytes and of a Python message (which rclpy converts to its C message
first). Each is the best of five passes over the stream; a warm process, so a lower bound of
the live cost.

    .venv/bin/python bench/bench_imu_packet.py [--packets 20000]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import rclpy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, Temperature

from gnss_ins_common.rates import IMU400CC_RATE_HZ
from gnss_ins_common.ros_serial import node_time_s
from imu400cc_driver.axes import PacketConverter, measurement_to_packet
from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S
from imu400cc_driver.driver import DriverConfig, ImuDriver, ImuSample
from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.messages import SampleWriter, sample_messages
from imu400cc_driver.protocol import encode_packet, unpack_packet

#: Device timer counts between two packets at 134 Hz (the emulator's default unit).
TIMER_STEP = 9330
START_S = 1.7e9


def stream(count: int) -> list[bytes]:
    """``count`` packets of a unit at rest with noise, as the device sends them."""
    config = DriverConfig()
    rng = np.random.default_rng(0)
    packets, timer = [], 41606
    for _ in range(count):
        rate = rng.normal(0.0, 0.004, 3)
        force = np.array([0.0, 0.0, 9.80665]) + rng.normal(0.0, 0.003, 3)
        raw = measurement_to_packet(
            rate, force, 25.0, timer, config.scaling, config.axis_map, config.accel_sign
        )
        packets.append(encode_packet(raw))
        timer = (timer - TIMER_STEP) % 65536
    return packets


def per_item_us(make_run: Callable[[], Callable[[Any], object]], items: Sequence[Any]) -> float:
    """Best of five passes of a fresh ``make_run()`` over ``items`` [µs per item]."""
    best = float("inf")
    for _ in range(5):
        run = make_run()
        start = time.perf_counter()
        for item in items:
            run(item)
        best = min(best, time.perf_counter() - start)
    return best / len(items) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--packets", type=int, default=20_000)
    args = parser.parse_args()
    packets = stream(args.packets)
    reads = [
        (packet, START_S + k / IMU400CC_RATE_HZ + PACKET_TRANSMISSION_S)
        for k, packet in enumerate(packets)
    ]
    config = DriverConfig()
    driver = ImuDriver(config)
    samples = [sample for read in reads for sample in driver.feed(*read)]
    raws = [unpack_packet(packet) for packet in packets]
    convert = PacketConverter(
        config.scaling, config.axis_map, config.accel_sign, config.gravity_m_s2
    )

    rclpy.init()
    node = rclpy.create_node("bench_imu_packet")
    publisher = node.create_publisher(Imu, "bench_imu_packet/imu", 10)
    writer = SampleWriter(driver, "imu_link", Imu, Temperature, serialize_message)
    imu_bytes = writer.write(samples[0])[0]
    imu_message = sample_messages(samples[0], driver, "imu_link", Imu, Temperature)[0]

    def feeding() -> Callable[[tuple[bytes, float]], object]:
        fed = ImuDriver(config)  # a new driver each pass: its clock needs increasing times
        return lambda read: fed.feed(*read)

    def python_messages(sample: ImuSample) -> object:
        return sample_messages(sample, driver, "imu_link", Imu, Temperature)

    rows = [
        ("ImuDriver.feed (framer, clock, conversion)", feeding, reads),
        ("  framer", lambda: PacketFramer(confirm_with_next_packet=True).feed, packets),
        ("  conversion", lambda: convert, raws),
        ("read stamp on the ROS clock (node_time_s)", lambda: lambda _: node_time_s(node), reads),
        ("serialized messages (SampleWriter.write)", lambda: writer.write, samples),
        ("Python messages (sample_messages, before)", lambda: python_messages, samples),
        ("publish(bytes), no subscriber", lambda: lambda _: publisher.publish(imu_bytes), reads),
        (
            "publish(Imu): conversion + publish (before)",
            lambda: lambda _: publisher.publish(imu_message),
            reads,
        ),
    ]
    print(f"imu400cc_node's Python work per packet, {len(packets)} packets, best of 5 [µs]")
    for name, make_run, items in rows:
        print(f"  {name:<46} {per_item_us(make_run, items):7.2f}")
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
