"""`gnss_ins launch`: start and supervise the vehicle's nodes for real hardware on a machine
without `ros2`.

The same nodes, namespaces and remappings as launch/vehicle.launch.py
(ins_fusion.runtime.vehicle_nodes), each in its own process, until Ctrl-C/SIGTERM. A node that
ends (crash, exit, kill -9) is started again with the same command, 0.5 s later, the delay
doubling with each failure in a row up to 30 s (ins_fusion.runtime.processes); the others run
on. A missing port, every WARN/ERROR line of a node's log (rate-limited by the nodes) and every
restart are reported on the console. A process that goes silent on /diagnostics for
``--restart-silent`` seconds without ending (hung) is killed and so restarted
(ins_fusion.runtime.watchdog). ``--record DIR`` adds a supervised recorder
(ins_fusion.runtime.recorder), ``--ntrip URL`` the NTRIP client that brings the rover its
corrections (docs/ntrip.md); ``--stop-on-failure`` stops everything when one process ends.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gnss_ins_common.paths import config_file
from ins_fusion.runtime.health import (
    SHOWN,
    STATUS_PROCESS,
    STATUS_TOPIC,
    status_command,
    write_supervisor_state,
)
from ins_fusion.runtime.processes import Backoff, ProcessGroup, default_log_dir
from ins_fusion.runtime.recorder import (
    DEFAULT_SPLIT_S,
    RECORDER,
    STORAGES,
    TOPICS_FILE,
    Recording,
    read_topics,
    recording_name,
)
from ins_fusion.runtime.vehicle_nodes import (
    ADU5,
    DEFAULT_PORTS,
    DISCOVERY_RANGES,
    NTRIP,
    VEHICLE,
    command,
    discovery_environment,
    ntrip_parameters,
)
from ins_fusion.runtime.watchdog import FRESH_S, START_GRACE_S, read_heard, silent
from ins_fusion.tools.record import min_free_option
from ntrip_client.caster_url import PASSWORD_VARIABLE, parse_caster_url, read_password

#: Seconds between two supervision steps (exits, restarts, new warnings).
_PERIOD_S = 0.2
#: --restart-silent: its default, and its least value other than 0: twice the age at which
#: heard.json stops counting (the nodes report, the status server writes, every second).
DEFAULT_SILENT_S = 10.0
MIN_SILENT_S = 2.0 * FRESH_S
#: The processes that report on /diagnostics.
REPORTING = frozenset(SHOWN)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Ports, parameter files, logs, supervision and recording."""
    parser.add_argument(
        "--config",
        type=Path,
        help="directory with imu400cc.yaml, gnss_leica.yaml, gnss_adu5.yaml, ins_fusion.yaml "
        "and optionally ntrip.yaml (default: the installed config/)",
    )
    for role, port in DEFAULT_PORTS.items():
        parser.add_argument(f"--{role}-port", default=port, help=f"serial port of the {role}")
    parser.add_argument("--no-adu5", action="store_true", help="run without the ADU5")
    parser.add_argument(
        "--log-dir",
        type=Path,
        help="directory of the NAME.log of each process, appended to and rotated at 10 MB "
        "(default: $XDG_STATE_HOME/gnss_ins/logs, ~/.local/state/gnss_ins/logs without it)",
    )
    parser.add_argument(
        "--discovery",
        type=str.upper,
        choices=DISCOVERY_RANGES,
        default=DISCOVERY_RANGES[0],
        help="ROS 2 discovery range of the processes: LOCALHOST (only this machine reaches the "
        "nodes) or SUBNET (every host of the network with the same ROS_DOMAIN_ID can, e.g. "
        "publish a fix the fusion uses: see docs/operation.md on securing it)",
    )
    parser.add_argument(
        "--stop-on-failure",
        action="store_true",
        help="stop everything and exit with 1 when a process ends, instead of restarting it",
    )
    parser.add_argument(
        "--restart-silent",
        type=_silent_seconds,
        default=DEFAULT_SILENT_S,
        metavar="S",
        help="restart a process that still runs but has sent no /diagnostics status for S "
        "seconds (a hang; one that ends is restarted anyway). After a (re)start a process "
        f"has {START_GRACE_S:.0f} s for its first status. S must be at least "
        f"{MIN_SILENT_S:g} and longer than the nodes' diagnostics_period; 0 turns this off",
    )
    parser.add_argument(
        "--record",
        type=Path,
        metavar="DIR",
        help="also record the topics into DIR/vehicle_<UTC start time> with `gnss_ins record`, "
        "supervised like the nodes: a restarted recorder continues the same recording",
    )
    parser.add_argument(
        "--record-split",
        type=_split_seconds,
        default=DEFAULT_SPLIT_S,
        metavar="S",
        help="with --record: a new bag file every S seconds of recorded time (0: never)",
    )
    parser.add_argument(
        "--record-topics",
        type=Path,
        metavar="FILE",
        help=f"with --record: YAML file with the list 'topics:' to record "
        f"(default: the installed config/{TOPICS_FILE})",
    )
    parser.add_argument(
        "--record-storage",
        choices=STORAGES,
        default=STORAGES[0],
        help="with --record: rosbag2 storage plugin",
    )
    parser.add_argument(
        "--min-free",
        type=_checked_min_free,
        metavar="SIZE",
        help="with --record: passed to `gnss_ins record --min-free` (its free-space limit)",
    )
    add_ntrip_arguments(parser)


