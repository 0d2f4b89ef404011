"""Latency and gaps of the live system: IMU packet at the port → /ins/odometry at a subscriber.

``gnss_ins launch`` runs on the README's emulated devices (bench/vehicle_rig.py
``emulated_vehicle``: its own ROS domain, the IMU at rest), recording the default topics unless
``--no-record``. The IMU is this bench's own ``gnss_ins emulate-imu --send-log``, given to launch
with ``--imu-port`` (the rig's own IMU emulator is then left idle, silent in polled mode): for
every packet the emulator logs the sample's true time and the host wall-clock time at which the
packet was written to the pseudo-terminal, i.e. when it arrived at the port.

A subscriber in this process (a SingleThreadedExecutor, raw messages: only the header stamp is
read) takes /imu/data_raw and /ins/odometry with the middleware's message info: the arrival
time is its ``received_timestamp`` (Fast DDS's reception, host wall clock, so not delayed by this
process's executor), the publication time its ``source_timestamp``. This process uses the
daemon's transport settings (``discovery_environment("LOCALHOST")``: UDP only), as a consumer on
the vehicle would; the processes that join with ``--disturb`` use the plain environment (Fast
DDS's shared memory on, as an operator's shell gives it).

Matching, checked and counted (printed under "matching"):

- an odometry message → its IMU sample: the fusion stamps each output with the stamp of the
  IMU sample it is computed at (ins_fusion/node.py publishes from that sample's callback,
  ``OutputClock`` picks the sample; ``OutputWriter`` writes ``stamp_ns(row[T])`` with
  ``row[T]`` = the sample's stamp - ``imu_time_offset``, 0 in config/ins_fusion.yaml). Equal
  stamps within 1 µs (float seconds carry ~0.24 µs) count as the same sample; an odometry
  stamp with no received IMU stamp is counted.
- a stamp → its packet: the driver's stamp is the packet's sample time mapped onto the host
  clock (lower envelope of arrival - transmission time, docs/timing.md), so it lies a fraction
  of a millisecond after the emulator's true sample time, which is logged. Each stamp takes
  the packet whose sample time is nearest after removing the median offset; a residual beyond
  a quarter of the IMU period (1.9 ms; packets are 7.46 ms apart) is counted as a mismatch,
  and consecutive IMU messages must take consecutive packets (skips counted: packets the
  driver dropped or messages this subscriber missed).

Latency of an odometry message = its arrival time - the write time of its sample's packet,
split into: packet → IMU message published (imu400cc_node: serial read, decode, publish),
IMU published → odometry published (DDS to the fusion node, its callback and solution), and
odometry published → arrived here. Gaps: the largest interval between consecutive arrivals of
/ins/odometry (50 Hz: outputs 14.9 or 22.4 ms apart by the output clock) and of /imu/data_raw
(134 Hz, 7.5 ms) over the measured span.

``--disturb``: every 10 s a ``gnss_ins status --once`` (a new ROS process that joins the
domain, listens 2 s and leaves); every 120 s the Leica GNSS node is killed with SIGKILL and
launch starts it again after 0.5 s (its new process joins the domain too). The fusion then
misses one or two GNSS fixes and keeps publishing from the IMU: odometry does not stop. The
largest gaps within 5 s after each kind of event are printed.

CPU: user + system time of each process of the launch (vehicle_rig.PROCESSES and launch
itself, from /proc every 2 s; a restarted node's processes added up, its new process counted
from its start) over the measured span, in % of one core; and this bench's own process.

    .venv/bin/python bench/bench_latency.py [--duration 600] [--disturb] [--no-record]

Plain script: prints a table of numbers, asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import resource
import signal
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from vehicle_rig import PROCESSES, children, emulated_vehicle

from gnss_ins_common.rates import IMU400CC_RATE_HZ
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import discovery_environment
from ins_fusion.tools.emulate_imu import read_send_log

STATUS_EVERY_S = 10.0
RESTART_EVERY_S = 120.0
RESTARTED = "leica_gnss"
CPU_EVERY_S = 2.0
#: Seconds after an event in which a gap counts as the event's.
AFTER_EVENT_S = 5.0
PERIOD_NS = round(1e9 / IMU400CC_RATE_HZ)
#: A stamp this close to its packet's sample time (after the median offset) is a match [ns].
MATCH_NS = PERIOD_NS // 4
#: Gaps longer than this are listed [ms] (the acceptance bound).
LONG_GAP_MS = 40.0
#: Most long gaps listed per topic.
LISTED = 20
#: Odometry and IMU stamps this close are the same sample [ns].
SAME_STAMP_NS = 1_000
_STAMP = {0: struct.Struct(">iI"), 1: struct.Struct("<iI")}


def stamp_ns(data: bytes) -> int:
    """header.stamp [ns] of a serialized (XCDR1) message: right after the encapsulation."""
    sec, nanosec = _STAMP[data[1] & 1].unpack_from(data, 4)
    return int(sec) * 1_000_000_000 + int(nanosec)


@dataclass
class Arrivals:
    """One topic at the subscriber, one row per message: stamp, publication (source) time,
    reception time and this process's callback time [ns, host wall clock]."""

    rows: list[tuple[int, int, int, int]] = field(default_factory=list)

    def __call__(self, data: bytes, info: Any) -> None:
        now = time.time_ns()
        self.rows.append(
            (stamp_ns(data), info["source_timestamp"], info["received_timestamp"], now)
        )

    def columns(self, since_ns: int, until_ns: int) -> np.ndarray:
        """The rows received in [since_ns, until_ns], as an int64 array (n, 4)."""
        rows = np.array(self.rows, dtype=np.int64).reshape(-1, 4)
        return rows[(rows[:, 2] >= since_ns) & (rows[:, 2] <= until_ns)]


