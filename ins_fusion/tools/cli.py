"""`gnss_ins`: run, record and check the GNSS/INS on the vehicle, and work with its recordings.

Each sub-command is a module in ins_fusion/tools that defines ``add_arguments(parser)`` and
``run(args) -> int``; register it in ``SUBCOMMANDS`` and in one of ``GROUPS`` below. Only the
chosen sub-command's module is imported, so ``gnss_ins --help`` stays fast and a sub-command
that needs rclpy does not slow down one that does not.
"""

from __future__ import annotations

import argparse
import atexit
import gc
import importlib
import importlib.metadata
import os
import sys
from collections.abc import Callable
from typing import Any

#: sub-command name -> (module under ins_fusion.tools, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "batch": ("batch", "many bags replayed on a Dask cluster: per-bag results, fleet summary"),
    "allan": ("allan", "IMU noise terms from a static bag (Allan deviation) as fusion parameters"),
    "calibrate": ("calibrate", "IMU laboratory calibration from bags: biases, scales, axes"),
    "emulate": (
        "emulate",
        "IMU, Leica and ADU5 emulated together on one simulated drive (for launch)",
    ),
    "emulate-imu": ("emulate_imu", "emulated IMU400CC on a pseudo-terminal"),
    "emulate-gnss": ("emulate_gnss", "emulated Leica RTK rover or ADU5 on a pseudo-terminal"),
    "emulate-caster": ("emulate_caster", "NTRIP caster on 127.0.0.1 serving an RTCM 3 capture"),
    "demo": (
        "demo",
        "the whole system on a simulated drive: emulators, nodes, bag, accuracy report",
    ),
    "launch": (
        "launch",
        "start and supervise the vehicle's nodes for real hardware (no ros2 needed)",
    ),
    "imu-demo": ("imu_demo", "run imu400cc_node on an emulated device and print what it publishes"),
    "import-qfree": ("import_qfree", "Q-Free OBU GNSS/MEMS text logs to a rosbag2 bag"),
    "record": ("record", "record ROS 2 topics to a rosbag2 bag (MCAP or sqlite3)"),
    "install-service": ("install_service", "start the vehicle daemon at boot (a systemd unit)"),
    "list-devices": ("list_devices", "serial adapters with their stable /dev/serial/by-id names"),
    "status": ("status", "the vehicle's health on one screen (or --json), from /diagnostics"),
    "topics": ("topics", "the topics on the ROS domain: type, publishers, subscribers"),
    "echo": ("echo", "print a topic's messages (as ros2 topic echo, without ros2)"),
    "redecode": (
        "redecode",
        "a recording's raw device bytes through today's drivers: a new bag, outputs rebuilt",
    ),
    "recover": ("recover", "a readable bag from a recording that was killed (no metadata.yaml)"),
    "play": ("play", "publish a rosbag2 bag with its timing and /clock"),
    "replay": ("replay", "bag through the fusion core offline: accuracy report, plot, sweeps"),
    "simulate": ("simulate", "simulated drive to a rosbag2 bag, or live on emulated devices"),
}

#: The sub-commands as ``gnss_ins --help`` lists them: by what the user is doing.
GROUPS: dict[str, tuple[str, ...]] = {
    "on the vehicle": (
        "launch",
        "status",
        "topics",
        "echo",
        "record",
        "list-devices",
        "install-service",
    ),
    "recordings, offline": ("replay", "play", "redecode", "recover", "batch", "import-qfree"),
    "calibration and noise": ("calibrate", "allan"),
    "without hardware": (
        "demo",
        "simulate",
        "emulate",
        "emulate-imu",
        "emulate-gnss",
        "emulate-caster",
        "imu-demo",
    ),
}

#: Sub-commands that run OpenBLAS single-threaded unless the user set OPENBLAS_NUM_THREADS: the
#: engine's matrices are at most 21 x 21 and a replay's work on whole tracks gains nothing
#: measurable from more threads, whose start at numpy's import alone costs ~0.07 s of CPU (a
#: whole replay: ~0.2 s less, docs/benchmarks.md).
SINGLE_THREAD_BLAS = frozenset({"replay", "batch"})


def argument_type(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """An argparse ``type`` from a parser raising ValueError (argparse then exits with 2)."""

    def convert(text: str) -> Any:
        try:
            return parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    convert.__name__ = parse.__name__
    return convert


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """Appends ``(default: X)`` to an option's help when it has a default worth showing and its
    help does not already name one."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        nothing = default is None or default is False or default == argparse.SUPPRESS
        if "default" in text or nothing or default in ([], ()) or not action.option_strings:
            return text
        return f"{text} (default: %(default)s)"


def version() -> str:
    """The installed package's version (setup.py, package.xml)."""
    try:
        return importlib.metadata.version("gnss_ins")
    except importlib.metadata.PackageNotFoundError:
        return "unknown (not installed)"


def build_parser(command: str | None) -> argparse.ArgumentParser:
    """Parser listing every sub-command; only ``command``'s module is imported for its options."""
    parser = argparse.ArgumentParser(
        prog="gnss_ins",
        description=__doc__.splitlines()[0].strip("`").replace("`", ""),
        epilog=commands_text(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", help="one of the commands below"
    )
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        sub_parser = sub.add_parser(
            name, description=help_text, formatter_class=DefaultsHelpFormatter
        )
        if name == command:
            module = importlib.import_module(f"ins_fusion.tools.{module_name}")
            module.add_arguments(sub_parser)
            sub_parser.set_defaults(_module=module)
    return parser


def commands_text() -> str:
    """The sub-commands with their one-line help, in GROUPS."""
    width = max(len(name) for name in SUBCOMMANDS) + 2
    lines = []
    for title, names in GROUPS.items():
        lines.append(f"{title}:")
        lines += [f"  {name:<{width}}{SUBCOMMANDS[name][1]}" for name in names]
        lines.append("")
    lines.append("`gnss_ins COMMAND --help`: the command's options with their defaults.")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``gnss_ins`` console script."""
    # The interpreter's shutdown runs full collections over every object still alive: with
    # numba's kernels loaded ~0.6 s of CPU at every exit. Frozen (after the exit handlers the
    # command registers: atexit runs the last registered first) they are skipped; objects
    # are still released, the standard streams flushed.
    atexit.unregister(gc.freeze)
    atexit.register(gc.freeze)
    argv = sys.argv[1:] if argv is None else argv
    command = next((arg for arg in argv if not arg.startswith("-")), None)
    if command in SINGLE_THREAD_BLAS:  # before the sub-command's module imports numpy
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    args = build_parser(command).parse_args(argv)
    try:
        return int(args._module.run(args))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
