"""`gnss_ins launch`: start the vehicle's nodes for real hardware on a machine without `ros2`.

The same nodes, namespaces and remappings as launch/vehicle.launch.py
(ins_fusion.runtime.vehicle_nodes), each in its own process, until Ctrl-C/SIGTERM; a port that
does not exist, every WARN/ERROR line of a node's log (rate-limited by the nodes) and a node that
dies are reported on the console, and when one dies the others are stopped, so a broken cable or
port never leaves half a system running silently.
"""

from __future__ import annotations

import argparse
import signal
import time
from pathlib import Path

from ins_fusion.runtime.processes import ProcessGroup
from ins_fusion.runtime.vehicle_nodes import ADU5, DEFAULT_PORTS, VEHICLE, command


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Ports and parameter files."""
    parser.add_argument(
        "--config",
        type=Path,
        help="directory with imu400cc.yaml, gnss_leica.yaml, gnss_adu5.yaml, ins_fusion.yaml "
        "(default: the installed config/)",
    )
    for role, port in DEFAULT_PORTS.items():
        parser.add_argument(f"--{role}-port", default=port, help=f"serial port of the {role}")
    parser.add_argument("--no-adu5", action="store_true", help="run without the ADU5")
    parser.add_argument(
        "--log-dir", type=Path, default=Path("gnss_ins_logs"), help="one NAME.log per node"
    )


def run(args: argparse.Namespace) -> int:
    """Start the nodes and wait; returns 1 when a node stopped on its own."""
    if args.config is not None and not args.config.is_dir():
        print(f"gnss_ins launch: error: --config {args.config} is not a directory")
        return 2
    ports = {role: getattr(args, f"{role}_port") for role in DEFAULT_PORTS}
    group = ProcessGroup(args.log_dir)
    stop = False
    ended: list[str] = []

    def request_stop(*_: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
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
        print(f"logs in {args.log_dir}/ (their warnings and errors also here); Ctrl-C to stop")
        while not stop and not group.exited():
            for line in group.problems():
                print(line, flush=True)
            time.sleep(0.2)
        for line in group.problems():
            print(line, flush=True)
        ended = group.exited()
    finally:
        group.stop_all()
    for name in ended:
        print(f"gnss_ins launch: error: {name} stopped on its own; see {args.log_dir}/{name}.log")
    return 1 if ended else 0
