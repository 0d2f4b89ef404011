"""Benchmark of a recording on the vehicle that is killed at random moments.

The operator's set-up without hardware: the three devices emulated (``gnss_ins emulate-imu``,
``emulate-gnss`` for the Leica and the ADU5), ``gnss_ins launch --record`` running the four nodes
and the supervised recorder. The recorder is SIGKILLed ``--kills`` times, each at a random moment
20–60 s (``--min-s``/``--max-s``) after it started recording; the launcher restarts it into the
same bag. At the end launch is stopped with Ctrl-C (SIGINT) and the one bag is read.

Printed per kill, from /imu/data_raw (134 Hz): the data before the kill that did not reach the
bag (kill time − last IMU message before it) and the gap in the recording (last message before
the kill → first after the restart); then the bag's summary. Plain script, no asserts.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import sys
import tempfile
import time
from pathlib import Path

from vehicle_rig import children, emulated_vehicle

from ins_fusion.bags.bag_io import BagReader

IMU_TOPIC = "/imu/data_raw"


def wait_for_text(path: Path, text: str, timeout_s: float, after: int = 0) -> int:
    """Wait until ``text`` appears in ``path`` past byte ``after``; returns the file's size."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        data = path.read_bytes() if path.exists() else b""
        if text.encode() in data[after:]:
            return len(data)
        time.sleep(0.1)
    sys.exit(f"{text!r} did not appear in {path} within {timeout_s:g} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kills", type=int, default=3, help="recorder kills")
    parser.add_argument("--min-s", type=float, default=20.0, help="earliest kill after start")
    parser.add_argument("--max-s", type=float, default=60.0, help="latest kill after start")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory(prefix="bench_record_kill.") as scratch:
        work = Path(scratch)
        bags, recorder_log = work / "bags", work / "logs" / "recorder.log"
        options = ("--record", str(bags), "--record-storage", args.storage)
        kills: list[float] = []
        with emulated_vehicle(work, *options) as launcher:
            seen = wait_for_text(recorder_log, f"recording {IMU_TOPIC}", 60.0)
            for k in range(args.kills):
                time.sleep(rng.uniform(args.min_s, args.max_s))
                pid = children(launcher.pid).get("recorder")
                if pid is None:
                    sys.exit("no recorder running")
                os.kill(pid, signal.SIGKILL)
                kills.append(time.time())
                print(f"kill {k + 1}: recorder {pid} killed", flush=True)
                seen = wait_for_text(recorder_log, f"recording {IMU_TOPIC}", 60.0, after=seen)
            time.sleep(5.0)
        (bag,) = bags.iterdir()
        with BagReader(bag) as reader:
            times = [m.log_time_ns / 1e9 for m in reader.messages([IMU_TOPIC])]
            summary = reader.summary()
        print(f"bag recording killed {len(kills)} times ({args.storage}, seed {args.seed}):")
        print("  kill  lost before the kill s  gap in the recording s")
        for k, killed in enumerate(kills, start=1):
            before = max(t for t in times if t <= killed)
            after = min(t for t in times if t > killed)
            print(f"  {k:>4}  {killed - before:>22.3f}  {after - before:>22.3f}")
        print(summary.format(f"bag {bag.name}"))


if __name__ == "__main__":
    main()
