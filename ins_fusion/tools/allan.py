"""`gnss_ins allan`: IMU noise terms from a static record, written as ins_fusion_node parameters.

Reads sensor_msgs/Imu from a bag (header stamps as sample times), refuses records that are
irregularly sampled, too short for white noise or not static, computes the overlapping Allan
deviation of the three gyros and three accelerometers and fits the IEEE 952 terms
(ins_fusion.noise_id). Prints a table of the terms per axis; ``-o`` writes the imu_noise.*
parameters in the node's names and units, ``--plot`` the log-log figure. Without ``--terms`` a
bias instability the record does not pin is written provisionally (noise_id.provisional, with
warnings naming the record length that would pin it); with ``--terms`` every requested term must
meet the full precision. Exit status 2 on a bad bag, topic or record, or when the record does not
give the requested terms (the table and the plot are still produced then, the parameter file is
not). docs/allan.md is the guide.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gnss_ins_common.params import ParameterValueError
from ins_fusion.bags.bag_io import BagError
from ins_fusion.bags.imu import read_imu
from ins_fusion.bags.summary import utc_text
from ins_fusion.bags.topics import IMU_DATA
from ins_fusion.core.nav.units import deg_s, mg
from ins_fusion.noise_id.allan import ONE_SIGMA
from ins_fusion.noise_id.analysis import (
    AXES,
    DEFAULT_TERMS,
    SENSORS,
    TERMS,
    check_length,
    identify,
    shortcomings,
)
from ins_fusion.noise_id.output import (
    fusion_parameters,
    provisional_lines,
    summary_table,
    write_parameter_file,
    written_bias_lines,
)
from ins_fusion.noise_id.plot import plot_allan
from ins_fusion.noise_id.provisional import provisional_biases
from ins_fusion.noise_id.record import (
    RecordError,
    StaticLimits,
    check_static,
    check_values,
    sample_clock,
)
from ins_fusion.runtime.progress import Progress


def _terms(text: str) -> tuple[str, ...]:
    names = tuple(dict.fromkeys(t.strip() for t in text.split(",") if t.strip()))
    unknown = [n for n in names if n not in TERMS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f"expected a comma-separated list of {', '.join(TERMS)}, got {text!r}"
        )
    return names


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _probability(text: str) -> float:
    value = _positive(text)
    if not value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability between 0 and 1, got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins allan``."""
    parser.add_argument("bag", type=Path, help="rosbag2 bag of a static IMU record")
    parser.add_argument("--topic", default=IMU_DATA, help="sensor_msgs/Imu topic")
    parser.add_argument(
        "-o", "--output", type=Path, metavar="YAML", help="write ins_fusion_node's imu_noise.*"
    )
    parser.add_argument("--plot", type=Path, metavar="PNG", help="write the Allan-deviation figure")
    parser.add_argument(
        "--terms",
        type=_terms,
        metavar="LIST",
        help=f"strict: terms the record must give to the full precision, {', '.join(TERMS)} "
        f"(default: {','.join(DEFAULT_TERMS)}, with a provisional bias instability when the "
        "record is too short to pin it)",
    )
    parser.add_argument(
        "--confidence",
        type=_probability,
        default=ONE_SIGMA,
        help="probability of the confidence intervals (default 0.683, 1 sigma)",
    )
    parser.add_argument(
        "--max-rate-change",
        type=_positive,
        default=0.1,
        metavar="DEG_S",
        help="static check: largest move of the 10 s gyro means [deg/s] (default 0.1)",
    )
    parser.add_argument(
        "--max-accel-change",
        type=_positive,
        default=10.0,
        metavar="MG",
        help="static check: largest move of the 10 s accelerometer means and |f| [mg] (default 10)",
    )


def _error(message: str) -> int:
    print(f"gnss_ins allan: error: {message}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    """Analyse, print, write; 0 done, 2 bad input or a record that does not give the terms."""
    try:
        with Progress("read", unit="messages") as progress:
            record = read_imu(args.bag, args.topic, None, progress.update_with_total, relative=True)
        clock = sample_clock(record.t_s)
        check_values(record)
        check_length(record.duration_s, args.terms or DEFAULT_TERMS)
        limits = StaticLimits(deg_s(args.max_rate_change), mg(args.max_accel_change))
        check_static(record, clock.rate_hz, limits)
    except (BagError, RecordError) as exc:
        return _error(str(exc))
    source = f"bag {args.bag}, topic {args.topic}, from {utc_text(record.start_ns)}"
    axes = len(SENSORS) * len(AXES)
    with Progress("allan", total=axes, unit="axes") as progress:
        report = identify(record, clock, source, args.confidence, progress.update)
    print("\n".join(summary_table(report)))
    if args.plot is not None:
        plot_allan(args.plot, report)
        print(f"plot: {args.plot}")
    terms = args.terms or DEFAULT_TERMS
    provisional = None
    if args.terms is None:
        provisional = provisional_biases(report)
        for line in provisional_lines(provisional) if provisional.axes else ():
            print(f"gnss_ins allan: warning: {line.strip()}", file=sys.stderr)
    # Without --terms the provisional bias stands in for one the record does not pin.
    strict = terms if provisional is None else tuple(t for t in terms if t != "bias")
    problems = shortcomings(report, strict)
    if problems:
        return _error(
            f"the record does not give the requested terms ({', '.join(terms)}); no "
            "parameter file written:\n  " + "\n  ".join(problems)
        )
    if args.output is not None:
        try:
            parameters = fusion_parameters(report, terms, provisional)
        except ParameterValueError as exc:
            return _error(f"identified values outside the node's ranges: {exc}")
        write_parameter_file(args.output, report, parameters, provisional)
        print("\n".join(written_bias_lines(parameters, provisional, args.output)))
        print(f"parameters: {args.output}")
    return 0