def add_ntrip_arguments(parser: argparse.ArgumentParser) -> None:
    """``--ntrip`` and ``--ntrip-password-file`` (also install-service's)."""
    parser.add_argument(
        "--ntrip",
        metavar="URL",
        help="also run the NTRIP client: corrections from http[s]://USER@HOST:PORT/MOUNTPOINT "
        f"to the Leica rover (password: ${PASSWORD_VARIABLE} or --ntrip-password-file, never "
        "in the URL; docs/ntrip.md)",
    )
    parser.add_argument(
        "--ntrip-password-file",
        type=Path,
        metavar="FILE",
        help="with --ntrip: the file holding the caster's password (mode 0600)",
    )


def ntrip_problem(args: argparse.Namespace, env: Mapping[str, str]) -> str | None:
    """Why ``--ntrip`` / ``--ntrip-password-file`` cannot be used with the environment ``env``
    (None: they can), checked before anything starts: a bad URL or password file would only
    make the client fail at every restart."""
    if args.ntrip is None:
        return "--ntrip-password-file without --ntrip" if args.ntrip_password_file else None
    try:
        parse_caster_url(args.ntrip)
        file = args.ntrip_password_file
        read_password(env, None if file is None else str(file))
    except ValueError as exc:
        return f"--ntrip: {exc}"
    return None


def _silent_seconds(text: str) -> float:
    """``--restart-silent``: 0 (off), or at least MIN_SILENT_S seconds."""
    value = float(text)
    if not math.isfinite(value) or not (value == 0 or value >= MIN_SILENT_S):
        raise argparse.ArgumentTypeError(f"{text}: 0 (never) or seconds >= {MIN_SILENT_S:g}")
    return value


def _kill_silent(group: ProcessGroup, args: argparse.Namespace, log_dir: Path) -> list[str]:
    """Kill the processes that have gone silent (ins_fusion.runtime.watchdog); the lines
    saying so. ``poll`` restarts them."""
    if args.restart_silent == 0 or args.stop_on_failure:
        return []
    found = silent(
        group.running_since(),
        REPORTING,
        STATUS_PROCESS,
        read_heard(log_dir),
        time.monotonic(),
        args.restart_silent,
    )
    return [group.kill(name, why) for name, why in found.items()]


def _split_seconds(text: str) -> float:
    """``--record-split``: seconds >= 0 (0: one file)."""
    value = float(text)
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"{text}: seconds >= 0 (0: never split)")
    return value


def _checked_min_free(text: str) -> str:
    """``--min-free`` refused here when ``gnss_ins record`` would refuse it: otherwise every
    restart of the recorder would end on it."""
    min_free_option(text)
    return text


