"""``gnss_ins install-service``: start the vehicle daemon at boot with systemd.

Writes /etc/systemd/system/gnss_ins.service (``--dry-run``: prints it) for ``gnss_ins launch``
with the given ports, log directory and recording, run as ``--user`` with ROS_DOMAIN_ID fixed,
restarted by systemd whenever it ends (ins_fusion/runtime/service.py). Then:
``systemctl daemon-reload && systemctl enable --now gnss_ins``. Ports are best given as
/dev/serial/by-id/... paths (``gnss_ins list-devices``), which do not change with the order of
plugging. Refuses to replace an existing unit unless ``--force``. ``--ntrip URL`` adds the NTRIP
client; its password comes from ``--ntrip-password-file`` only (mode 0600, readable by
``--user``): the unit file is world-readable, so no password is ever written into it.
"""

from __future__ import annotations

import argparse
import getpass
import sys
from pathlib import Path

from ins_fusion.runtime.health import write_whole
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.service import SYSTEM_UNIT_DIR, UNIT_NAME, Service, unit_text
from ins_fusion.runtime.vehicle_nodes import DEFAULT_PORTS
from ins_fusion.tools.launch import add_ntrip_arguments, ntrip_problem
from ntrip_client.caster_url import PASSWORD_VARIABLE, parse_caster_url


def _domain(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 101:
        raise argparse.ArgumentTypeError(f"{text}: a ROS domain id in [0, 101]")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins install-service``."""
    for role, port in DEFAULT_PORTS.items():
        parser.add_argument(f"--{role}-port", default=port, help=f"serial port of the {role}")
    parser.add_argument("--no-adu5", action="store_true", help="run without the ADU5")
    parser.add_argument("--user", default=getpass.getuser(), help="user the daemon runs as")
    parser.add_argument(
        "--working-dir", type=Path, default=Path.cwd(), help="the daemon's working directory"
    )
    parser.add_argument(
        "--log-dir",
        type=Path,
        help="launch's log directory (default: launch's, under the user's state directory)",
    )
    parser.add_argument("--record", type=Path, metavar="DIR", help="record into DIR")
    parser.add_argument("--domain-id", type=_domain, default=0, help="ROS_DOMAIN_ID")
    parser.add_argument(
        "--unit-dir", type=Path, default=SYSTEM_UNIT_DIR, help="where the unit file goes"
    )
    add_ntrip_arguments(parser)
    parser.add_argument("--dry-run", action="store_true", help="print the unit, write nothing")
    parser.add_argument("--force", action="store_true", help="replace an existing unit file")


def _ntrip_problem(args: argparse.Namespace) -> str | None:
    """Why the NTRIP options cannot go into a unit (None: they can). The unit carries no
    environment, so a caster user's password can only come from ``--ntrip-password-file``: an
    ``NTRIP_PASSWORD`` of the shell that installs the unit would never reach the daemon."""
    if (problem := ntrip_problem(args, {})) is not None:
        return problem
    if args.ntrip is None or args.ntrip_password_file is not None:
        return None
    if parse_caster_url(args.ntrip).user:
        return (
            f"--ntrip with the user of {args.ntrip}: give its password with"
            f" --ntrip-password-file (a unit carries no {PASSWORD_VARIABLE})"
        )
    return None


def launch_options(args: argparse.Namespace) -> list[str]:
    """``gnss_ins launch``'s options for the unit."""
    options = [f"--{role}-port={getattr(args, f'{role}_port')}" for role in DEFAULT_PORTS]
    if args.no_adu5:
        options.append("--no-adu5")
    if args.log_dir is not None:
        options.append(f"--log-dir={args.log_dir.absolute()}")
    if args.record is not None:
        options.append(f"--record={args.record.absolute()}")
    if args.ntrip is not None:
        options.append(f"--ntrip={args.ntrip}")
    if args.ntrip_password_file is not None:
        options.append(f"--ntrip-password-file={args.ntrip_password_file.absolute()}")
    return options


def run(args: argparse.Namespace) -> int:
    """Print or write the unit; 2 when it exists (without ``--force``) or cannot be written, or
    the NTRIP options are wrong."""
    if (problem := _ntrip_problem(args)) is not None:
        print(f"gnss_ins install-service: error: {problem}", file=sys.stderr)
        return 2
    script = Path(sys.executable).parent / "gnss_ins"  # the console script of this install
    launch = ["launch", *launch_options(args)]
    service = Service(
        [str(script), *launch] if script.exists() else gnss_ins_command(*launch),
        args.user,
        args.working_dir.absolute(),
        args.domain_id,
    )
    text = unit_text(service)
    if args.dry_run:
        print(text, end="")
        return 0
    path = args.unit_dir / UNIT_NAME
    if path.exists() and not args.force:
        print(
            f"gnss_ins install-service: error: {path} exists; --force replaces it", file=sys.stderr
        )
        return 2
    try:
        write_whole(path, text)
    except OSError as exc:
        print(f"gnss_ins install-service: error: {exc} (as root: sudo)", file=sys.stderr)
        return 2
    print(f"wrote {path}; start it now and at every boot with:")
    print("  sudo systemctl daemon-reload && sudo systemctl enable --now gnss_ins")
    print("  journalctl -u gnss_ins -f     # launch's console; gnss_ins status for the health")
    return 0
