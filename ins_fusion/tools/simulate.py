"""`gnss_ins simulate`: a simulated drive to a rosbag2 bag, or live on emulated serial devices.

Bag mode writes what imu400cc_node and gnss_node would publish on the drive, each message at its
receive time, plus the truth (ins_fusion/sim/drive.py lists topics, frames and stamps), then
prints the bag summary. The same seed gives the same messages.

``--live`` runs the drive in real time instead, on emulated devices (ins_fusion/sim/live.py: the
port lines it prints first, ``--truth-output BAG``, ``--hold``, as ``gnss_ins demo`` uses them).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from datetime import datetime
from pathlib import Path

from ins_fusion.bags.bag_io import STORAGES, BagError
from ins_fusion.sim import imu_model, odometer_model, vibration
from ins_fusion.sim.drive import (
    DEFAULT_START_NS,
    POSITION_RECEIVERS,
    SimulationConfig,
    SkyZoneSpec,
)
from ins_fusion.sim.live import LiveOptions, run_live
from ins_fusion.sim.scenarios import SCENARIOS
from ins_fusion.sim.simulated_bag import write_bag


def _numbers(text: str, count: tuple[int, int], what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(":")]
    except ValueError:
        values = []
    if not count[0] <= len(values) <= count[1]:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return values


def _positive(text: str) -> float:
    value = _numbers(text, (1, 1), "a number")[0]
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def _outage(text: str) -> tuple[float, float]:
    start, duration = _numbers(text, (2, 2), "START:DURATION in seconds")
    return start, duration


def _sky_zone(text: str) -> SkyZoneSpec:
    values = _numbers(text, (2, 3), "T:RADIUS[:SATELLITES]")
    return SkyZoneSpec(values[0], values[1], int(values[2]) if len(values) == 3 else 0)


def _number(text: str) -> float:
    value = _numbers(text, (1, 1), "a number")[0]
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def _utc_ns(text: str) -> int:
    try:
        stamp = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an ISO 8601 UTC time, got {text!r}") from None
    if stamp.tzinfo is None:
        raise argparse.ArgumentTypeError(f"{text!r}: give the time zone, e.g. a final Z")
    return round(stamp.timestamp() * 1e9)


def add_drive_arguments(parser: argparse.ArgumentParser, duration_s: float, what: str) -> None:
    """``--scenario``, ``--duration`` (default ``duration_s``, help ``what``) and ``--seed``: the
    drive, also of ``gnss_ins emulate``."""
    parser.add_argument(
        "--scenario",
        choices=sorted(SCENARIOS),
        default="test_pattern",
        help="the drive (docs/simulator.md)",
    )
    parser.add_argument("--duration", type=_positive, default=duration_s, help=what)
    parser.add_argument("--seed", type=int, default=0, help="seed of every error model")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins simulate``."""
    add_drive_arguments(parser, 240.0, "seconds to simulate")
    parser.add_argument(
        "--imu", choices=sorted(imu_model.PROFILES), default="imu400cc", help="IMU error profile"
    )
    parser.add_argument(
        "--imu-rate", type=_positive, metavar="HZ", help="IMU output rate (default: the profile's)"
    )
    parser.add_argument("-o", "--output", type=Path, help="bag directory to create")
    parser.add_argument(
        "--storage", choices=sorted(STORAGES), default="mcap", help="rosbag2 storage plugin"
    )
    parser.add_argument(
        "--gnss",
        choices=[*POSITION_RECEIVERS, "none"],
        default="leica_rtk",
        help="position receiver on /gnss/fix, /gnss/vel, /gnss/time_reference (printed as the "
        "Leica rover's VTG, GGA, LLQ)",
    )
    parser.add_argument(
        "--gnss-rate",
        type=_positive,
        metavar="HZ",
        help="position receiver's epoch rate (default: the profile's, 1 Hz)",
    )
    parser.add_argument(
        "--adu5",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="ADU5 attitude on /gnss/attitude",
    )
    parser.add_argument(
        "--outage",
        type=_outage,
        action="append",
        default=[],
        metavar="START:DURATION",
        help="scheduled GNSS outage [s] (repeatable)",
    )
    parser.add_argument(
        "--sky-zone",
        type=_sky_zone,
        action="append",
        default=[],
        metavar="T:RADIUS[:SATS]",
        help="only SATS (default 0) satellites visible within RADIUS m of where the vehicle is at "
        "route time T s (repeatable; the drive meets it again on every lap)",
    )
    parser.add_argument(
        "--band-limit",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="low-pass the IMU white noise with the sensor bandwidth (per-sample σ as measured)",
    )
    parser.add_argument(
        "--vibration",
        choices=sorted(vibration.PROFILES),
        default="car",
        help="engine/road vibration the IMU senses, growing with speed; default like a car on "
        "a road (docs/simulator.md)",
    )
    parser.add_argument(
        "--speed",
        action="store_true",
        help="an odometer (DMI on the left rear wheel) on /vehicle/speed (bags only)",
    )
    parser.add_argument(
        "--speed-rate", type=_positive, metavar="HZ", help="odometer output rate (default 20)"
    )
    parser.add_argument(
        "--speed-scale",
        type=_number,
        metavar="FRACTION",
        help="odometer scale error, measured/true - 1 (default 0.02)",
    )
    parser.add_argument(
        "--speed-slip-threshold",
        type=_number,
        metavar="M_S2",
        help="deceleration above which the wheels slip and the odometer under-reads (default 3)",
    )
    parser.add_argument(
        "--truth-rate", type=_positive, default=50.0, help="rate of /ground_truth/* [Hz]"
    )
    parser.add_argument(
        "--start",
        type=_utc_ns,
        default=DEFAULT_START_NS,
        help="UTC time of the bag's start, ISO 8601 (default 2024-06-01T10:00:00Z)",
    )
    parser.add_argument(
        "--live", action="store_true", help="emulated devices on pseudo-terminals in real time"
    )
    parser.add_argument("--truth-output", type=Path, help="live mode: bag of the truth topics")
    parser.add_argument(
        "--hold",
        action="store_true",
        help="live mode: at the end of the drive print 'drive ended' and keep the devices open"
        " until Ctrl-C/SIGTERM",
    )


