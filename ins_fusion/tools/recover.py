"""``gnss_ins recover``: a readable bag from a recording that did not finish (killed, power cut).

The unfinished bag is only read; its messages go to a new bag (``BAG_recovered`` by default),
written under a temporary name and renamed when complete. See ins_fusion/bags/recover.py for
what is recovered, and docs/bags.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ins_fusion.bags.bag_io import BagError
from ins_fusion.bags.recover import recover_bag


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins recover``."""
    parser.add_argument("bag", type=Path, help="bag directory of the unfinished recording")
    parser.add_argument(
        "-o", "--output", type=Path, help="bag directory to create (default: BAG_recovered)"
    )


def run(args: argparse.Namespace) -> int:
    """Recover and print the summary; 2 when there is nothing to recover or the output exists."""
    bag = Path(args.bag)
    output = args.output or bag.with_name(f"{bag.name}_recovered")
    if not bag.is_dir():
        print(f"gnss_ins recover: error: {bag}: not a bag directory", file=sys.stderr)
        return 2
    try:
        recovered = recover_bag(bag, output)
    except (BagError, OSError) as exc:
        print(f"gnss_ins recover: error: {exc}", file=sys.stderr)
        return 2
    print(recovered.format(f"bag {output} recovered from {len(recovered.files)} file(s):"))
    return 0
