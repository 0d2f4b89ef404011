"""`gnss_ins emulate-caster`: an NTRIP caster on 127.0.0.1 serving an RTCM 3 capture in a loop."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
from pathlib import Path

from gnss_driver.emulator import AALBORG_LLH
from ins_fusion.tools.cli import argument_type
from ntrip_client.caster_emulator import CasterEmulator
from ntrip_client.caster_url import PASSWORD_VARIABLE

#: The capture of the repository's tests (pyrtcm's, BSD-3; test/fixtures/rtcm/README.md); an
#: installed copy has none and needs --capture.
REPOSITORY_CAPTURE = (
    Path(__file__).resolve().parents[2] / "test/fixtures/rtcm/pygpsdata-NTRIP-USCL00CHL0.log"
)


def mountpoint(text: str) -> tuple[str, tuple[float, float]]:
    """``NAME`` (at Aalborg) or ``NAME@LAT,LON`` [deg]."""
    name, at, position = text.partition("@")
    if not name or any(c.isspace() or c == "/" for c in name):
        raise ValueError(f"mountpoint {text!r}: a name without spaces or '/'")
    if not at:
        return name, AALBORG_LLH[:2]
    try:
        lat, lon = (float(value) for value in position.split(","))
    except ValueError:
        raise ValueError(f"mountpoint {text!r}: expected NAME@LAT,LON in degrees") from None
    return name, (lat, lon)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the emulated caster."""
    parser.add_argument("--port", type=int, default=2101, help="TCP port on 127.0.0.1 (0: any)")
    parser.add_argument(
        "--mountpoint",
        type=argument_type(mountpoint),
        nargs="+",
        metavar="NAME[@LAT,LON]",
        help="mountpoints to serve (default: AAU00DNK at Aalborg)",
    )
    parser.add_argument(
        "--user", help=f"require this user, with the password of ${PASSWORD_VARIABLE}"
    )
    parser.add_argument(
        "--capture",
        type=Path,
        help="RTCM 3 capture whose frames are served in a loop (default: the repository's"
        " test/fixtures/rtcm capture)",
    )
    parser.add_argument("--rate", type=float, default=1000.0, help="bytes per second served")
    parser.add_argument(
        "--ntrip1-only", action="store_true", help="answer every request NTRIP 1 (ICY 200 OK)"
    )


def _error(message: str, code: int) -> int:
    print(f"gnss_ins emulate-caster: error: {message}", file=sys.stderr)
    return code


def run(args: argparse.Namespace) -> int:
    """Serve until SIGINT/SIGTERM; prints the address and mountpoints first."""
    capture = args.capture or REPOSITORY_CAPTURE
    if args.capture is None and not capture.is_file():
        return _error(f"no --capture given and no repository capture here ({capture})", 2)
    if args.user and not os.environ.get(PASSWORD_VARIABLE):
        return _error(f"--user needs the password in the environment, ${PASSWORD_VARIABLE}", 2)
    if not args.rate > 0:
        return _error(f"--rate {args.rate:g}: must be > 0 bytes per second", 2)
    try:
        data = capture.read_bytes()
        mountpoints = dict(args.mountpoint or [("AAU00DNK", AALBORG_LLH[:2])])
        credentials = (args.user, os.environ[PASSWORD_VARIABLE]) if args.user else None
        caster = CasterEmulator(
            data,
            mountpoints,
            credentials,
            port=args.port,
            rate_bytes_s=args.rate,
            ntrip1_only=args.ntrip1_only,
        )
        caster.start()
    except (OSError, ValueError) as exc:
        return _error(str(exc), 1)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    try:
        names = " ".join(mountpoints)
        auth = f", user {args.user}" if args.user else ", no authentication"
        print(f"caster on 127.0.0.1:{caster.port} mountpoints {names}{auth}. Ctrl-C to stop.")
        print(f"serving {len(caster.frames)} frames of {capture} at {args.rate:g} B/s", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            done.wait()
    finally:
        caster.stop()
    print(f"{caster.connections} connections, {len(caster.sent_frames)} frames sent")
    return 0
