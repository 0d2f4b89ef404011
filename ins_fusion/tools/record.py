"""``gnss_ins record``: record ROS 2 topics into a rosbag2 bag (MCAP by default).

The recording node (ins_fusion/tools/ros_record.py) subscribes with ``raw=True`` to each
requested topic as soon as a publisher of it appears, with the QoS its publishers offer, and
writes what it receives on a writer thread in log-time order, flushed within 0.65 s of its
reception (what a SIGKILL or power cut loses; ``gnss_ins recover`` reads the rest). Ctrl-C or
SIGTERM stops the subscriptions, takes every message already received, and closes the bag
cleanly. A disk guard watches the free space (ins_fusion/bags/recording.py). ``--resume``
continues an existing recording (a supervised recorder that was restarted); the unfinished file
of the recorder before is salvaged in a child process, so the recorder does not keep its memory.

Exit codes: 0 recorded and closed; 1 writing failed (the bag is left for ``gnss_ins recover``);
2 bad arguments; 3 stopped by the disk guard (the bag is closed and complete) or refused to start
below the free-space limit.

rclpy is imported only when recording starts (this module is loaded by ``gnss_ins --help``).
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import re
import sys
from pathlib import Path

from ins_fusion.bags.bag_io import STORAGES, BagError, BagWriter
from ins_fusion.bags.recording import DEFAULT_MIN_FREE, POLICIES, MinFree, RecordingWriter
from ins_fusion.bags.recording import free_space as read_free_space

#: Exit code of a recording stopped (or not started) by the disk guard.
EXIT_DISK_FULL = 3
#: The recorder's node name unless --name gives one.
DEFAULT_NAME = "gnss_ins_record"
#: How long a message is held to be written in log-time order, and the longest time a written
#: message waits to be flushed (s): a kill loses at most their sum.
HOLD_S, FLUSH_PERIOD_S = 0.2, 0.4


def min_free_option(text: str) -> MinFree:
    """``--min-free`` as argparse reads it (also ``gnss_ins launch --min-free``)."""
    try:
        return MinFree.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc


def _node_name(text: str) -> str:
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", text):
        raise argparse.ArgumentTypeError(f"{text!r}: a ROS node name (letters, digits, _)")
    return text


def _seconds(text: str) -> float:
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text}: a positive number of seconds")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins record``."""
    parser.add_argument("topics", nargs="*", help="topics to record (relative names resolved)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="bag directory to create")
    parser.add_argument("-a", "--all", action="store_true", help="record every topic that appears")
    parser.add_argument(
        "--storage", choices=sorted(STORAGES), default="mcap", help="rosbag2 storage plugin"
    )
    parser.add_argument(
        "--max-bag-size",
        type=int,
        default=0,
        metavar="BYTES",
        help="start a new file when a file's message bytes would exceed BYTES (0: never)",
    )
    parser.add_argument(
        "--max-bag-duration",
        type=float,
        default=0.0,
        metavar="S",
        help="start a new file after S seconds of recorded time (0: never)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the recording in OUTPUT if it exists (its unfinished file is recovered "
        "into a new one) instead of refusing it",
    )
    parser.add_argument(
        "--min-free",
        type=min_free_option,
        default=MinFree.parse(DEFAULT_MIN_FREE),
        metavar="SIZE",
        help="free space kept on the bag's file system: a size (500M, 1G), a percentage (5%%) "
        "or both, the smaller applies; 0 switches the guard off (default "
        + DEFAULT_MIN_FREE.replace("%", "%%")
        + ")",
    )
    parser.add_argument(
        "--on-disk-full",
        choices=POLICIES,
        default="stop",
        help="at the free-space limit: close the bag and stop, or delete the oldest files of "
        "this recording (needs --max-bag-duration or --max-bag-size) (default: stop)",
    )
    parser.add_argument(
        "--name",
        type=_node_name,
        default=DEFAULT_NAME,
        help="the recorder's ROS node name, which names its /diagnostics status "
        f"('NAME: recording'; default {DEFAULT_NAME}; gnss_ins launch's is 'recorder')",
    )
    parser.add_argument(
        "--silence-warning",
        type=_seconds,
        default=5.0,
        metavar="S",
        help="warn when a streaming recorded topic with a publisher has been silent for S s "
        "(default 5; a topic that carries messages on events only is never silent)",
    )


def run(args: argparse.Namespace) -> int:
    """Record until Ctrl-C/SIGTERM; prints the summary (exit codes: module docstring)."""
    if not args.topics and not args.all:
        print("gnss_ins record: error: name topics to record or use --all", file=sys.stderr)
        return 2
    disk = args.output if args.output.exists() else args.output.parent
    if refused := _below_limit(disk.resolve(), args.min_free):
        print(f"gnss_ins record: error: {refused}; not recording", file=sys.stderr)
        return EXIT_DISK_FULL
    if args.resume and args.output.exists():
        _continue_in_child(args.output, args.storage)
    try:
        writer = BagWriter(
            args.output,
            storage=args.storage,
            max_file_bytes=args.max_bag_size,
            max_file_duration_s=args.max_bag_duration,
            resume=args.resume,
        )
    except BagError as exc:
        print(f"gnss_ins record: error: {exc}", file=sys.stderr)
        return 2
    _say_continued(args.output, writer)
    recording = RecordingWriter(
        writer,
        _print_log,
        hold_s=HOLD_S,
        flush_period_s=FLUSH_PERIOD_S,
        min_free=args.min_free,
        policy=args.on_disk_full,
    )
    from ins_fusion.tools.ros_record import record

    lost, failure, subscribed_s = record(
        recording, None if args.all else list(args.topics), args.silence_warning, args.name
    )
    if failure is not None:
        print(
            f"gnss_ins record: error: writing {args.output} failed: {failure!r}; "
            f"`gnss_ins recover {args.output}` restores what reached the disk",
            file=sys.stderr,
        )
        return 1
    title = f"bag {args.output} ({args.storage}, files: {len(writer.files)})"
    print(writer.summary.format(title + (" (this run)" if args.resume else "")))
    lost_text = ", ".join(f"{t} {n}" for t, n in sorted(lost.items()) if n) or "none"
    if subscribed_s:
        first, last = min(subscribed_s.values()), max(subscribed_s.values())
        span = f"{first:.1f} s" if last - first < 0.05 else f"{first:.1f}-{last:.1f} s"
        print(
            f"  topics subscribed {span} after the start: messages published before are not"
            " in the bag (a latched topic's history excepted)"
        )
    print(f"  lost in transport once subscribed (reported by the middleware): {lost_text}")
    print(f"  received later than {HOLD_S} s after a later message: {recording.late}")
    for path in recording.deleted:
        print(f"  deleted by the disk guard: {path.name}")
    if recording.stopped is not None:
        print(f"gnss_ins record: error: {recording.stopped}", file=sys.stderr)
        return EXIT_DISK_FULL
    return 0


def _continue_in_child(output: Path, storage: str) -> None:
    """Write what the unfinished files of the recording ``output`` hold into new files, in a
    child process: salvaging reads a whole file's messages into memory (tens of MB for a few
    minutes of the vehicle's topics), which the recorder would otherwise keep for the rest of
    its run (freed memory is not returned by the allocator). Forked before rclpy starts. If the
    child fails, the recorder's own ``BagWriter`` does the same work (and reports the error)."""
    child = multiprocessing.get_context("fork").Process(
        target=_write_unfinished, args=(output, storage), name="gnss_ins_record_resume"
    )
    child.start()
    child.join()


def _write_unfinished(output: Path, storage: str) -> None:
    """The child of ``_continue_in_child``: the recording continued and closed again."""
    try:
        writer = BagWriter(output, storage=storage, resume=True)
    except BagError:
        sys.exit(2)  # the recorder's own BagWriter reports it
    _say_continued(output, writer)
    writer.close()


def _say_continued(output: Path, writer: BagWriter) -> None:
    for found in writer.resumed:
        print(
            f"continuing {output}: {len(found.messages)} messages of the unfinished "
            f"{found.path.name} written into a new file",
            file=sys.stderr,
        )


def _below_limit(path: Path, min_free: MinFree) -> str | None:
    """Why recording must not start on the file system of ``path`` (None: it may)."""
    free = read_free_space(path)
    limit = min_free.limit(free.total_bytes)
    if limit > 0 and free.free_bytes < limit:
        return f"{free.free_bytes} bytes free on the file system of {path}, below --min-free"
    return None


def _print_log(level: str, text: str) -> None:
    """The recording's messages on stderr, in the rcutils form ``gnss_ins launch`` scans."""
    print(f"[{level.upper()}] [gnss_ins_record]: {text}", file=sys.stderr, flush=True)
