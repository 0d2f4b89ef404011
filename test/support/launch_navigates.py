"""Whether `gnss_ins launch` navigates on the emulated devices: run by the docs test while the
README's launch example runs (the block's ``until=`` option, test/support/docs_pages.py).

Listens to /diagnostics. Once ins_fusion_node reports 'navigating' at level OK (aligned and
settled), it counts the Leica's position fixes (its gnss_node's ``fixes_*`` counters) and the
fusion's ``gnss_position.used`` over the next WINDOW_FIXES fixes, and watches every fusion status
meanwhile. Exit status 0 when at least MIN_USED_SHARE of those fixes were used and the fusion
stayed 'navigating' at level OK throughout; 1 otherwise, or when it did not settle or the Leica
did not deliver within the time limits. Prints one line with the numbers either way, then the
`gnss_ins status --json` view of the fusion as an operator would read it.

    .venv/bin/python test/support/launch_navigates.py [--fixes N]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor

#: Fixes counted after the fusion settled (the Leica sends one a second): with the README's
#: emulated drive this reaches ~50 s into the driving after its 60 s standstill.
WINDOW_FIXES = 100
#: Least share of those fixes the fusion must use.
MIN_USED_SHARE = 0.95
#: Time limits [s]: from the start to the first settled status (node start-up, the kernels
#: loaded, 10 s of levelling, 5 s settling), and per fix of the window.
SETTLE_LIMIT_S = 150.0
PER_FIX_LIMIT_S = 2.0
FUSION, LEICA = "ins_fusion_node", "leica_gnss"
#: The Leica's counters of fixes by type that hold no position.
NOT_A_POSITION = ("fixes_no_fix", "fixes_2d")


def leica_fixes(values: dict[str, str]) -> int:
    """The position fixes the Leica's gnss_node has published (all types with a position)."""
    return sum(
        int(v) for k, v in values.items() if k.startswith("fixes_") and k not in NOT_A_POSITION
    )


@dataclass
class Watch:
    """What the statuses said: the counts when the fusion settled and now, and every state the
    fusion was in (with its first message) before and after settling."""

    settled_at: tuple[int, int] | None = None  # (leica fixes, fusion used) at settling
    now: tuple[int, int] = (0, 0)
    leica: int = 0
    before: dict[str, str] = field(default_factory=dict)
    after: dict[str, str] = field(default_factory=dict)

    def take(self, array: Any) -> None:
        for status in array.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name.startswith(f"{LEICA}:"):
                self.leica = leica_fixes(values)
            elif status.name.startswith(f"{FUSION}:"):
                self._fusion(values, status.level[0], status.message)

    def _fusion(self, values: dict[str, str], level: int, message: str) -> None:
        state, used = values.get("state", "?"), int(values.get("gnss_position.used", 0))
        self.now = (self.leica, used)
        good = state == "navigating" and level == 0
        if self.settled_at is None and good:
            self.settled_at = self.now
        seen = self.before if self.settled_at is None else self.after
        key = state if good else f"{state} ({['OK', 'WARN', 'ERROR', 'STALE'][level]})"
        seen.setdefault(key, message)

    def window(self) -> tuple[int, int]:
        """(fixes, used) since settling."""
        assert self.settled_at is not None
        return self.now[0] - self.settled_at[0], self.now[1] - self.settled_at[1]


def listen(watch: Watch, fixes: int) -> str | None:
    """Spin until the window is full; what went wrong, or None."""
    rclpy.init(args=["--ros-args", "--disable-external-lib-logs"])
    node = rclpy.create_node("launch_navigates")
    node.create_subscription(DiagnosticArray, "/diagnostics", watch.take, 100)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    start = time.monotonic()
    try:
        while watch.settled_at is None:
            if time.monotonic() - start > SETTLE_LIMIT_S:
                return f"the fusion was not navigating (OK) after {SETTLE_LIMIT_S:g} s"
            executor.spin_once(timeout_sec=0.1)
        settled = time.monotonic()
        while watch.window()[0] < fixes:
            if time.monotonic() - settled > fixes * PER_FIX_LIMIT_S:
                return f"only {watch.window()[0]} Leica fixes in {fixes * PER_FIX_LIMIT_S:g} s"
            executor.spin_once(timeout_sec=0.1)
        return None
    finally:
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        rclpy.try_shutdown()


def operator_view() -> str:
    """The fusion's row of `gnss_ins status --json`."""
    status = Path(sys.executable).parent / "gnss_ins"
    result = subprocess.run(
        [str(status), "status", "--json"], capture_output=True, text=True, timeout=60
    )
    try:
        fusion = json.loads(result.stdout)["processes"][FUSION]
    except (ValueError, KeyError):
        return f"gnss_ins status --json: exit {result.returncode}: {result.stdout}{result.stderr}"
    return f"gnss_ins status: {FUSION} {fusion['level']} {fusion['message']}: {fusion['values']}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fixes", type=int, default=WINDOW_FIXES, help="fixes counted")
    args = parser.parse_args()
    watch = Watch()
    problem = listen(watch, args.fixes)
    states = f"states before settling: {watch.before or 'none'}; after: {watch.after or 'none'}"
    if problem is None:
        fixes, used = watch.window()
        share = used / fixes
        print(
            f"launch navigates: {used} of {fixes} Leica fixes used ({100 * share:.1f} %); {states}"
        )
        if share < MIN_USED_SHARE:
            problem = f"less than {100 * MIN_USED_SHARE:g} % of the fixes used"
        elif set(watch.after) != {"navigating"}:
            problem = "the fusion left 'navigating' (OK) after it settled"
    else:
        print(f"launch navigates: {states}")
    print(operator_view(), flush=True)
    if problem is not None:
        print(f"launch navigates: FAILED: {problem}", flush=True)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
