"""``gnss_ins import-qfree``: Q-Free OBU GNSS and MEMS text logs to a rosbag2 bag.

Layouts, units and the reference receiver are described in ins_fusion/qfree.py and
shared/reference/gnss-ins-ntnu-notes.md §3–5. Output topics (header.stamp = bag time = the UTC
date/time columns of the line):

- ``/gnss/fix`` (sensor_msgs/NavSatFix, frame ``gnss_link``): status NO_FIX when the good flag
  (column 9) is 0, SBAS_FIX when SBAS is active (column 32), else FIX; service GPS; covariance
  diag(sE², sN², sD²) from columns 22–24 (DIAGONAL_KNOWN), else (6 m)² per axis (APPROXIMATED,
  Table 4.9); altitude = ellipsoidal height (column 13).
- ``/gnss/vel`` (geometry_msgs/TwistWithCovarianceStamped, ENU, frame ``gnss_link``): from the
  NED velocity (columns 27–29) of good epochs that have one; linear covariance (0.43 m/s)² per
  axis (Table 4.9), angular diagonal −1 (not measured).
- ``/imu/data_raw`` (sensor_msgs/Imu, frame ``imu_link``, REP-145): specific force m/s², rate
  rad/s, rotated by ``--mounting``; orientation_covariance[0] = −1; covariances from the bench
  variances of Tables 4.4/4.5.
- ``/ground_truth/fix`` and ``/ground_truth/vel``: the same from equipment id 6 (the SPAN
  reference), frame ``base_link``.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ins_fusion import qfree
from ins_fusion.tools.bag_io import STORAGES, BagWriter, jazzy_typestore
from ins_fusion.tools.progress import Progress

GNSS_FIX, GNSS_VEL, IMU_RAW = "/gnss/fix", "/gnss/vel", "/imu/data_raw"
TRUTH_FIX, TRUTH_VEL = "/ground_truth/fix", "/ground_truth/vel"
GNSS_FRAME, IMU_FRAME, TRUTH_FRAME = "gnss_link", "imu_link", "base_link"
#: Bad lines and gyro wraps printed one by one; the rest are counted.
MAX_LISTED = 20


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins import-qfree``."""
    parser.add_argument("--gnss", type=Path, required=True, help="GNSS log (35 columns)")
    parser.add_argument("--mems", type=Path, required=True, help="MEMS log (14 columns)")
    parser.add_argument("--reference", type=Path, help="GNSS log of the reference (equipment id 6)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="bag directory to create")
    parser.add_argument("--storage", choices=sorted(STORAGES), default="mcap")
    parser.add_argument("--accel-unit", choices=sorted(qfree.ACCEL_UNITS), default="mg")
    parser.add_argument("--gyro-unit", choices=sorted(qfree.GYRO_UNITS), default="mdps")
    parser.add_argument(
        "--mounting",
        type=_mounting,
        default=(0.0, 0.0, 0.0),
        metavar="ROLL,PITCH,YAW",
        help="rotation (deg) from the logger's sensor axes to imu_link: R = Rz(yaw)·Ry(pitch)·"
        "Rx(roll); e.g. the thesis mount: -1.04,25.10,180",
    )
    parser.add_argument(
        "--equipment",
        type=int,
        help="import only this receiver id from --gnss/--mems (default: every id but 6)",
    )
    parser.add_argument(
        "--keep-gyro-wrap",
        action="store_true",
        help="report 16-bit gyro wraps but do not undo them",
    )


def _mounting(text: str) -> tuple[float, float, float]:
    try:
        roll, pitch, yaw = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected ROLL,PITCH,YAW in degrees, got {text!r}"
        ) from None
    return roll, pitch, yaw


def _listed(items: Sequence[object], what: str) -> None:
    """Print up to MAX_LISTED items to stderr, then how many more there are."""
    for item in items[:MAX_LISTED]:
        print(f"{what}: {item}", file=sys.stderr)
    if len(items) > MAX_LISTED:
        print(f"{what}: ... and {len(items) - MAX_LISTED} more", file=sys.stderr)


