"""``gnss_ins echo TOPIC``: print the messages of a topic as YAML-like text, as ``ros2 topic
echo`` does, for a machine whose ROS 2 comes from PyPI (no ``ros2`` command).

The type is taken from the graph (the publishers'); the subscription is best effort and
volatile, so it matches any publisher and never holds one back. ``--count N`` stops after N
messages; Ctrl-C stops quietly. rclpy is imported only when listening starts.
"""

from __future__ import annotations

import argparse
import array
import sys
from collections.abc import Iterator
from typing import Any

from ins_fusion.runtime.priority import run_as_a_look

#: Longest sequence printed in full; longer ones are shortened to their first elements.
SHOWN_ELEMENTS = 32


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins echo``."""
    parser.add_argument("topic", help="topic name, e.g. /ins/odometry")
    parser.add_argument(
        "--count", type=int, default=0, metavar="N", help="stop after N messages (0: Ctrl-C)"
    )
    parser.add_argument(
        "--wait",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds to wait for a publisher of the topic to be discovered",
    )
    parser.add_argument("--field", help="print only this field, e.g. pose.pose.position")


def run(args: argparse.Namespace) -> int:
    """Print the topic's messages; 1 when no publisher appears within --wait, 2 on bad input."""
    run_as_a_look()  # below the vehicle's nodes (runtime.priority)
    from ins_fusion.tools.ros_echo import echo

    if args.count < 0 or not args.wait >= 0.0:
        print("gnss_ins echo: --count and --wait must be >= 0", file=sys.stderr)
        return 2

    def show(message: Any) -> None:
        if args.field:
            message = field(message, args.field)
        print("\n".join(lines(message)), "---", sep="\n", flush=True)

    def refuse(cls: Any) -> str | None:
        try:
            if args.field:
                field(cls(), args.field)
        except AttributeError as exc:
            return str(exc)
        return None

    return echo(args.topic, args.count, args.wait, show, refuse)


def field(message: Any, path: str) -> Any:
    """The field ``a.b.c`` of ``message`` (AttributeError naming the missing part)."""
    for name in path.split("."):
        if name not in fields(message):
            raise AttributeError(f"no field {name!r} in {type(message).__name__} ({path})")
        message = getattr(message, name)
    return message


def fields(message: Any) -> dict[str, str]:
    """The field names and types of a ROS message object, in declaration order ({} for a
    value)."""
    types = getattr(type(message), "get_fields_and_field_types", None)
    return dict(types()) if callable(types) else {}


def lines(value: Any, indent: str = "") -> Iterator[str]:
    """A message or value as YAML-like lines: ``name: value``, nested messages indented,
    sequences of messages as ``- `` items, short numeric sequences on one line, long ones
    shortened."""
    names = fields(value)
    if _is_sequence(value) and any(fields(element) for element in value):
        for element in value:
            first, *rest = lines(element, indent + "  ")
            yield f"{indent}- {first.lstrip()}"
            yield from rest
        return
    if not names:
        yield indent + _scalar(value)
        return
    for name, kind in names.items():
        item = getattr(value, name)
        if kind in ("octet", "byte"):  # one byte (bytes of length 1): its number
            yield f"{indent}{name}: {item[0]}"
        elif fields(item) or (_is_sequence(item) and any(fields(e) for e in item)):
            yield f"{indent}{name}:"
            yield from lines(item, indent + ("  " if fields(item) else ""))
        else:
            yield f"{indent}{name}: {_scalar(item)}"


def _is_sequence(value: Any) -> bool:
    return isinstance(value, (list, tuple, array.array)) or type(value).__name__ == "ndarray"


def _scalar(value: Any) -> str:
    if isinstance(value, (bytes, bytearray)):
        value = list(value)
    if _is_sequence(value):
        items = [_scalar(v) for v in list(value)[:SHOWN_ELEMENTS]]
        more = len(value) - SHOWN_ELEMENTS
        return "[" + ", ".join(items + ([f"... {more} more"] if more > 0 else [])) + "]"
    if isinstance(value, str):
        return repr(value)
    if hasattr(value, "item"):  # a numpy scalar
        value = value.item()
    return str(value)
