"""Start-up cost of `gnss_ins replay` and of the fusion node's engine; prints numbers only.

1. `gnss_ins replay BAG --report FILE` on a 20 s simulated bag (the figure-eight, so the filter
   starts and runs): CPU seconds (user + system) of the whole command, median of ``--runs``,
   after one untimed run (which fills numba's cache on a fresh tree).
2. A fresh Python that imports ``ins_fusion.node`` (rclpy, messages, the engine) and feeds an
   InsEngine the bag's IMU and GNSS until its first solution: CPU seconds of the process, the
   node's start-up before it publishes, without the DDS discovery.

Compare trees with PYTHONPATH=<tree> (both use this Python's installed dependencies).

    .venv/bin/python bench/bench_startup.py [--runs 5]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

from speed_bag import gnss_ins_command

from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.simulated_bag import write_bag

#: Imports the node's modules, feeds the engine until its first solution (argv: bag).
_FIRST_SOLUTION = """
import sys
import ins_fusion.node  # rclpy, the messages, the engine: what the node imports
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.topics import TopicMap

inputs = load_bag(sys.argv[1], TopicMap())
warm_up()  # as the node does before it builds its engine
engine = InsEngine(FusionConfig.from_parameters({}))
feed = {
    "fix": engine.add_gnss_fix,
    "vel": engine.add_gnss_velocity,
    "attitude": engine.add_attitude,
}
kept, j = inputs.measurements, 0
for k, (t, rate, force) in enumerate(inputs.imu.samples()):
    while j < len(kept) and kept[j][0] <= k:
        feed[kept[j][1]](kept[j][2])
        j += 1
    engine.add_imu(t, rate, force)
    if engine.solution() is not None:
        print(f"first solution after {k} IMU samples")
        break
"""


def child_cpu(command: list[str]) -> float:
    """CPU seconds (user + system) of a child process run to its end."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=5, help="timed runs of each (default 5)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "startup"
        with redirect_stdout(StringIO()):
            write_bag(SimulationConfig(scenario="figure_eight", duration_s=20.0, seed=2), bag)
        commands = {
            "gnss_ins replay (20 s bag, whole command)": [
                *gnss_ins_command(),
                "replay",
                str(bag),
                f"--report={Path(tmp) / 'report.json'}",
            ],
            "node imports + engine to its first solution": [
                sys.executable,
                "-c",
                _FIRST_SOLUTION,
                str(bag),
            ],
        }
        for label, command in commands.items():
            child_cpu(command)  # untimed: fills numba's cache on a fresh tree
            times = [child_cpu(command) for _ in range(args.runs)]
            print(
                f"{label}: median CPU {statistics.median(times):.2f} s "
                f"(min {min(times):.2f}, max {max(times):.2f}, {args.runs} runs)"
            )


if __name__ == "__main__":
    main()
