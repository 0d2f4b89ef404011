"""Instructions of one warm fusion of a bag, counted by callgrind; prints numbers only.

CPU seconds on a shared machine spread by ±20 % between runs of the same work, more than most
single changes save; the number of instructions a run executes does not. This bench runs
``run_fusion`` (the replay's fusion: the engine, the history, the track rows) in a worker under
``valgrind --tool=callgrind --instr-atstart=no``: start-up, kernel load, reading the bag and one
untimed fusion run uninstrumented, then ``callgrind_control -i on`` around one more fusion, so
the count holds that fusion only. Prints the instructions and the instructions per IMU sample.
``--tree DIR`` counts another checkout (an A/B: ``git worktree add DIR COMMIT``); several trees
run one after the other. Instructions are not time (the interpreter's and the kernels'
instructions per cycle differ), but a change that removes work removes instructions.

    .venv/bin/python bench/bench_fusion_instructions.py [--bag BAG] [--tree DIR ...]

Needs valgrind (``apt install valgrind``; not a Python package); without it, prints how and
skips. Under callgrind the fusion of the 437 s bench bag takes ~5 min, the uninstrumented part
another ~3–10 min (numba's kernel load is slow under valgrind).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from speed_bag import simulated_bag

#: The worker: everything but the counted fusion before "ready"; one fusion per line on stdin.
_WORKER = """
import os, sys
from gnss_ins_common.params import validate_all
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap
warm_up()
inputs = load_bag(sys.argv[1], TopicMap())
params = validate_all(PARAMETERS, {})
run_fusion(inputs, params)
print("ready", os.getpid(), len(inputs.imu), flush=True)
sys.stdin.readline()
run_fusion(inputs, params)
print("done", flush=True)
sys.stdin.readline()
"""


def count(tree: Path, bag: Path, workdir: Path) -> tuple[int, int]:
    """(instructions of one warm fusion of ``bag`` by the checkout ``tree``, IMU samples)."""
    out = workdir / f"callgrind.{tree.name}"
    out.mkdir(parents=True, exist_ok=True)
    command = [
        "valgrind",
        "--tool=callgrind",
        "--instr-atstart=no",
        "--trace-children=yes",
        f"--callgrind-out-file={out}/cg.%p",
        f"--log-file={out}/valgrind.%p.log",
        sys.executable,
        "-c",
        _WORKER,
        str(bag),
    ]
    # Run in the tree: ``python -c`` puts the working directory before PYTHONPATH.
    env = {**os.environ, "PYTHONPATH": str(tree)}
    worker = subprocess.Popen(
        command, cwd=tree, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert worker.stdin is not None and worker.stdout is not None
    ready = worker.stdout.readline().split()
    if not ready or ready[0] != "ready":
        raise SystemExit(f"{tree}: the worker did not start (exit {worker.wait()})")
    pid, samples = ready[1], int(ready[2])
    subprocess.run(["callgrind_control", "-i", "on", pid], check=True, capture_output=True)
    worker.stdin.write("go\n")
    worker.stdin.flush()
    worker.stdout.readline()
    subprocess.run(["callgrind_control", "-i", "off", pid], check=True, capture_output=True)
    worker.stdin.write("exit\n")
    worker.stdin.close()
    worker.wait()
    log = (out / f"valgrind.{pid}.log").read_text(errors="replace")
    counted = re.search(r"I\s+refs:\s+([\d,]+)", log)  # what was collected while on
    if counted is None:
        raise SystemExit(f"{tree}: no instruction count in {out}/valgrind.{pid}.log")
    return int(counted.group(1).replace(",", "")), samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bag", type=Path, help="bag to fuse (default: bench/speed_bag.py)")
    parser.add_argument(
        "--tree",
        type=Path,
        action="append",
        help="checkout to count (repeatable; default: this one)",
    )
    parser.add_argument("--workdir", type=Path, help="keep the bag and callgrind's files here")
    args = parser.parse_args()
    if shutil.which("valgrind") is None or shutil.which("callgrind_control") is None:
        print("skipped: valgrind not found (apt install valgrind)")
        return
    trees = [tree.resolve() for tree in args.tree or [Path(__file__).resolve().parents[1]]]
    with tempfile.TemporaryDirectory(prefix="instructions_") as temporary:
        workdir = (args.workdir or Path(temporary)).resolve()
        bag = (args.bag or simulated_bag(workdir)).resolve()
        for tree in trees:
            instructions, samples = count(tree, bag, workdir)
            print(
                f"{tree}: {instructions / 1e9:.3f} G instructions in one warm fusion of {bag.name}"
                f" = {instructions / samples:,.0f} per IMU sample ({samples} samples)"
            )


if __name__ == "__main__":
    main()