def _types() -> Any:
    """Message classes of the Jazzy typestore by name (built on first use)."""
    return jazzy_typestore().types


def _header(time_ns: int, frame: str) -> Any:
    return _types()["std_msgs/msg/Header"](
        _types()["builtin_interfaces/msg/Time"](*divmod(time_ns, 1_000_000_000)), frame
    )


def _vector(xyz: Sequence[float]) -> Any:
    return _types()["geometry_msgs/msg/Vector3"](*(float(v) for v in xyz))


def navsatfix(epoch: qfree.GnssEpoch, frame: str) -> Any:
    """sensor_msgs/NavSatFix of a GNSS epoch (status and covariance as in the module doc)."""
    status_cls, fix_cls = (
        _types()["sensor_msgs/msg/NavSatStatus"],
        _types()["sensor_msgs/msg/NavSatFix"],
    )
    if not epoch.good:
        status = status_cls.STATUS_NO_FIX
    else:
        status = status_cls.STATUS_SBAS_FIX if epoch.sbas else status_cls.STATUS_FIX
    covariance, known = epoch.position_covariance_enu_m2
    return fix_cls(
        _header(epoch.stamp.utc_ns, frame),
        status_cls(status, status_cls.SERVICE_GPS),
        epoch.latitude_deg,
        epoch.longitude_deg,
        epoch.height_m,
        np.array(covariance, dtype=np.float64),
        fix_cls.COVARIANCE_TYPE_DIAGONAL_KNOWN if known else fix_cls.COVARIANCE_TYPE_APPROXIMATED,
    )


def twist_enu(epoch: qfree.GnssEpoch, vel_enu_m_s: Sequence[float], frame: str) -> Any:
    """geometry_msgs/TwistWithCovarianceStamped: ENU velocity, Table 4.9 covariance."""
    covariance = np.zeros((6, 6))
    covariance[:3, :3] = np.eye(3) * qfree.VELOCITY_STD_DEFAULT_M_S**2
    covariance[3:, 3:] = -np.eye(3)
    twist = _types()["geometry_msgs/msg/Twist"](_vector(vel_enu_m_s), _vector((0.0, 0.0, 0.0)))
    return _types()["geometry_msgs/msg/TwistWithCovarianceStamped"](
        _header(epoch.stamp.utc_ns, frame),
        _types()["geometry_msgs/msg/TwistWithCovariance"](twist, covariance.ravel()),
    )