def listen(node: Any) -> tuple[Arrivals, Arrivals]:
    """Raw subscriptions of /imu/data_raw and /ins/odometry (reliable, as published; no QoS
    event handlers, which cost the executor a wait-set entry each)."""
    from nav_msgs.msg import Odometry
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    imu, odometry = Arrivals(), Arrivals()
    for msg_type, topic, store in (
        (Imu, "/imu/data_raw", imu),
        (Odometry, "/ins/odometry", odometry),
    ):
        node.create_subscription(
            msg_type,
            topic,
            store,
            qos,
            raw=True,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
        )
    return imu, odometry


def match_packets(stamps: np.ndarray, sample_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each stamp [ns], the index of the packet of nearest sample time once the median
    offset is removed, and the residual [ns] (module docstring)."""

    def nearest(t: np.ndarray) -> np.ndarray:
        right = np.clip(np.searchsorted(sample_ns, t), 1, len(sample_ns) - 1)
        left = right - 1
        return np.where(t - sample_ns[left] <= sample_ns[right] - t, left, right)

    offset = int(np.median(stamps - sample_ns[nearest(stamps)]))
    index = nearest(stamps - offset)
    return index, stamps - offset - sample_ns[index]


def gaps(arrivals_ns: np.ndarray) -> np.ndarray:
    """Intervals between consecutive arrivals [ms], in arrival order."""
    return np.diff(np.sort(arrivals_ns)) / 1e6


def largest_gap_after(arrivals_ns: np.ndarray, events_ns: list[int]) -> float:
    """The largest interval between consecutive arrivals that ends within AFTER_EVENT_S after
    one of the events [ms] (0 without events)."""
    t = np.sort(arrivals_ns)
    worst = 0.0
    for event in events_ns:
        ends = (t[1:] > event) & (t[1:] <= event + AFTER_EVENT_S * 1e9)
        if ends.any():
            worst = max(worst, float(np.max(np.diff(t)[ends])) / 1e6)
    return worst


def describe_gap(
    arrived_ns: np.ndarray, index: int, start_ns: int, events: list[tuple[int, str]]
) -> str:
    """'LENGTH ms at T s' of the gap ending at ``arrived_ns[index + 1]`` (T from the start),
    with the time since the last event before it, if any."""
    end = int(arrived_ns[index + 1])
    text = f"{(end - arrived_ns[index]) / 1e6:.1f} ms at {(end - start_ns) / 1e9:.1f} s"
    before = [(t, kind) for t, kind in events if t <= end]
    if before:
        t, kind = before[-1]
        text += f" ({(end - t) / 1e9:.1f} s after a {kind})"
    return text


def cpu_s(pid: int) -> float | None:
    """User + system CPU time of a process [s] (None once it has ended)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class CpuBooks:
    """CPU seconds of each named process over the measured span, restarts added up."""

    def __init__(self) -> None:
        self._first: dict[tuple[str, int], float] = {}
        self._last: dict[tuple[str, int], float] = {}

    def read(self, pids: dict[str, int], at_start: bool) -> None:
        """A reading; a process first seen after the start counts from its own start (0 s)."""
        for name, pid in pids.items():
            if (seconds := cpu_s(pid)) is None:
                continue
            self._first.setdefault((name, pid), seconds if at_start else 0.0)
            self._last[(name, pid)] = seconds

    def seen(self, name: str) -> bool:
        """Whether a process of ``name`` was read."""
        return any(key[0] == name for key in self._last)

    def seconds(self, name: str) -> float:
        """CPU seconds of ``name``'s processes."""
        return sum(v - self._first[k] for k, v in self._last.items() if k[0] == name)


def row(name: str, values_ms: np.ndarray) -> str:
    """A table line: count, p50, p99 and max [ms]."""
    if values_ms.size == 0:
        return f"  {name:<38} {'(none)':>8}"
    p50, p99 = np.percentile(values_ms, [50, 99])
    return f"  {name:<34} {values_ms.size:>8} {p50:>8.2f} {p99:>8.2f} {values_ms.max():>8.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=600.0, help="measured seconds")
    parser.add_argument(
        "--settle", type=float, default=10.0, help="seconds from the first odometry to the start"
    )
    parser.add_argument(
        "--disturb",
        action="store_true",
        help=f"gnss_ins status every {STATUS_EVERY_S:g} s, {RESTARTED} killed every "
        f"{RESTART_EVERY_S:g} s",
    )
    parser.add_argument("--no-record", action="store_true", help="launch without --record")
    args = parser.parse_args()

    # The rig's domain (emulated_vehicle sets the same default); the joiners' plain environment.
    os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    plain_env = dict(os.environ)
    os.environ.update(discovery_environment("LOCALHOST"))  # this process: the daemon's settings
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    events: dict[str, list[int]] = {"status": [], "restart": []}
    status_runs: list[subprocess.Popen[bytes]] = []
    restarts_seen = 0
    books = CpuBooks()
    with tempfile.TemporaryDirectory(prefix="bench_latency.") as scratch:
        work = Path(scratch)
        send_log, port = work / "sent.bin", work / "imu_timed"
        imu = subprocess.Popen(
            gnss_ins_command("emulate-imu", "--link", str(port), "--send-log", str(send_log)),
            stdout=subprocess.DEVNULL,
        )
        try:
            while not port.exists():
                time.sleep(0.1)
            rclpy.init()
            node = rclpy.create_node("bench_latency")
            imu_rx, odometry_rx = listen(node)
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            record = () if args.no_record else ("--record", str(work / "bags"))
            launch_log = work / "launch.out"
            with (
                launch_log.open("w") as out,
                emulated_vehicle(work, f"--imu-port={port}", *record, output=out) as launcher,
            ):
                deadline = time.monotonic() + 180.0
                while not odometry_rx.rows and time.monotonic() < deadline:
                    executor.spin_once(timeout_sec=0.1)
                if not odometry_rx.rows:
                    sys.exit("no /ins/odometry within 180 s")
                settle_end = time.monotonic() + args.settle
                while time.monotonic() < settle_end:
                    executor.spin_once(timeout_sec=0.1)

                start_ns, start = time.time_ns(), time.monotonic()
                load_start = os.getloadavg()
                own_start = resource.getrusage(resource.RUSAGE_SELF)
                books.read({**children(launcher.pid), "launch": launcher.pid}, at_start=True)
                next_cpu, next_status, next_restart = CPU_EVERY_S, STATUS_EVERY_S, RESTART_EVERY_S
                while (elapsed := time.monotonic() - start) < args.duration:
                    executor.spin_once(timeout_sec=0.05)
                    if elapsed >= next_cpu:
                        next_cpu += CPU_EVERY_S
                        books.read({**children(launcher.pid), "launch": launcher.pid}, False)
                    if args.disturb and elapsed >= next_status:
                        next_status += STATUS_EVERY_S
                        events["status"].append(time.time_ns())
                        status_runs.append(
                            subprocess.Popen(
                                gnss_ins_command(
                                    "status",
                                    "--once",
                                    "--wait",
                                    "2",
                                    "--log-dir",
                                    str(work / "logs"),
                                ),
                                stdout=subprocess.DEVNULL,
                                env=plain_env,
                            )
                        )
                    if args.disturb and elapsed >= next_restart:
                        next_restart += RESTART_EVERY_S
                        pids = children(launcher.pid)
                        books.read({**pids, "launch": launcher.pid}, False)
                        if RESTARTED in pids:
                            events["restart"].append(time.time_ns())
                            os.kill(pids[RESTARTED], signal.SIGKILL)
                end_ns = time.time_ns()
                books.read({**children(launcher.pid), "launch": launcher.pid}, False)
                own_end = resource.getrusage(resource.RUSAGE_SELF)
                load_end = os.getloadavg()
                for run in status_runs:
                    run.wait(timeout=60)
                # The messages on their way at the end.
                flush_end = time.monotonic() + 1.0
                while time.monotonic() < flush_end:
                    executor.spin_once(timeout_sec=0.05)
            console = launch_log.read_text()
            restarts_seen = console.count(" restarted (pid ")
            node.destroy_node()
            rclpy.shutdown()
        finally:
            imu.terminate()  # SIGTERM: the emulator stops and closes its send log
            imu.wait(timeout=30)
        packets = read_send_log(send_log)

    span_s = (end_ns - start_ns) / 1e9
    imu_rows = imu_rx.columns(start_ns, end_ns)
    odo_rows = odometry_rx.columns(start_ns, end_ns)
    # IMU and odometry stamps -> packets (module docstring).
    sample_ns, written_ns = packets["sample_ns"], packets["written_ns"]
    imu_packet, imu_residual = match_packets(imu_rows[:, 0], sample_ns)
    odo_packet, odo_residual = match_packets(odo_rows[:, 0], sample_ns)
    steps = np.diff(imu_packet[np.argsort(imu_rows[:, 0])])
    # Each odometry message's IMU message, among all received (the measured span's first
    # output may be at a sample that arrived just before it).
    imu_all = imu_rx.columns(0, np.iinfo(np.int64).max)
    order = np.argsort(imu_all[:, 0])
    imu_stamps = imu_all[order, 0]
    at = np.clip(np.searchsorted(imu_stamps, odo_rows[:, 0]), 1, len(imu_stamps) - 1)
    at = np.where(
        np.abs(imu_stamps[at - 1] - odo_rows[:, 0]) < np.abs(imu_stamps[at] - odo_rows[:, 0]),
        at - 1,
        at,
    )
    same = np.abs(imu_stamps[at] - odo_rows[:, 0]) <= SAME_STAMP_NS
    imu_of_odo = order[at]
    odo_packet_via_imu = match_packets(imu_all[imu_of_odo, 0], sample_ns)[0]

    latency = (odo_rows[:, 2] - written_ns[odo_packet]) / 1e6
    to_imu_pub = (imu_all[imu_of_odo, 1] - written_ns[odo_packet])[same] / 1e6
    imu_to_odo_pub = (odo_rows[:, 1] - imu_all[imu_of_odo, 1])[same] / 1e6
    delivery = (odo_rows[:, 2] - odo_rows[:, 1]) / 1e6
    imu_latency = (imu_rows[:, 2] - written_ns[imu_packet]) / 1e6
    callback_delay = (
        np.concatenate([odo_rows[:, 3] - odo_rows[:, 2], imu_rows[:, 3] - imu_rows[:, 2]]) / 1e6
    )
    odo_gaps, imu_gaps = gaps(odo_rows[:, 2]), gaps(imu_rows[:, 2])
    own_cpu = (
        own_end.ru_utime + own_end.ru_stime - own_start.ru_utime - own_start.ru_stime
    ) / span_s

    mode = "with disturbances" if args.disturb else "undisturbed"
    recording = "no recording" if args.no_record else "recording (launch --record)"
    print(f"latency: {span_s:.0f} s measured, {mode}, {recording}")
    loads = " / ".join(" ".join(f"{v:.2f}" for v in load) for load in (load_start, load_end))
    print(f"  load average (1, 5, 15 min) at the start / end: {loads} ({os.cpu_count()} cores)")
    print(f"  {'[ms]':<38} {'count':>8} {'p50':>8} {'p99':>8} {'max':>8}")
    print(row("packet -> odometry arrived", latency))
    print(row("  packet -> IMU published", to_imu_pub))
    print(row("  IMU published -> odometry published", imu_to_odo_pub))
    print(row("  odometry published -> arrived", delivery))
    print(row("packet -> IMU arrived", imu_latency))
    print(row("odometry gap", odo_gaps))
    print(row("IMU gap", imu_gaps))
    print(row("arrival -> this bench's callback", callback_delay))
    print(
        f"  odometry later than 10 ms: {int((latency > 10).sum())}, than 30 ms:"
        f" {int((latency > 30).sum())}"
    )
    every_event = sorted((t, kind) for kind, times in events.items() for t in times)
    for topic, rows in (("odometry", odo_rows), ("IMU", imu_rows)):
        arrived = np.sort(rows[:, 2])
        interval = np.diff(arrived) / 1e6
        long = np.flatnonzero(interval > LONG_GAP_MS)
        print(
            f"  {topic} gaps > {LONG_GAP_MS:g} ms: {long.size},"
            f" > 100 ms: {int((interval > 100).sum())}; rate {interval.size / span_s:.2f} Hz"
        )
        if long.size:  # the first LISTED of them
            listed = [describe_gap(arrived, i, start_ns, every_event) for i in long[:LISTED]]
            print(f"    {'; '.join(listed)}")
    if args.disturb:
        finished = sum(run.returncode in (0, 1, 2) for run in status_runs)
        print(
            f"  status runs {len(events['status'])} ({finished} ended with a health code),"
            f" {RESTARTED} killed {len(events['restart'])}, restarts by launch {restarts_seen}"
        )
        for kind, times in events.items():
            print(
                f"  largest gap within {AFTER_EVENT_S:g} s after a {kind}: odometry"
                f" {largest_gap_after(odo_rows[:, 2], times):.1f} ms,"
                f" IMU {largest_gap_after(imu_rows[:, 2], times):.1f} ms"
            )
    else:
        print(f"  restarts by launch: {restarts_seen}")
    print(
        "  matching: IMU stamps -> packets: "
        f"{int((np.abs(imu_residual) > MATCH_NS).sum())} of {len(imu_residual)} beyond"
        f" {MATCH_NS / 1e6:.2f} ms (largest residual {np.abs(imu_residual).max() / 1e3:.0f} µs),"
        f" {int((steps != 1).sum())} skips in the packet order;"
    )
    print(
        f"    odometry stamps: {int((~same).sum())} of {len(same)} without an IMU stamp"
        f" within {SAME_STAMP_NS / 1e3:g} µs,"
        f" {int((odo_packet_via_imu != odo_packet)[same].sum())} matched to another packet"
        f" than their IMU message's, {int((np.abs(odo_residual) > MATCH_NS).sum())} beyond"
        f" {MATCH_NS / 1e6:.2f} ms; packets logged {len(packets)}"
    )
    print(f"  {'CPU % of one core':<20} {'':>6}")
    total = 0.0
    for name in [*PROCESSES, "launch"]:
        if not books.seen(name):
            print(f"  {name:<20} {'-':>6}")
            continue
        share = books.seconds(name) / span_s * 100.0
        total += share
        print(f"  {name:<20} {share:>6.2f}")
    print(f"  {'all of them':<20} {total:>6.2f}")
    print(f"  {'this bench':<20} {own_cpu * 100.0:>6.2f}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
