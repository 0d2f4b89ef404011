"""False-accept and loss rates of the IMU400CC PacketFramer under serial-line damage; prints
numbers, asserts nothing.

For each damage kind (one byte dropped / inserted / changed, anywhere in the packet), a stream
of PACKETS realistic packets (test/support/framer_damage.py: half at rest, half driving) with every
5th packet damaged, framed in continuous mode (timer-step fit or next-packet confirmation) and
in polled mode (checksum only). Targets (issue 12): at most 1 false packet per 10 000 damaged
ones, and no intact packet lost after a single dropped byte.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "test"))  # the harness is a test helper

from support.framer_damage import KINDS, realistic_packets, run_damaged  # noqa: E402

PACKETS = 500_000
SEED = 3


def main() -> None:
    rng = np.random.default_rng(SEED)
    packets = realistic_packets(PACKETS, rng)
    print(f"PacketFramer, {PACKETS:,} packets per run, 1 in 5 damaged")
    for confirm in (True, False):
        for kind in KINDS:
            start = time.perf_counter()
            r = run_damaged(packets, kind, rng, confirm)
            elapsed = time.perf_counter() - start
            print(
                f"  {'continuous' if confirm else 'polled':>10} {kind:>6}: damaged {r.damaged:,},"
                f" false {r.false} ({r.false / r.damaged * 1e4:.2f} per 10 000;"
                f" {r.false_values} with false measurements),"
                f" intact lost {r.lost} (after the damaged one: {r.lost_after_damage})"
                f" [{elapsed:.1f} s]"
            )


if __name__ == "__main__":
    main()
