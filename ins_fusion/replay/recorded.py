"""Errors of a recorded fused output (/ins/fix, /ins/odometry of ins_fusion_node or of
``gnss_ins replay --output``) against the truth topics of a bag (/ground_truth/fix,
/ground_truth/attitude), for ``gnss_ins demo``'s table, report and figure.

Both are base_link: the fused position is compared with the truth interpolated at its stamps
(geodetic, then E/N/U of the fused point in the tangent plane at the truth point [m]); the yaw
of the odometry (FLU x axis from east, counter-clockwise, REP-103) with the truth's [deg].
Messages with a NavSatFix status below STATUS_FIX (the node while aligning) are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray
from ins_fusion.adapters.messages_in import stamp_s
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.bags.topics import INS_FIX, INS_ODOMETRY, TRUTH_ATTITUDE, TRUTH_FIX
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import wrap_angle
from ins_fusion.replay.metrics import map_enu


@dataclass(frozen=True)
class RecordedErrors:
    """Errors of one recorded output: ``t_s`` (n,) fix stamps [s], ``enu_m`` (n, 3) fused
    minus truth E, N, U [m]; ``yaw_t_s`` (m,) odometry stamps [s], ``yaw_deg`` (m,) fused minus
    truth yaw wrapped to [-180, 180); ``track_enu_m`` (n, 3) the fused positions in the tangent
    plane at ``datum`` (lat, lon [deg], h [m]: the first truth fix)."""

    t_s: FloatArray
    enu_m: FloatArray
    yaw_t_s: FloatArray
    yaw_deg: FloatArray
    track_enu_m: FloatArray
    datum: tuple[float, float, float]

    def summary(self) -> dict[str, float]:
        """Samples, horizontal RMS/95th percentile/maximum, vertical and yaw RMS [m, deg]."""
        horizontal = np.hypot(self.enu_m[:, 0], self.enu_m[:, 1])
        return {
            "samples": float(len(horizontal)),
            "horizontal_rms": float(np.sqrt(np.mean(horizontal**2))),
            "horizontal_p95": float(np.percentile(horizontal, 95)),
            "horizontal_max": float(horizontal.max()),
            "vertical_rms": float(np.sqrt(np.mean(self.enu_m[:, 2] ** 2))),
            "yaw_rms": float(np.sqrt(np.mean(self.yaw_deg**2))) if len(self.yaw_deg) else math.nan,
        }


def _fixes(reader: BagReader, topic: str) -> FloatArray:
    """(stamp [s], lat [deg], lon [deg], height [m]) of the fixes with a fix, (n, 4)."""
    if topic not in reader.topics:
        return np.zeros((0, 4))
    rows = [
        (stamp_s(m.message), m.message.latitude, m.message.longitude, m.message.altitude)
        for m in reader.messages([topic], deserialize=True)
        if m.message.status.status >= 0
    ]
    return np.array(rows, dtype=np.float64).reshape(-1, 4)


def _yaws(reader: BagReader, topic: str, odometry: bool) -> FloatArray:
    """(stamp [s], yaw of the FLU x axis from east [rad]) of an Odometry or Imu topic, (n, 2)."""
    if topic not in reader.topics:
        return np.zeros((0, 2))
    stamps, quats = [], []
    for m in reader.messages([topic], deserialize=True):
        q = m.message.pose.pose.orientation if odometry else m.message.orientation
        stamps.append(stamp_s(m.message))
        quats.append((q.x, q.y, q.z, q.w))
    if not quats:
        return np.zeros((0, 2))
    yaw = Rotation.from_quat(np.array(quats)).as_euler("ZYX")[:, 0]
    return np.column_stack([stamps, yaw])


def recorded_errors(fused_bag: Path, truth_bag: Path) -> RecordedErrors | None:
    """The errors of ``fused_bag``'s /ins/fix and /ins/odometry against ``truth_bag``'s truth
    inside the truth's time span; None when either has no fix there."""
    with BagReader(fused_bag) as reader:
        fused, fused_yaw = _fixes(reader, INS_FIX), _yaws(reader, INS_ODOMETRY, True)
    with BagReader(truth_bag) as reader:
        truth, truth_yaw = _fixes(reader, TRUTH_FIX), _yaws(reader, TRUTH_ATTITUDE, False)
    if len(truth) < 2:
        return None
    fused = fused[(fused[:, 0] >= truth[0, 0]) & (fused[:, 0] <= truth[-1, 0])]
    if len(fused) == 0:
        return None
    at = [np.interp(fused[:, 0], truth[:, 0], truth[:, k]) for k in (1, 2, 3)]
    enu = np.column_stack(
        [
            earth.geodetic_to_enu(
                np.radians(fused[i, 1]),
                np.radians(fused[i, 2]),
                fused[i, 3],
                math.radians(at[0][i]),
                math.radians(at[1][i]),
                at[2][i],
            )
            for i in range(len(fused))
        ]
    ).T
    datum = (float(truth[0, 1]), float(truth[0, 2]), float(truth[0, 3]))
    track = map_enu(fused[:, 1:4], datum)
    yaw_t, yaw_err = np.zeros(0), np.zeros(0)
    if len(truth_yaw) >= 2 and len(fused_yaw):
        inside = (fused_yaw[:, 0] >= truth_yaw[0, 0]) & (fused_yaw[:, 0] <= truth_yaw[-1, 0])
        yaw_t = fused_yaw[inside, 0]
        reference = np.interp(yaw_t, truth_yaw[:, 0], np.unwrap(truth_yaw[:, 1]))
        yaw_err = np.degrees(wrap_angle(fused_yaw[inside, 1] - reference))
    return RecordedErrors(fused[:, 0], enu, yaw_t, yaw_err, track, datum)


def truth_track(truth_bag: Path, datum: tuple[float, float, float]) -> FloatArray:
    """The truth positions of ``truth_bag`` in the tangent plane at ``datum``, (n, 3) [m]."""
    with BagReader(truth_bag) as reader:
        return map_enu(_fixes(reader, TRUTH_FIX)[:, 1:4], datum)
