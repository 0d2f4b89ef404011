"""The fused base_link solution moved to another frame rigidly attached to base_link.

Used for the GNSS antenna (withheld fixes, ins_fusion.replay.withheld) and for references of
the IMU (``header.frame_id`` = the IMU's frame, e.g. comma2k19's imu_link pose). A frame s is
given by its origin r (lever arm, base_link FLU [m]) and its orientation q_base_s (REP-103 roll,
pitch, yaw of s in base_link, the engine's ``imu_mounting_rpy_deg`` convention: z-y'-x''
intrinsic, core.nav.rotation.quat_from_euler). Per recorded solution, with R = R(q_enu_base):

- position  p_s = p_base + R r                                    (map ENU [m])
- orientation q_enu_s = q_enu_base ⊗ q_base_s                        (s FLU in ENU)
- velocity  v_s = v_base + R (ω × r), ω the solution's bias-corrected ω_ib in base_link FLU
  (ω_ib rather than ω_eb: the Earth-rate term, ≤ 7.3e-5 rad/s × |r|, is neglected)
- position covariance P_pos + [a×] P_att [a×]^T with a = R r, P_att the attitude covariance
  about the ENU axes (a small rotation error ψ moves the point by ψ × a). The position-attitude
  cross-covariance is not in the solution and is left out, as are the covariances of ω and of
  the lever arm itself; the velocity covariance is kept as it is, and so is the attitude's
  (rotating by a fixed q_base_s does not change errors about the ENU axes) unless the frame
  has one of its own: imu_link, whose attitude is the engine's mechanised one while base_link's
  adds the estimated mounting's uncertainty (InsSolution.cov_att_imu_enu_rad2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray
from ins_fusion.core.nav.rotation import quat_from_euler
from ins_fusion.replay.run import SolutionTrack

#: REP-105 vehicle frame and the IMU driver's frame (imu400cc_node publishes in imu_link).
BASE_FRAME = "base_link"
IMU_FRAME = "imu_link"


def skew_stack(vectors: FloatArray) -> FloatArray:
    """Cross-product matrices [v×] (n, 3, 3) of vectors (n, 3)."""
    v = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -v[:, 2], v[:, 1]
    out[:, 1, 0], out[:, 1, 2] = v[:, 2], -v[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -v[:, 1], v[:, 0]
    return out


def lever_arm_covariance(cov_att_enu_rad2: FloatArray, arm_enu_m: FloatArray) -> FloatArray:
    """Position covariance [m²] (n, 3, 3) that attitude errors about the ENU axes [rad²]
    (n, 3, 3) give a point at ENU offsets ``arm_enu_m`` (n, 3) from base_link: [a×] P [a×]^T."""
    a = skew_stack(arm_enu_m)
    cov: FloatArray = a @ np.asarray(cov_att_enu_rad2, dtype=np.float64) @ a.transpose(0, 2, 1)
    return cov


def mounting_quat(rpy_rad: Sequence[float]) -> FloatArray:
    """q_base_s (x, y, z, w) of a frame with REP-103 roll, pitch, yaw [rad] in base_link, as the
    engine builds its IMU mounting (core.nav.rotation.mat_from_rpy_flu before the FLU/FRD
    change)."""
    return np.asarray(quat_from_euler(rpy_rad[0], rpy_rad[1], rpy_rad[2]), dtype=np.float64)


def moved_track(
    track: SolutionTrack,
    lever_arm_flu_m: Sequence[float],
    mounting_rpy_rad: Sequence[float] | FloatArray = (0.0, 0.0, 0.0),
    cov_att_enu_rad2: FloatArray | None = None,
) -> SolutionTrack:
    """``track`` of the frame at ``lever_arm_flu_m`` (base_link FLU [m]) with orientation
    ``mounting_rpy_rad`` in base_link (see the module docstring; one (3,) mounting, or one per
    solution (n, 3) when the engine estimated it) and attitude covariance ``cov_att_enu_rad2``
    (n, 3, 3) [rad²] (None: base_link's); ``solutions`` stay those of base_link."""
    if not len(track.t_s):
        return track
    r = np.asarray(lever_arm_flu_m, dtype=np.float64).reshape(3)
    rot = Rotation.from_quat(track.quat_enu_flu_xyzw)
    arm_enu = rot.apply(r)
    rate = track.rate_flu_rad_s
    quat = track.quat_enu_flu_xyzw
    rpy = np.asarray(mounting_rpy_rad, dtype=np.float64)
    if rpy.ndim == 2:
        quat = (rot * Rotation.from_euler("ZYX", rpy[:, ::-1])).as_quat()
    elif rpy.any():
        quat = (rot * Rotation.from_quat(mounting_quat(rpy.tolist()))).as_quat()
    return replace(
        track,
        pos_enu_m=track.pos_enu_m + arm_enu,
        quat_enu_flu_xyzw=np.asarray(quat, dtype=np.float64),
        vel_enu_m_s=track.vel_enu_m_s + rot.apply(np.cross(rate, r)),
        cov_pos_enu_m2=track.cov_pos_enu_m2 + lever_arm_covariance(track.cov_att_enu_rad2, arm_enu),
        cov_att_enu_rad2=track.cov_att_enu_rad2 if cov_att_enu_rad2 is None else cov_att_enu_rad2,
    )


def comparison_frame(frame_id: str, base_frame: str, imu_frame: str) -> str | None:
    """The frame a reference stamped ``frame_id`` is compared in: ``frame_id`` itself when it
    names the IMU (``imu_frame``, the IMU messages' frame_id, or imu_link) or base_link
    (``base_frame``, the node's parameter, or base_link); None for an empty or any other
    frame_id (the caller compares base_link as is and says so)."""
    if not frame_id:
        return None
    if frame_id in {imu_frame, IMU_FRAME} or frame_id in {base_frame, BASE_FRAME}:
        return frame_id
    return None


def is_imu_frame(frame: str | None, imu_frame: str) -> bool:
    """Whether a comparison frame is the IMU's (``imu_frame`` or imu_link)."""
    return frame is not None and frame in {imu_frame, IMU_FRAME}
