"""adapters.cdr_out: ins_fusion_node's serialized outputs decode, with rclpy's own deserializer,
to the messages the fill functions make of the same solution (what the node published before)."""

from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, NavSatFix
from tf2_msgs.msg import TFMessage

from gnss_ins_common.message_fields import fill_orientation, stamp_ns
from ins_fusion.adapters.solution_out import fill_fused_fix, fill_odometry
from ins_fusion.core.engine.engine import InsSolution
from ins_fusion.core.output.solution_rows import COV_VEL, LAT, pack
from ins_fusion.node import output_writer

RATE_VARIANCE = 3.3e-6


def _covariance(rng: np.random.Generator, scale: float) -> np.ndarray:
    a = rng.normal(size=(3, 3)) * scale
    return a @ a.T + np.eye(3) * scale**2


def _solution(rng: np.random.Generator, t_s: float, state: str) -> InsSolution:
    return InsSolution(
        t_s=t_s,
        lat_deg=float(rng.uniform(-80.0, 80.0)),
        lon_deg=float(rng.uniform(-180.0, 180.0)),
        height_m=float(rng.uniform(-50.0, 3000.0)),
        pos_enu_m=rng.normal(size=3) * 100.0,
        vel_enu_m_s=rng.normal(size=3) * 10.0,
        quat_enu_flu_xyzw=Rotation.random(random_state=rng).as_quat(),
        rate_flu_rad_s=rng.normal(size=3) * 0.1,
        cov_pos_enu_m2=_covariance(rng, 0.1),
        cov_vel_enu=_covariance(rng, 0.01),
        cov_att_enu_rad2=_covariance(rng, 1e-3),
        gyro_bias_flu_rad_s=np.zeros(3),
        accel_bias_flu_m_s2=np.zeros(3),
        state=state,
    )


def _expected_imu(solution: InsSolution, odometry: Odometry) -> Imu:
    """ins/imu as the node filled it: orientation, bias-corrected rate, its noise variance."""
    imu = fill_orientation(
        Imu(),
        stamp_ns(solution.t_s),
        "base_link",
        solution.quat_enu_flu_xyzw,
        solution.cov_att_enu_rad2.ravel(),
    )
    w = odometry.twist.twist.angular
    imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = w.x, w.y, w.z
    imu.angular_velocity_covariance = np.eye(3).ravel() * RATE_VARIANCE
    return imu


def _expected_transform(odometry: Odometry) -> TFMessage:
    transform = TransformStamped(header=odometry.header, child_frame_id=odometry.child_frame_id)
    p, t = odometry.pose.pose.position, transform.transform.translation
    t.x, t.y, t.z = p.x, p.y, p.z
    transform.transform.rotation = odometry.pose.pose.orientation
    return TFMessage(transforms=[transform])


@pytest.mark.parametrize("map_frame", ["map", "odom", "vehicle_1/local_enu_frame"])
def test_serialized_outputs_equal_the_filled_messages(map_frame):
    rng = np.random.default_rng(len(map_frame))
    writer = output_writer(map_frame, "base_link", RATE_VARIANCE)
    # Stamps with sub-ns fractions and one a rounding error below a whole second.
    stamps = (1_717_236_000.123456789, 1_717_236_000.99999999995, 12.5, 0.0)
    for i, t_s in enumerate(stamps):
        solution = _solution(rng, t_s, "aligning" if i % 2 else "navigating")
        outputs = writer.write(pack(solution))
        assert outputs is not None
        odometry = fill_odometry(Odometry(), solution, map_frame, "base_link", RATE_VARIANCE)
        assert deserialize_message(outputs.odometry, Odometry) == odometry
        fix = fill_fused_fix(NavSatFix(), solution, "base_link")
        assert deserialize_message(outputs.fix, NavSatFix) == fix
        assert deserialize_message(outputs.imu, Imu) == _expected_imu(solution, odometry)
        assert deserialize_message(outputs.transform, TFMessage) == _expected_transform(odometry)


@pytest.mark.parametrize(
    ("column", "value"), [(LAT, np.nan), (COV_VEL.start, -1.0), (COV_VEL.start + 1, 1.0)]
)
def test_a_row_that_is_not_publishable_gives_no_messages(column, value):
    writer = output_writer("map", "base_link", RATE_VARIANCE)
    row = pack(_solution(np.random.default_rng(3), 5.0, "navigating"))
    assert writer.write(row) is not None
    row[column] = value  # NaN latitude, negative variance, asymmetric covariance
    assert writer.write(row) is None
