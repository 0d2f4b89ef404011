"""The steps of ``gnss_ins calibrate`` (ins_fusion/tools/calibrate.py parses the arguments):
read the bags, find or check the segments, run the method, write the calibration file, the
report and the figure. Bad input raises one of the errors in ``INPUT_ERRORS``, printed by
``execute`` with exit status 2; the axes check exits 1 when the driver's mapping disagrees.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import yaml

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.params import ParameterValueError, load_yaml
from imu400cc_driver.axes import DEFAULT_ACCEL_SIGN, DEFAULT_AXIS_SPEC
from ins_fusion.bags.bag_io import BagError
from ins_fusion.bags.imu import ImuRecord, read_imu
from ins_fusion.calibration_id import axes, rotation, static
from ins_fusion.calibration_id.lsq import EstimationError
from ins_fusion.calibration_id.model import BiasInstability, Site
from ins_fusion.calibration_id.report import METHOD_TITLES, decimals, write_report
from ins_fusion.calibration_id.result import CalibrationResult, calibration_mapping
from ins_fusion.calibration_id.segments import (
    DetectorSettings,
    Kind,
    Segment,
    SegmentError,
    detect,
    from_window,
    static_only,
)
from ins_fusion.calibration_id.unknown_attitude import unknown_attitude
from ins_fusion.core.nav.calibration import CalibrationError, ImuCalibration
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2, deg_h, mg
from ins_fusion.core.settings.config import NODE_NAME as FUSION_NODE
from ins_fusion.core.settings.params import PARAMETERS as FUSION_PARAMETERS

STATIC_METHODS = ("six-position", "salychev", "known-attitude", "unknown-attitude")
METHODS = (*STATIC_METHODS, "rate-table", "known-angle", "axes")
#: imu400cc_node's section in a ROS parameter file.
DRIVER_NODE = "imu400cc_node"


class UsageError(ValueError):
    """Options that do not fit the method."""


#: Bad input (and files that cannot be written): a message and exit status 2.
INPUT_ERRORS = (UsageError, BagError, SegmentError, EstimationError, CalibrationError, OSError)


def execute(args: argparse.Namespace) -> int:
    """Run the method; 0 done, 1 the axes check disagrees with the driver, 2 bad input."""
    try:
        return _run(args)
    except INPUT_ERRORS as exc:
        print(f"gnss_ins calibrate: error: {exc}", file=sys.stderr)
        return 2


def parse_windows(text: str) -> list[tuple[int, float, float]]:
    """``[N@]T0:T1,...`` -> (bag index from 0, t0, t1) [s after the bag's first IMU stamp]."""
    windows = []
    for item in text.split(","):
        bag, _, span = item.strip().rpartition("@")
        t0, sep, t1 = span.partition(":")
        try:
            index = int(bag) - 1 if bag else 0
            window = (index, float(t0), float(t1))
        except ValueError:
            raise ValueError(f"window {item!r}: expected [BAG@]T0:T1 in seconds") from None
        if not sep or index < 0 or window[2] <= window[1]:
            raise ValueError(f"window {item!r}: expected [BAG@]T0:T1 with T1 > T0, BAG >= 1")
        windows.append(window)
    return windows


def parse_attitudes(text: str) -> list[tuple[float, float, float]]:
    """``ROLL:PITCH:YAW,...`` [deg] -> radians."""
    attitudes = []
    for item in text.split(","):
        parts = item.strip().split(":")
        try:
            roll, pitch, yaw = (math.radians(float(p)) for p in parts)
        except ValueError:
            raise ValueError(f"attitude {item!r}: expected ROLL:PITCH:YAW in degrees") from None
        attitudes.append((roll, pitch, yaw))
    return attitudes


def parse_positions(text: str) -> list[tuple[int, float]]:
    """``+z,-z,+x,...`` -> (axis, sign) per static segment."""
    return [axes.parse_position(item) for item in text.split(",")]


def _check_usage(args: argparse.Namespace) -> None:
    method = args.method
    needs = {
        "known-attitude": ("attitudes", "--attitudes"),
        "rate-table": ("rate", "--rate"),
        "known-angle": ("angle", "--angle"),
    }
    if method in needs and getattr(args, needs[method][0]) is None:
        raise UsageError(f"{method} needs {needs[method][1]}")
    if method in STATIC_METHODS and args.latitude is None:
        raise UsageError(f"{method} needs --latitude (gravity and earth rate of the laboratory)")
    if method == "axes" and (args.output is not None or args.base is not None):
        raise UsageError("axes writes no calibration file (-o/--base)")
    if method not in ("six-position", "salychev", "axes") and args.positions is not None:
        raise UsageError("--positions is for six-position, salychev and axes")
    if args.accel_scale is not None and method not in (
        "six-position",
        "salychev",
        "known-attitude",
    ):
        raise UsageError("--accel-scale is for six-position, salychev and known-attitude")
    if args.scale_ranges is not None and (
        method not in ("six-position", "salychev", "known-attitude") or not args.scale_ranges > 0
    ):
        raise UsageError(
            "--scale-ranges is a positive G for six-position, salychev, known-attitude"
        )
    for path in (args.output, args.report, args.plot):
        if path is not None and path.is_dir():
            raise UsageError(f"{path} is a directory")


def _detector(args: argparse.Namespace) -> DetectorSettings:
    static_rate = math.radians(args.static_rate_max)
    if args.rate is not None:  # a slow rate table must not count as static
        static_rate = min(static_rate, 0.5 * math.radians(args.rate))
    settings = DetectorSettings(
        window_s=args.window,
        accel_std_max_m_s2=args.accel_std_max,
        gyro_std_max_rad_s=math.radians(args.gyro_std_max),
        static_rate_max_rad_s=static_rate,
        min_duration_s=args.min_duration,
        trim_s=args.trim,
    )
    if min(settings.window_s, settings.accel_std_max_m_s2, settings.gyro_std_max_rad_s) <= 0.0:
        raise UsageError("--window, --accel-std-max and --gyro-std-max must be positive")
    return settings


def find_segments(
    records: Sequence[ImuRecord],
    windows: Sequence[tuple[int, float, float]] | None,
    settings: DetectorSettings,
) -> list[Segment]:
    """Given windows (checked) or every detected segment, in time order per bag."""
    if windows is None:
        return [s for k, record in enumerate(records) for s in detect(record, k, settings)]
    segments = []
    for index, t0, t1 in windows:
        if index >= len(records):
            raise SegmentError(f"window {index + 1}@{t0:g}:{t1:g}: there are {len(records)} bags")
        segments.append(from_window(records[index], index, t0, t1, settings))
    return sorted(segments, key=lambda s: (s.record, s.t_start_s))


def _instability(path: Path | None) -> BiasInstability:
    if path is None:
        return BiasInstability()
    try:
        values = load_yaml(path, FUSION_NODE, FUSION_PARAMETERS)
    except ParameterValueError as exc:
        raise UsageError(str(exc)) from None
    gyro = [deg_h(v) for v in values["imu_noise.gyro_bias_instability"]]
    accel = [mg(v) for v in values["imu_noise.accel_bias_instability"]]
    tau = float(values["imu_noise.bias_correlation_time"])
    return BiasInstability((gyro[0], gyro[1], gyro[2]), (accel[0], accel[1], accel[2]), tau, tau)


def _driver_map(path: Path | None) -> tuple[AxisMap, float]:
    if path is None:
        return AxisMap.from_spec(DEFAULT_AXIS_SPEC), DEFAULT_ACCEL_SIGN
    try:
        document = yaml.safe_load(path.read_text()) or {}
        section = document.get(DRIVER_NODE, document.get(f"/{DRIVER_NODE}")) or {}
        values = section.get("ros__parameters") or {}
        axis_map = AxisMap.from_spec(values.get("axis_map", list(DEFAULT_AXIS_SPEC)))
        accel_sign = float(values.get("accel_sign", DEFAULT_ACCEL_SIGN))
    except (OSError, yaml.YAMLError, AttributeError, ValueError, TypeError) as exc:
        raise UsageError(
            f"{path}: cannot read {DRIVER_NODE}'s axis_map/accel_sign: {exc}"
        ) from None
    if accel_sign not in (1.0, -1.0):
        raise UsageError(f"{path}: accel_sign must be 1.0 or -1.0, not {accel_sign}")
    return axis_map, accel_sign


def _check_positions(result: CalibrationResult, declared: Sequence[tuple[int, float]]) -> None:
    found = [label.split()[0] for label in result.labels]
    wanted = [static.axis_label(axis, sign) for axis, sign in declared]
    if found != wanted:
        raise EstimationError(
            f"--positions says {','.join(wanted)} but the data put +g on {','.join(found)}:"
            " the driver's axis_map/accel_sign may be wrong (gnss_ins calibrate axes checks it)"
        )


def _run_method(
    args: argparse.Namespace, records: Sequence[ImuRecord], segments: Sequence[Segment]
) -> tuple[CalibrationResult, axes.AxisCheck | None]:
    method = args.method
    instability = _instability(args.noise)
    statics = [s for s in segments if s.kind is Kind.STATIC]
    if args.segments is not None and method != "rate-table":
        statics = static_only(segments, method)
    if method in STATIC_METHODS:
        options = static.StaticOptions(
            Site.at(args.latitude, args.height, args.gravity),
            math.radians(args.level_sigma),
            instability,
            static.Scale(
                args.accel_scale or ("symmetric" if method == "salychev" else "asymmetric")
            ),
            math.inf if args.scale_ranges is None else args.scale_ranges * STANDARD_GRAVITY_M_S2,
        )
        if method == "known-attitude":
            return static.known_attitude(statics, args.attitudes, options), None
        if method == "unknown-attitude":
            return unknown_attitude(statics, options), None
        result = static.six_position(statics, options, salychev=method == "salychev")
        if args.positions is not None:
            _check_positions(result, args.positions)
        return result, None
    mount = math.radians(args.mount_sigma)
    if method == "rate-table":
        result = rotation.rate_table(
            segments, math.radians(args.rate), math.radians(args.rate_sigma), mount, instability
        )
        return result, None
    if method == "known-angle":
        result = rotation.known_angle(
            records,
            statics,
            math.radians(args.angle),
            math.radians(args.angle_sigma),
            mount,
            instability,
        )
        return result, None
    driver, driver_sign = _driver_map(args.driver_params)
    declared = args.positions or [axes.parse_position(p) for p in axes.DEFAULT_POSITIONS]
    gravity = args.gravity or STANDARD_GRAVITY_M_S2
    check = axes.check_axes(records, statics, declared, driver, driver_sign, gravity)
    result = CalibrationResult(
        "axes",
        list(statics),
        [f"{static.axis_label(a, s)} up (declared)" for a, s in declared],
    )
    return result, check


def _temperature_range(
    result: CalibrationResult, records: Sequence[ImuRecord]
) -> tuple[float, float] | None:
    ranges = [
        r
        for s in result.segments
        if (r := records[s.record].temperature_range(s.t_start_s, s.t_end_s)) is not None
    ]
    if not ranges:
        return None
    return min(r[0] for r in ranges), max(r[1] for r in ranges)


def _write_calibration(
    args: argparse.Namespace,
    result: CalibrationResult,
    temperature: tuple[float, float] | None,
) -> None:
    base: dict[str, Any] | None = None
    if args.base is not None:
        ImuCalibration.from_yaml(args.base)  # readable and valid
        base = yaml.safe_load(args.base.read_text())["imu_calibration"]
    section = calibration_mapping(result, base, temperature, args.sensor)
    bags = ", ".join(p.name for p in args.bags)
    made = f"gnss_ins calibrate {result.method} ({bags}), {datetime.now(UTC):%Y-%m-%d}"
    section["source"] = f"{section['source']}; {made}" if section.get("source") else made
    first = ("sensor", "source", "temperature_range_c")
    section = {
        **{k: section[k] for k in first if k in section},
        **{k: v for k, v in section.items() if k not in first},
    }
    header = (
        f"# IMU calibration written by gnss_ins calibrate {result.method}\n"
        f"# ({METHOD_TITLES[result.method]}); format: ins_fusion/core/nav/calibration.py.\n"
        "# Use it with ins_fusion_node's calibration_file parameter (docs/calibration.md).\n"
    )
    body = yaml.safe_dump(
        {"imu_calibration": section}, sort_keys=False, default_flow_style=None, width=100
    )
    text = header + body
    args.output.write_text(text, encoding="utf-8")
    ImuCalibration.from_yaml(args.output)


def _settings_rows(
    args: argparse.Namespace, records: Sequence[ImuRecord], temperature: tuple[float, float] | None
) -> list[tuple[str, str]]:
    rows = [
        (
            "bags",
            ", ".join(f"{r.name} ({len(r.t_s)} samples, {r.rate_hz:.1f} Hz)" for r in records),
        ),
        ("segments", "given (--segments)" if args.segments else "detected (static detection)"),
    ]
    if args.method in STATIC_METHODS:
        site = Site.at(args.latitude, args.height, args.gravity)
        rows += [
            (
                "site",
                f"latitude {args.latitude:g}°, height {args.height:g} m, gravity"
                f" {site.gravity_m_s2:.5f} m/s²",
            ),
            ("level σ of the positions", f"{args.level_sigma:g}°"),
        ]
    if args.method == "rate-table":
        rows.append(("table rate", f"{args.rate:g} ± {args.rate_sigma:g} deg/s"))
    if args.method == "known-angle":
        rows.append(("rotation angle", f"{args.angle:g} ± {args.angle_sigma:g}°"))
    if args.method != "axes":
        instability = (
            f"from {args.noise}" if args.noise else "not modelled (no --noise): white noise only"
        )
        rows.append(("bias instability", instability))
    rows.append(
        (
            "temperature",
            "no /imu/temperature in the segments"
            if temperature is None
            else f"{temperature[0]:.1f}-{temperature[1]:.1f} °C",
        )
    )
    if args.output is not None:
        rows.append(("calibration file", str(args.output)))
    return rows


def _summary(result: CalibrationResult, check: axes.AxisCheck | None) -> str:
    lines = [f"{METHOD_TITLES[result.method]}: {len(result.segments)} segments"]
    for e in result.estimates:
        if not e.written:
            continue
        value, sigma = e.user()
        text = ", ".join(
            "—" if math.isnan(v) else f"{v:.{decimals(s)}f}±{s:.{decimals(s)}f}"
            for v, s in zip(value.ravel(), sigma.ravel(), strict=True)
        )
        lines.append(f"  {e.quantity.label} [{e.quantity.unit_text}]: {text}")
    if check is not None:
        lines.append(
            f"  found axis_map {list(check.found.spec)}, accel_sign {check.found_accel_sign:g};"
            f" driver axis_map {list(check.driver.spec)}, accel_sign"
            f" {check.driver_accel_sign:g}: {'agree' if check.agrees else 'DISAGREE'}"
        )
    lines += [f"  note: {n}" for n in result.notes]
    return "\n".join(lines)


def _run(args: argparse.Namespace) -> int:
    _check_usage(args)
    settings = _detector(args)
    records = [read_imu(path, args.imu_topic, args.temperature_topic) for path in args.bags]
    segments = find_segments(records, args.segments, settings)
    if not segments:
        raise SegmentError(
            "no static or steady segment found"
            f" (--min-duration {settings.min_duration_s:g} s, --accel-std-max"
            f" {settings.accel_std_max_m_s2:g} m/s², --gyro-std-max {args.gyro_std_max:g} deg/s)"
        )
    result, check = _run_method(args, records, segments)
    temperature = _temperature_range(result, records)
    if temperature is None:
        result.notes.append("no /imu/temperature during the segments: no temperature range")
    if args.output is not None:
        _write_calibration(args, result, temperature)
    if args.plot is not None:
        from ins_fusion.calibration_id.plot import plot_segments  # matplotlib only when asked

        plot_segments(
            records,
            result.segments,
            result.labels,
            args.plot,
            f"gnss_ins calibrate {result.method}",
        )
    if args.report is not None:
        plot_name = None
        if args.plot is not None:
            plot_name = os.path.relpath(args.plot.resolve(), args.report.resolve().parent)
        text = write_report(
            result, records, _settings_rows(args, records, temperature), check, plot_name
        )
        args.report.write_text(text, encoding="utf-8")
    print(_summary(result, check))
    return 0 if check is None or check.agrees else 1