def recording(args: argparse.Namespace) -> Recording:
    """The recorder of ``--record``, named now. Raises OSError or ValueError for a topics file
    that cannot be read."""
    topics = read_topics(args.record_topics or config_file(TOPICS_FILE))
    return Recording(
        args.record / recording_name(),
        tuple(topics),
        args.record_split,
        args.record_storage,
        args.min_free,
    )


def run(args: argparse.Namespace) -> int:
    """Start the nodes (and the recorder) and supervise them until Ctrl-C/SIGTERM; 0 then.
    With ``--stop-on-failure``: 1 as soon as a process ends. 2 on bad arguments."""
    if args.config is not None and not args.config.is_dir():
        print(f"gnss_ins launch: error: --config {args.config} is not a directory")
        return 2
    record: Recording | None = None
    if args.record is not None:
        try:
            record = recording(args)
            args.record.mkdir(parents=True, exist_ok=True)
        except (OSError, ValueError) as exc:
            print(f"gnss_ins launch: error: --record: {exc}")
            return 2
    if (problem := ntrip_problem(args, os.environ)) is not None:
        print(f"gnss_ins launch: error: {problem}")
        return 2
    log_dir = args.log_dir if args.log_dir is not None else default_log_dir()
    ports = {role: getattr(args, f"{role}_port") for role in DEFAULT_PORTS}
    env = {**os.environ, **discovery_environment(args.discovery)}
    group = ProcessGroup(log_dir, env, backoff=None if args.stop_on_failure else Backoff())
    stop = False

    def request_stop(*_: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    ended: list[str] = []
    try:
        for spec in VEHICLE:
            if spec is ADU5 and args.no_adu5:
                continue
            port = ports[spec.port_role] if spec.port_role else None
            group.start(spec.name, command(spec, args.config, port))
            print(f"started {spec.name}" + (f" on {port}" if port else ""), flush=True)
            if port is not None and not Path(port).exists():
                print(
                    f"warning: {port} does not exist; {spec.name} keeps trying to open it",
                    flush=True,
                )
        if args.ntrip is not None:
            extra = ntrip_parameters(args.ntrip, args.ntrip_password_file)
            own = args.config is not None and (args.config / NTRIP.config).is_file()
            group.start(NTRIP.name, command(NTRIP, args.config if own else None, None, extra))
            print(f"started {NTRIP.name}: corrections from {args.ntrip}", flush=True)
        if record is not None:
            group.start(RECORDER, record.command())
            print(
                f"started {RECORDER}: {len(record.topics)} topics into {record.output} "
                f"({record.storage}, a new file every {record.split_s:g} s)",
                flush=True,
            )
        group.start(STATUS_PROCESS, status_command(log_dir))
        print(f"started {STATUS_PROCESS}: the system's health on {STATUS_TOPIC}", flush=True)
        reach = "this machine only" if args.discovery == "LOCALHOST" else "the network"
        print(f"ROS discovery: {args.discovery} ({reach})", flush=True)
        then = "stops everything" if args.stop_on_failure else "is started again"
        print(
            f"logs in {log_dir}/ (their warnings and errors also here); a process that ends "
            f"{then}; Ctrl-C to stop",
            flush=True,
        )
        written: dict[str, Any] = {}
        while not stop and not (args.stop_on_failure and group.exited()):
            for line in [*group.poll(), *group.problems(), *_kill_silent(group, args, log_dir)]:
                print(line, flush=True)
            if (state := group.state()) != written:  # for `gnss_ins status`
                write_supervisor_state(log_dir, state)
                written = state
            time.sleep(_PERIOD_S)
        for line in group.problems():
            print(line, flush=True)
        ended = group.exited() if args.stop_on_failure else []
    finally:
        print("stopping the processes (the last started first)", flush=True)
        group.stop_all()
        write_supervisor_state(log_dir, group.state())
        print(f"stopped; logs in {log_dir}/", flush=True)
    for name in ended:
        print(f"gnss_ins launch: error: {name} stopped on its own; see {log_dir}/{name}.log")
    return 1 if ended else 0
