"""``gnss_ins import-qfree``: Q-Free OBU GNSS and MEMS text logs to a rosbag2 bag.

Layouts and the reference receiver are described in ins_fusion/qfree/logs.py, units and
mountings in ins_fusion/qfree/mems_conversion.py, both from
shared/reference/gnss-ins-ntnu-notes.md §3–5. The messages are filled like the drivers' and the
simulator's (gnss_ins_common/message_fields.py, topics and frames of ins_fusion/bags/topics.py);
header.stamp = bag time = the UTC date/time columns of the line:

- ``/gnss/fix`` (sensor_msgs/NavSatFix, frame ``gnss_link``): status NO_FIX when the good flag
  (column 9) is 0, SBAS_FIX when SBAS is active (column 32), else FIX; service GPS; covariance
  diag(sE², sN², sD²) from columns 22–24 (DIAGONAL_KNOWN), else (6 m)² per axis (APPROXIMATED,
  Table 4.9); altitude = ellipsoidal height (column 13).
- ``/gnss/vel`` (geometry_msgs/TwistWithCovarianceStamped, ENU, frame ``gnss_link``): from the
  NED velocity (columns 27–29) of good epochs that have one; linear covariance (0.43 m/s)² per
  axis (Table 4.9), angular variances 1e6 (not measured, as gnss_node).
- ``/imu/data_raw`` (sensor_msgs/Imu, frame ``imu_link``, REP-145): specific force m/s², rate
  rad/s, rotated by ``--mounting`` (or per sensor ``--accel-mounting``/``--gyro-mounting``, or
  the thesis's own transforms with ``--preset thesis``); stamps plus ``--time-shift``;
  orientation_covariance[0] = −1; diagonal covariances from the bench variances of Tables
  4.4/4.5.
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

from gnss_ins_common.message_fields import fill_imu, fill_navsatfix, fill_velocity
from gnss_ins_common.navsat import SERVICE_GPS
from ins_fusion.bags.bag_io import STORAGES, BagError, BagWriter
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import (
    GNSS_FIX,
    GNSS_FRAME,
    GNSS_VEL,
    IMU_DATA,
    IMU_FRAME,
    TOPICS,
    TRUTH_FIX,
    TRUTH_FRAME,
    TRUTH_VEL,
)
from ins_fusion.qfree import checks, logs, mems_conversion
from ins_fusion.runtime.progress import Progress

#: Bad lines and gyro wraps printed one by one; the rest are counted.
MAX_LISTED = 20


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins import-qfree``."""
    parser.add_argument("--gnss", type=Path, required=True, help="GNSS log (35 columns)")
    parser.add_argument("--mems", type=Path, required=True, help="MEMS log (14 columns)")
    parser.add_argument("--reference", type=Path, help="GNSS log of the reference (equipment id 6)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="bag directory to create")
    parser.add_argument(
        "--storage", choices=sorted(STORAGES), default="mcap", help="rosbag2 storage plugin"
    )
    parser.add_argument(
        "--accel-unit",
        choices=sorted(mems_conversion.ACCEL_UNITS),
        help="unit of the MEMS log's accelerations (default: mg)",
    )
    parser.add_argument(
        "--gyro-unit",
        choices=sorted(mems_conversion.GYRO_UNITS),
        help="unit of the MEMS log's rates (default: mdps, milli-degrees per second)",
    )
    parser.add_argument(
        "--mounting",
        type=_mounting,
        metavar="ROLL,PITCH,YAW",
        help="rotation (deg) from the logger's sensor axes to imu_link for both sensors: "
        "R = Rz(yaw)·Ry(pitch)·Rx(roll)",
    )
    for sensor in ("accel", "gyro"):
        parser.add_argument(
            f"--{sensor}-mounting",
            type=_mounting,
            metavar="ROLL,PITCH,YAW",
            help=f"the same for the {'accelerometer' if sensor == 'accel' else 'gyro'} alone "
            "(instead of --mounting)",
        )
    parser.add_argument(
        "--preset",
        choices=("thesis",),
        help="thesis: the NTNU thesis's own accelerometer and gyro transforms (its program, "
        "appendix 6.5: accel x 0.97396 x 9.82171 with Rz(pi)Ry Rx, gyro negated with the "
        "opposite roll sign) and its 1.24 s IMU delay; not with the unit and mounting options",
    )
    parser.add_argument(
        "--time-shift",
        type=float,
        metavar="SECONDS",
        help="added to the MEMS stamps (the thesis delayed its IMU data by 1.24 s to meet the "
        "late GNSS; default 0, with --preset thesis 1.24)",
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


def _transforms(
    args: argparse.Namespace,
) -> tuple[mems_conversion.SensorTransform, mems_conversion.SensorTransform]:
    """(accelerometer, gyro) transforms of the options; ValueError for a preset combined with
    unit or mounting options."""
    options = ("accel_unit", "gyro_unit", "mounting", "accel_mounting", "gyro_mounting")
    if args.preset == "thesis":
        given = [f"--{o.replace('_', '-')}" for o in options if getattr(args, o) is not None]
        if given:
            raise ValueError(f"--preset thesis sets the transforms itself, not with {given[0]}")
        return mems_conversion.thesis_transforms()
    both = args.mounting or (0.0, 0.0, 0.0)
    return (
        mems_conversion.SensorTransform.mounted(
            args.accel_unit or "mg", args.accel_mounting or both
        ),
        mems_conversion.SensorTransform.mounted(
            args.gyro_unit or "mdps", args.gyro_mounting or both
        ),
    )


def _listed(items: Sequence[object], what: str) -> None:
    """Print up to MAX_LISTED items to stderr, then how many more there are."""
    for item in items[:MAX_LISTED]:
        print(f"{what}: {item}", file=sys.stderr)
    if len(items) > MAX_LISTED:
        print(f"{what}: ... and {len(items) - MAX_LISTED} more", file=sys.stderr)


def navsatfix(epoch: logs.GnssEpoch, frame: str) -> Any:
    """sensor_msgs/NavSatFix of a GNSS epoch (status and covariance as in the module doc)."""
    covariance, kind = epoch.position_covariance_enu_m2
    return fill_navsatfix(
        new_message(TOPICS[GNSS_FIX]),
        epoch.stamp.utc_ns,
        frame,
        int(epoch.status),
        SERVICE_GPS,
        epoch.latitude_deg,
        epoch.longitude_deg,
        epoch.height_m,
        covariance,
        int(kind),
    )


def twist_enu(epoch: logs.GnssEpoch, vel_enu_m_s: Sequence[float], frame: str) -> Any:
    """geometry_msgs/TwistWithCovarianceStamped: ENU velocity, Table 4.9 covariance."""
    return fill_velocity(
        new_message(TOPICS[GNSS_VEL]),
        epoch.stamp.utc_ns,
        frame,
        vel_enu_m_s,
        logs.VELOCITY_COVARIANCE_ENU_M2_S2,
    )


def imu_message(series: mems_conversion.ImuSeries, k: int) -> Any:
    """sensor_msgs/Imu (REP-145, no orientation) of sample ``k`` of the series."""
    return fill_imu(
        new_message(TOPICS[IMU_DATA]),
        int(series.utc_ns[k]),
        IMU_FRAME,
        series.rate_rad_s[k],
        series.accel_m_s2[k],
        series.rate_variance_rad2_s2,
        series.accel_variance_m2_s4,
    )


def _validated(
    log: logs.ParsedLog[Any], problem: Callable[[Any], str | None], refused: Counter[str]
) -> list[Any]:
    """The records of ``log`` with plausible values (``problem``) in time order; the others
    listed on stderr and counted in ``refused`` (keys "implausible" and "time")."""
    kept, implausible = checks.refuse(log.records, problem)
    kept, time_faults = checks.refuse_time_faults(kept)
    _listed(implausible, "implausible value")
    _listed(time_faults, "time order")
    refused.update(implausible=len(implausible), time=len(time_faults))
    return kept


def _read(path: Path, parse: Callable[..., logs.ParsedLog[Any]]) -> logs.ParsedLog[Any]:
    with path.open(encoding="utf-8", errors="replace") as lines:
        log = parse(lines, str(path))
    _listed(log.bad_lines, "bad line")
    return log


#: (bag time ns, order, topic, message factory): the messages, made when written.
Event = tuple[int, int, str, Callable[[], Any]]


def _events(
    epochs: list[logs.GnssEpoch],
    series: mems_conversion.ImuSeries,
    selected: Callable[[int], bool],
) -> tuple[list[Event], int]:
    """Every message to write in time order, and the count of GNSS epochs without a usable
    velocity (bad, or none in the log)."""
    events: list[Event] = []
    no_velocity = 0
    for epoch in epochs:
        ref = epoch.stamp.equipment_id == logs.REFERENCE_EQUIPMENT_ID
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
    for k, t in enumerate(series.utc_ns.tolist()):
        events.append((t, len(events), IMU_DATA, partial(imu_message, series, k)))
    events.sort(key=lambda event: event[:2])
    return events, no_velocity


def run(args: argparse.Namespace) -> int:
    """Parse the logs, write the bag, print the summary. 2 if a file cannot be read or the bag
    exists, 1 if nothing could be imported."""
    try:
        parsed = [_read(args.gnss, logs.parse_gnss), _read(args.mems, logs.parse_mems)]
        if args.reference:
            parsed.append(_read(args.reference, logs.parse_gnss))
    except OSError as exc:
        print(f"gnss_ins import-qfree: error: {exc}", file=sys.stderr)
        return 2
    gnss, mems, *reference = parsed
    refused: Counter[str] = Counter()
    epochs: list[logs.GnssEpoch] = [
        e for log in (gnss, *reference) for e in _validated(log, checks.gnss_problem, refused)
    ]
    try:
        accel, gyro = _transforms(args)
    except ValueError as exc:
        print(f"gnss_ins import-qfree: error: {exc}", file=sys.stderr)
        return 2
    mems_problem = partial(checks.mems_problem, accel_unit=accel.unit, gyro_unit=gyro.unit)
    mems_records = _validated(mems, mems_problem, refused)

    def selected(equipment_id: int) -> bool:
        if args.equipment is not None:
            return bool(equipment_id == args.equipment)
        return equipment_id != logs.REFERENCE_EQUIPMENT_ID

    receivers = {e.stamp.equipment_id for e in epochs} | {
        s.stamp.equipment_id for s in mems_records
    }
    if args.equipment is None and len(receivers - {logs.REFERENCE_EQUIPMENT_ID}) > 1:
        print(
            f"warning: receivers {sorted(receivers)} share the topics; choose with --equipment",
            file=sys.stderr,
        )
    samples = [s for s in mems_records if selected(s.stamp.equipment_id)]
    default_shift = mems_conversion.THESIS_LATENCY_S if args.preset == "thesis" else 0.0
    shift_s = default_shift if args.time_shift is None else args.time_shift
    series = mems_conversion.imu_series(
        samples, accel=accel, gyro=gyro, unwrap=not args.keep_gyro_wrap, time_shift_s=shift_s
    )
    _listed(series.wraps, "gyro wrap")
    events, no_velocity = _events(epochs, series, selected)
    if not events:
        print(
            "gnss_ins import-qfree: error: no valid GNSS epoch or MEMS sample to import",
            file=sys.stderr,
        )
        return 1
    try:
        writer = BagWriter(args.output, storage=args.storage)
    except BagError as exc:
        print(f"gnss_ins import-qfree: error: {exc}", file=sys.stderr)
        return 2
    with writer, Progress("import", total=len(events), unit="msgs") as progress:
        for done, (t, _, topic, make) in enumerate(events, start=1):
            writer.write(topic, t, make())
            if done % 1000 == 0:
                progress.update(done)
        progress.update(len(events))

    print(writer.summary.format(f"bag {args.output} ({args.storage}, files: {len(writer.files)})"))
    print(
        f"  bad lines: {sum(len(log.bad_lines) for log in parsed)};"
        f" GNSS epochs without usable velocity: {no_velocity};"
        f" MEMS samples of other equipment: {len(mems_records) - len(samples)}"
    )
    print(
        f"  refused: {refused['implausible']} lines with implausible values,"
        f" {refused['time']} lines at or before the time of the previous line"
    )
    if series.wraps:
        per_axis = Counter(w.axis for w in series.wraps)
        print(
            f"  gyro 16-bit wrap: {len(series.wraps)} jumps"
            f" ({', '.join(f'{axis} {per_axis[axis]}' for axis in 'xyz')}),"
            f" {'kept' if args.keep_gyro_wrap else 'undone'};"
            f" first at {series.wraps[0].source}:{series.wraps[0].line}"
        )
    else:
        print("  gyro 16-bit wrap: none")
    if args.preset is not None:
        print(f"  transforms: preset {args.preset}")
    for name, value in (
        ("mounting", args.mounting),
        ("accelerometer mounting", args.accel_mounting),
        ("gyro mounting", args.gyro_mounting),
    ):
        if value is not None and any(value):
            print("  {} (roll, pitch, yaw) deg: {:g}, {:g}, {:g}".format(name, *value))
    if shift_s:
        print(f"  MEMS stamps shifted by {shift_s:+g} s")
    return 0