def imu_message(series: qfree.ImuSeries, k: int) -> Any:
    """sensor_msgs/Imu (REP-145, no orientation) of sample ``k`` of the series."""
    orientation_covariance = np.zeros(9)
    orientation_covariance[0] = -1.0
    return _types()["sensor_msgs/msg/Imu"](
        _header(int(series.utc_ns[k]), IMU_FRAME),
        _types()["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
        orientation_covariance,
        _vector(series.rate_rad_s[k]),
        series.rate_covariance_rad2_s2.ravel(),
        _vector(series.accel_m_s2[k]),
        series.accel_covariance_m2_s4.ravel(),
    )


def _read(path: Path, parse: Callable[..., qfree.ParsedLog[Any]]) -> qfree.ParsedLog[Any]:
    with path.open(encoding="utf-8", errors="replace") as lines:
        log = parse(lines, str(path))
    _listed(log.bad_lines, "bad line")
    return log


def run(args: argparse.Namespace) -> int:
    """Parse the logs, write the bag, print the summary; 1 if nothing could be imported."""
    try:
        gnss = _read(args.gnss, qfree.parse_gnss)
        mems = _read(args.mems, qfree.parse_mems)
        reference = _read(args.reference, qfree.parse_gnss) if args.reference else None
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    epochs = gnss.records + (reference.records if reference else [])
    is_reference = [e.stamp.equipment_id == qfree.REFERENCE_EQUIPMENT_ID for e in epochs]
    receivers = Counter(
        e.stamp.equipment_id for e, ref in zip(epochs, is_reference, strict=True) if not ref
    )
    imu_ids = Counter(s.stamp.equipment_id for s in mems.records)

    def selected(equipment_id: int) -> bool:
        if args.equipment is not None:
            return equipment_id == args.equipment
        return equipment_id != qfree.REFERENCE_EQUIPMENT_ID

    imu_receivers = set(imu_ids) - {qfree.REFERENCE_EQUIPMENT_ID}
    if args.equipment is None and (len(receivers) > 1 or len(imu_receivers) > 1):
        print(
            f"warning: several receivers share the topics (GNSS ids {sorted(receivers)},"
            f" MEMS ids {sorted(imu_ids)}); choose one with --equipment",
            file=sys.stderr,
        )
    samples = [s for s in mems.records if selected(s.stamp.equipment_id)]
    series = qfree.imu_series(
        samples,
        accel_unit=args.accel_unit,
        gyro_unit=args.gyro_unit,
        mounting_deg=args.mounting,
        unwrap=not args.keep_gyro_wrap,
    )
    _listed(series.wraps, "gyro wrap")

    # (time, order, topic, message factory), written in time order
    events: list[tuple[int, int, str, Callable[[], Any]]] = []
    no_velocity = 0
    for epoch, ref in zip(epochs, is_reference, strict=True):
        if not ref and not selected(epoch.stamp.equipment_id):
            continue
        fix_topic, vel_topic = (TRUTH_FIX, TRUTH_VEL) if ref else (GNSS_FIX, GNSS_VEL)
        frame = TRUTH_FRAME if ref else GNSS_FRAME
        t = epoch.stamp.utc_ns
        events.append((t, len(events), fix_topic, partial(navsatfix, epoch, frame)))
        vel = epoch.vel_enu_m_s
        if vel is None or not epoch.good:
            no_velocity += 1
            continue
        events.append((t, len(events), vel_topic, partial(twist_enu, epoch, vel, frame)))
    for k in range(len(samples)):
        events.append(
            (int(series.utc_ns[k]), len(events), IMU_RAW, partial(imu_message, series, k))
        )
    if not events:
        print("error: no valid GNSS epoch or MEMS sample to import", file=sys.stderr)
        return 1
    events.sort(key=lambda event: event[:2])

    with (
        BagWriter(args.output, storage=args.storage) as writer,
        Progress("import", total=len(events), unit="msgs") as progress,
    ):
        for done, (t, _, topic, make) in enumerate(events, start=1):
            writer.write(topic, t, make())
            if done % 1000 == 0:
                progress.update(done)
        progress.update(len(events))

    bad = [*gnss.bad_lines, *mems.bad_lines, *(reference.bad_lines if reference else [])]
    wrap_axes = Counter(w.axis for w in series.wraps)
    print(writer.summary.format(f"bag {args.output} ({args.storage}, files: {len(writer.files)})"))
    print(
        f"  bad lines: {len(bad)}; GNSS epochs without usable velocity: {no_velocity};"
        f" MEMS samples of other equipment: {len(mems.records) - len(samples)}"
    )
    if series.wraps:
        action = "kept" if args.keep_gyro_wrap else "undone"
        per_axis = ", ".join(f"{axis} {wrap_axes[axis]}" for axis in "xyz")
        print(
            f"  gyro 16-bit wrap: {len(series.wraps)} jumps ({per_axis}), {action};"
            f" first at {series.wraps[0].source}:{series.wraps[0].line}"
        )
    else:
        print("  gyro 16-bit wrap: none")
    if any(args.mounting):
        print("  mounting (roll, pitch, yaw) deg: {:g}, {:g}, {:g}".format(*args.mounting))
    return 0
