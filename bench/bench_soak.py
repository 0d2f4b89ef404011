"""Soak of the vehicle daemon: ``gnss_ins launch --record`` on the three emulated devices for an
hour (``--duration``), as the README's "Every tool without hardware" runs them: the IMU at rest,
both receivers moving at 5 m/s (inconsistent inputs, as a faulty installation gives them).

Every ``--sample`` seconds the resident memory (RSS) and CPU time of each process of the launch
(the four nodes, the recorder, the status server and launch itself, by /proc) are read. At the
end launch is stopped with Ctrl-C and the recording is read: the last /diagnostics status of each
node gives the IMU packets the driver lost (``dropped_packets``), the fusion's solutions that
were not published (``outputs_invalid``; its log says why) and its resets; launch's console gives
the restarts. Printed per process: RSS at the start of the steady state (after ``--settle`` s)
and at the end, the growth per hour (least squares over the steady-state samples) and the mean
CPU (% of one core), and the sum of all. Plain script, no asserts.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from vehicle_rig import PROCESSES, children, emulated_vehicle

from ins_fusion.bags.bag_io import BagReader


def rss_and_cpu(pid: int) -> tuple[float, float] | None:
    """RSS [MB] and CPU time [s] of a process (None once it has ended)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    ticks = os.sysconf("SC_CLK_TCK")
    return int(fields[21]) * os.sysconf("SC_PAGE_SIZE") / 1e6, (
        int(fields[11]) + int(fields[12])
    ) / ticks


def last_statuses(bag: Path) -> dict[str, dict[str, str]]:
    """The last /diagnostics values of each status name in the recording."""
    last: dict[str, dict[str, str]] = {}
    with BagReader(bag) as reader:
        for msg in reader.messages(["/diagnostics"], deserialize=True):
            for status in msg.message.status:
                last[status.name] = {kv.key: kv.value for kv in status.values}
    return last


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=3600.0, help="seconds of running")
    parser.add_argument("--sample", type=float, default=30.0, help="seconds between readings")
    parser.add_argument("--settle", type=float, default=300.0, help="start of the steady state")
    parser.add_argument(
        "--keep",
        type=Path,
        metavar="DIR",
        help="new directory that keeps the nodes' logs, launch's console and the recording",
    )
    args = parser.parse_args()
    if args.keep is not None:
        args.keep.mkdir(parents=True)  # refuses an existing directory: nothing overwritten
    with tempfile.TemporaryDirectory(prefix="bench_soak.") as scratch:
        work = Path(scratch) if args.keep is None else args.keep
        launch_log = work / "launch.out"
        with (
            launch_log.open("w") as out,
            emulated_vehicle(
                work, "--record", str(work / "bags"), velocity=("3", "4", "0"), output=out
            ) as launcher,
        ):
            readings: dict[str, list[tuple[float, float, float]]] = {
                n: [] for n in [*PROCESSES, "launch"]
            }
            start = time.monotonic()
            while (elapsed := time.monotonic() - start) < args.duration:
                for name, pid in {**children(launcher.pid), "launch": launcher.pid}.items():
                    if (reading := rss_and_cpu(pid)) is not None:
                        readings[name].append((elapsed, *reading))
                time.sleep(min(args.sample, max(0.0, args.duration - elapsed)))
        console = launch_log.read_text()
        (bag,) = (work / "bags").iterdir()
        statuses = last_statuses(bag)
    print(
        f"soak: {args.duration:g} s, readings every {args.sample:g} s,"
        f" steady from {args.settle:g} s"
    )
    print(f"  {'process':<16} {'RSS start MB':>12} {'RSS end MB':>10} {'MB/h':>8} {'CPU %':>6}")
    total_cpu = 0.0
    for name, rows in readings.items():
        steady = np.array([r for r in rows if r[0] >= args.settle] or rows)
        if len(steady) < 2:
            print(f"  {name:<16} (no readings)")
            continue
        slope = np.polyfit(steady[:, 0], steady[:, 1], 1)[0] * 3600.0
        cpu = (steady[-1, 2] - steady[0, 2]) / (steady[-1, 0] - steady[0, 0]) * 100.0
        total_cpu += cpu
        print(
            f"  {name:<16} {steady[0, 1]:>12.1f} {steady[-1, 1]:>10.1f} {slope:>8.2f} {cpu:>6.1f}"
        )
    print(f"  {'all of them':<16} {'':>12} {'':>10} {'':>8} {total_cpu:>6.1f}")
    imu = statuses.get("imu400cc_node: IMU400CC", {})
    fusion = statuses.get("ins_fusion_node: INS", {})
    print(f"  IMU packets {imu.get('packets')}, dropped {imu.get('dropped_packets')}")
    print(f"  fusion: state {fusion.get('state')}, published {fusion.get('outputs_published')},")
    print(f"    not published {fusion.get('outputs_invalid')}, resets {fusion.get('resets')}")
    if args.keep is not None:
        print(f"  logs, console and recording kept in {args.keep}")
    print(f"  restarts by launch: {console.count(' restarted (pid ')}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