def run(args: argparse.Namespace) -> int:
    """Write the bag or run live; 2 on a usage, configuration or bag error."""
    if args.live == (args.output is not None):
        print("gnss_ins simulate: error: give either --output BAG or --live", file=sys.stderr)
        return 2
    if args.truth_output is not None and not args.live:
        print(
            "gnss_ins simulate: error: --truth-output is for --live (a bag holds the truth anyway)",
            file=sys.stderr,
        )
        return 2
    if args.hold and not args.live:
        print("gnss_ins simulate: error: --hold is for --live", file=sys.stderr)
        return 2
    if args.live and (args.imu_rate is not None or args.gnss_rate is not None):
        print(
            "gnss_ins simulate: error: --imu-rate and --gnss-rate are for bags; the emulators"
            " run at their devices' rates",
            file=sys.stderr,
        )
        return 2
    speed_options = (args.speed_rate, args.speed_scale, args.speed_slip_threshold)
    if not args.speed and any(v is not None for v in speed_options):
        print("gnss_ins simulate: error: the --speed-* options need --speed", file=sys.stderr)
        return 2
    if args.live and args.speed:
        print("gnss_ins simulate: error: --speed is for bags (no odometer device)", file=sys.stderr)
        return 2
    try:
        odometer = _odometer(args) if args.speed else None
    except ValueError as exc:
        print(f"gnss_ins simulate: error: {exc}", file=sys.stderr)
        return 2
    config = SimulationConfig(
        scenario=args.scenario,
        duration_s=args.duration,
        imu=args.imu,
        band_limited=args.band_limit,
        gnss=None if args.gnss == "none" else args.gnss,
        adu5=args.adu5,
        outages=tuple(args.outage),
        sky_zones=tuple(args.sky_zone),
        truth_rate_hz=args.truth_rate,
        seed=args.seed,
        start_ns=args.start,
        vibration=args.vibration,
        imu_rate_hz=args.imu_rate,
        gnss_rate_hz=args.gnss_rate,
        odometer=odometer,
    )
    try:
        if args.live:
            options = LiveOptions(
                truth_output=args.truth_output, storage=args.storage, hold=args.hold
            )
            return run_live(config, options)
        write_bag(config, args.output, args.storage)
    except (BagError, ValueError) as exc:
        print(f"gnss_ins simulate: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _odometer(args: argparse.Namespace) -> odometer_model.OdometerProfile:
    """The DMI profile with the rate, scale error and slip threshold given (ValueError if
    invalid)."""
    changes = {
        "rate_hz": args.speed_rate,
        "scale_error": args.speed_scale,
        "slip_threshold_m_s2": args.speed_slip_threshold,
    }
    given = {name: value for name, value in changes.items() if value is not None}
    return dataclasses.replace(odometer_model.DMI, **given)
