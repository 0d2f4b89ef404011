"""The axis/sign mapping of a unit from a six-position record, against the driver's.

imu400cc_node publishes, for device-axis readings d (imu400cc_driver.axes, ``axis_map`` M_drv and
``accel_sign`` a_drv): rate = M_drv d_ω and specific force = a_drv M_drv d_f. The right mapping M,
a gives the case's own imu_link FLU axes: rate = M d_ω, force = a M d_f. So the published data are
the true ones through signed permutations,

    rate_pub = P_g rate_true with P_g = M_drv Mᵀ,
    force_pub = P_a force_true with P_a = ε P_g, ε = a_drv a.

- P_a: the user says which case axis points up in each static segment (``--positions``, in
  order); the published force then reads +g along P_a u (REP-145).
- ε: in a mirror-image frame a rotation turns the other way, so between consecutive positions
  the published gravity direction follows the integrated published rate R (body at the end to
  body at the start) as f_end = Rᵀ f_start when det P_g = +1 and as f_end = R f_start when
  det P_g = -1. Turns of 30-150° tell the two apart (a 180° flip does not); without such a turn
  the unit's frame is taken as right-handed (det M = +1, as the driver expects), so
  det P_g = det M_drv. Then ε = det P_a det P_g.
- The unit's mapping: M = P_gᵀ M_drv and a = ε a_drv.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.types import FloatArray
from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id.lsq import EstimationError
from ins_fusion.calibration_id.segments import Segment
from ins_fusion.calibration_id.static import AXES, axis_label, up_axis

#: The order of the six positions in docs/calibration.md: which imu_link axis points up.
DEFAULT_POSITIONS = ("+z", "-z", "+x", "-x", "+y", "-y")
#: Turns between positions that decide ε [deg], and the largest mismatch accepted [deg].
TURN_RANGE_DEG = (30.0, 150.0)
MAX_MISMATCH_DEG = 15.0


@dataclass(frozen=True)
class Turn:
    """A rotation between two positions: index of the segment before it, angle between the
    gravity directions [deg], mismatch of the gyro-propagated gravity for det P_g = +1 and -1
    [deg]."""

    before: int
    angle_deg: float
    mismatch_same_deg: float
    mismatch_mirror_deg: float


@dataclass(frozen=True)
class AxisCheck:
    """What the six-position record says about the mapping (module docstring)."""

    accel_matrix: FloatArray
    gyro_mirrored: bool  #: det P_g = -1: the unit's frame has the other handedness
    evidence: str
    turns: list[Turn]
    found: AxisMap
    found_accel_sign: float
    driver: AxisMap
    driver_accel_sign: float

    @property
    def agrees(self) -> bool:
        """Whether the driver's axis_map and accel_sign are the unit's."""
        return self.found == self.driver and self.found_accel_sign == self.driver_accel_sign


def parse_position(text: str) -> tuple[int, float]:
    """``+x`` / ``x`` / ``-z`` -> (axis index, sign); ValueError otherwise."""
    term = text.strip().lower()
    sign = -1.0 if term.startswith("-") else 1.0
    name = term.lstrip("+-")
    if name not in ("x", "y", "z") or len(term) - len(name) > 1:
        raise ValueError(f"position {text!r}: expected +x, -x, +y, -y, +z or -z")
    return AXES.index(name), sign


def _map_from_matrix(matrix: FloatArray) -> AxisMap:
    indices = [int(np.argmax(np.abs(row))) for row in matrix]
    signs = [float(matrix[i, k]) for i, k in enumerate(indices)]
    return AxisMap((indices[0], indices[1], indices[2]), (signs[0], signs[1], signs[2]))


def _accel_matrix(
    segments: Sequence[Segment], declared: Sequence[tuple[int, float]], gravity_m_s2: float
) -> FloatArray:
    """P_a from the declared up axes and the published gravity (EstimationError if the
    declarations contradict each other or leave an axis out)."""
    matrix = np.zeros((3, 3))
    seen: dict[int, tuple[int, float, str]] = {}
    for s, (true_axis, true_sign) in zip(segments, declared, strict=True):
        axis, sign = up_axis(s, gravity_m_s2)
        entry = (axis, sign * true_sign, s.where)
        first = seen.setdefault(true_axis, entry)
        if first[:2] != entry[:2]:
            raise EstimationError(
                f"positions contradict each other: case axis {AXES[true_axis]} reads as"
                f" {axis_label(first[0], first[1])} in {first[2]} but as"
                f" {axis_label(axis, sign * true_sign)} in {s.where}; check --positions"
            )
        matrix[axis, true_axis] = sign * true_sign
    missing = [AXES[j] for j in range(3) if j not in seen]
    if missing or sorted(k for k, _, _ in seen.values()) != [0, 1, 2]:
        raise EstimationError(
            "the positions must put each case axis up or down at least once and land on"
            f" three different published axes (missing: {', '.join(missing) or 'none'})"
        )
    return matrix


def _turn_rotation(record: ImuRecord, start: int, stop: int) -> Rotation:
    """Body rotation over samples [start, stop): end-to-start attitude change."""
    t = record.t_s[start:stop]
    w = record.rate_flu_rad_s[start:stop]
    steps = Rotation.from_rotvec(0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None])
    total = Rotation.identity()
    for step in steps:
        total = total * step
    return total


def _angle_deg(a: FloatArray, b: FloatArray) -> float:
    cos = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def _turns(records: Sequence[ImuRecord], segments: Sequence[Segment]) -> list[Turn]:
    turns = []
    for k, (a, b) in enumerate(itertools.pairwise(segments)):
        if a.record != b.record:
            continue
        fa, fb = a.means.force_m_s2, b.means.force_m_s2
        angle = _angle_deg(fa, fb)
        if not TURN_RANGE_DEG[0] <= angle <= TURN_RANGE_DEG[1]:
            continue
        r = _turn_rotation(records[a.record], a.stop - 1, b.start + 1)
        turns.append(Turn(k, angle, _angle_deg(r.inv().apply(fa), fb), _angle_deg(r.apply(fa), fb)))
    return turns


def check_axes(
    records: Sequence[ImuRecord],
    segments: Sequence[Segment],
    declared: Sequence[tuple[int, float]],
    driver: AxisMap,
    driver_accel_sign: float,
    gravity_m_s2: float,
) -> AxisCheck:
    """The unit's mapping from the static segments (in time order) and the declared up axes."""
    if len(declared) != len(segments):
        listing = "; ".join(s.where for s in segments)
        raise EstimationError(
            f"{len(segments)} static segments found ({listing}) but --positions lists"
            f" {len(declared)}; give the windows with --segments"
        )
    accel = _accel_matrix(segments, declared, gravity_m_s2)
    turns = _turns(records, segments)
    if turns:
        votes = set()
        for turn in turns:
            best = min(turn.mismatch_same_deg, turn.mismatch_mirror_deg)
            if best > MAX_MISMATCH_DEG:
                raise EstimationError(
                    f"the gyro turn after {segments[turn.before].where} moves gravity"
                    f" {best:.0f}° away from where the accelerometers find it, whatever"
                    " accel_sign: gyro and accelerometer axes differ by more than a sign"
                )
            votes.add(turn.mismatch_mirror_deg < turn.mismatch_same_deg)
        if len(votes) > 1:
            raise EstimationError("the gyro turns disagree on the handedness of the unit's axes")
        gyro_mirrored = votes.pop()
        evidence = f"gyro turns between positions ({len(turns)})"
    else:
        gyro_mirrored = bool(np.linalg.det(driver.matrix) < 0)
        evidence = "handedness (no turn of 30-150° between positions in one bag)"
    epsilon = float(round(np.linalg.det(accel))) * (-1.0 if gyro_mirrored else 1.0)
    found = _map_from_matrix((epsilon * accel).T @ driver.matrix)
    return AxisCheck(
        accel,
        gyro_mirrored,
        evidence,
        turns,
        found,
        epsilon * driver_accel_sign,
        driver,
        driver_accel_sign,
    )
