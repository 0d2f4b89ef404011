"""The comma2k19 fixture with the car's CAN speed (test/fixtures/comma2k19/README.md,
"/vehicle/speed"): the drive's messages unchanged, the speed on the bag's time base in
base_link, and a real speed — it agrees with the reference speed as an odometer does (a scale
error of under 1 %, a few cm/s of scatter). Figures: comma2k19_ex1_seg40_speed.verify.json."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from support.paths import FIXTURES

from gnss_ins_common.message_fields import UNKNOWN_VARIANCE
from ins_fusion.bags import topics as T  # noqa: N812
from ins_fusion.bags.bag_io import BagReader

FIXTURE = FIXTURES / "comma2k19"
BAG = FIXTURE / "comma2k19_ex1_seg40"
SPEED_BAG = FIXTURE / "comma2k19_ex1_seg40_speed"
SPEED = "/vehicle/speed"


def _stamp(message) -> int:
    return int(message.header.stamp.sec) * 1_000_000_000 + int(message.header.stamp.nanosec)


@pytest.fixture(scope="module")
def speed_bag() -> dict[str, list]:
    """topic -> [(log ns, deserialized message)] of the speed fixture."""
    out: dict[str, list] = {}
    with BagReader(SPEED_BAG) as reader:
        assert reader.topics[SPEED].msgtype == T.VELOCITY_TYPE
        for msg in reader.messages(deserialize=True):
            out.setdefault(msg.topic, []).append((msg.log_time_ns, msg.message))
    return out


def test_every_message_of_the_drive_is_kept_byte_for_byte():
    def raw(path: Path) -> list[tuple[str, int, bytes]]:
        with BagReader(path) as reader:
            return [
                (m.topic, m.log_time_ns, bytes(m.message))
                for m in reader.messages()
                if m.topic != SPEED
            ]

    original = raw(BAG)
    assert len(original) == 11014
    assert raw(SPEED_BAG) == original


def test_speed_is_forward_speed_in_base_link_on_the_bag_time_base(speed_bag):
    speed = speed_bag[SPEED]
    assert len(speed) == 4974  # every CAN sample of the segment
    imu_ns = [t for t, _ in speed_bag[T.IMU_DATA]]
    for log_ns, message in speed:
        assert _stamp(message) == log_ns
        assert message.header.frame_id == "base_link"
        twist = message.twist.twist
        assert (twist.linear.y, twist.linear.z) == (0.0, 0.0)
        cov = np.asarray(message.twist.covariance).reshape(6, 6)
        assert 0.02**2 < cov[0, 0] < 0.03**2  # the measured short-term scatter
        assert np.all(np.diag(cov)[1:] == UNKNOWN_VARIANCE)
        assert np.count_nonzero(cov - np.diag(np.diag(cov))) == 0
    stamps = np.array([t for t, _ in speed])
    assert np.all(np.diff(stamps) > 0)
    # The CAN samples span the IMU's minute (same boot clock, same mapping).
    assert abs(stamps[0] - imu_ns[0]) < 0.2e9 and abs(stamps[-1] - imu_ns[-1]) < 0.2e9


def test_can_speed_agrees_with_the_reference_speed_like_an_odometer(speed_bag):
    t_v = np.array([t for t, _ in speed_bag[SPEED]]) / 1e9
    v = np.array([m.twist.twist.linear.x for _, m in speed_bag[SPEED]])
    t_g = np.array([t for t, _ in speed_bag[T.TRUTH_VEL]]) / 1e9
    g = np.array(
        [math.dist((0.0, 0.0, 0.0), _xyz(m.twist.twist.linear)) for _, m in speed_bag[T.TRUTH_VEL]]
    )
    inside = (t_v > t_g[0]) & (t_v < t_g[-1])
    v, ref = v[inside], np.interp(t_v[inside], t_g, g)
    rms = float(np.sqrt(np.mean((v - ref) ** 2)))
    scale = float(v @ ref / (ref @ ref))
    after_scale = float(np.sqrt(np.mean((v / scale - ref) ** 2)))
    assert 0.05 < rms < 0.3
    assert 0.98 < scale < 1.0  # the car's speedometer reads low by under 2 %
    assert after_scale < 0.1
    verified = json.loads((FIXTURE / "comma2k19_ex1_seg40_speed.verify.json").read_text())
    figures = verified["vs_ground_truth_speed"]
    assert figures["rms_difference_m_s"] == pytest.approx(rms, rel=1e-9)
    assert figures["scale_can_over_reference"] == pytest.approx(scale, rel=1e-9)


def _xyz(vector) -> tuple[float, float, float]:
    return (vector.x, vector.y, vector.z)
