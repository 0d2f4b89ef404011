"""ins_fusion_node at 134 Hz: CPU and IMU-sample-to-Odometry latency. Prints numbers only.

A simulated bag (imu400cc, test pattern, Leica RTK + ADU5) is played in real time with
`gnss_ins play`; the node runs as its own executable with output_rate = 134 Hz (one Odometry
per IMU sample). A subscriber in this process receives both imu/data_raw and ins/odometry;
latency = receive time of the Odometry - receive time of the Imu message with the same stamp
(the node's processing plus one DDS hop). CPU = the node process's user + system time over the
playback, again from the first Odometry on (the steady state: the bag's first seconds are a
standstill that aligns without outputs), and per thread over the playback (/proc/PID/task: the
Python thread that spins the executor, Fast DDS's receive and event threads, ...); the load
average beside it (the machine is shared).

    .venv/bin/python bench/bench_fusion_node.py [--duration 120] [--executor events|single]
        [--profile FILE] [--tree DIR] [--floor]

``--profile FILE`` runs the node under cProfile, timed by the CPU time of its executor thread
(where every callback runs), and writes the pstats to FILE; CPU and latency then include the
profiler's overhead. ``--tree DIR`` runs the node from another source tree (an A/B in one
session: ``git worktree add DIR COMMIT``; its numba cache is compiled before the measurement).
``--floor`` runs, instead of the node, an rclpy node that takes the fusion node's inputs
(serialized, the same QoS, executor and spin loop) and drops them, and publishes its four outputs
(Odometry, NavSatFix, Imu, /tf: serialized templates) at about the output rate: what rclpy and
DDS cost for the node's inputs and outputs before any work (its Odometry is unstamped: no
latency).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from bench_imu_node import print_cpu, process_cpu_s, thread_cpu_s
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

from gnss_ins_common.rates import IMU400CC_RATE_HZ
from gnss_ins_common.ros_node_main import EXECUTOR_ENV
from ins_fusion.bags.topics import GNSS_ATTITUDE, GNSS_FIX, GNSS_VEL, IMU_DATA
from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.simulated_bag import write_bag

# The node's main() under cProfile, timed by the CPU time of the executor's thread (wall time
# would count the waits and, on a loaded machine, the time the thread was not scheduled).
_PROFILED = """
import cProfile, sys, time
from ins_fusion.node import main
profile = cProfile.Profile(time.thread_time)
profile.runcall(main, ["ins_fusion_node", *sys.argv[1:]])
profile.dump_stats({!r})
"""


# A node that takes what ins_fusion_node subscribes to and drops it (serialized, same QoS), and
# publishes what the node publishes (serialized templates, the same topics and QoS: odometry,
# fix, imu, /tf) once every `every` IMU messages.
_FLOOR = """
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, NavSatFix, Temperature
from tf2_msgs.msg import TFMessage
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_node_main import make_executor, spin_guarded
from ins_fusion.ros_tf import transform_template
rclpy.init()
node = rclpy.create_node("ins_fusion_floor")
endpoints = Endpoints(node)
sensor_qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.BEST_EFFORT)
outputs = [
    (endpoints.publisher(Odometry, "ins/odometry", 50), bytes(serialize_message(Odometry()))),
    (endpoints.publisher(NavSatFix, "ins/fix", 50), bytes(serialize_message(NavSatFix()))),
    (endpoints.publisher(Imu, "ins/imu", 50), bytes(serialize_message(Imu()))),
    (node.create_publisher(TFMessage, "/tf", 100), transform_template("map", "base_link")),
]
count = 0
def on_imu(data):
    global count
    count += 1
    if count % {every} == 0:
        for publisher, message in outputs:
            publisher.publish(message)
endpoints.subscription(Imu, "imu/data_raw", on_imu, sensor_qos, raw=True)
endpoints.subscription(NavSatFix, "gnss/fix", lambda data: None, 20, raw=True)
endpoints.subscription(TwistWithCovarianceStamped, "gnss/vel", lambda data: None, 20, raw=True)
endpoints.subscription(Imu, "gnss/attitude", lambda data: None, 20, raw=True)
endpoints.subscription(Temperature, "imu/temperature", lambda data: None, 10, raw=True)
executor = make_executor()
executor.add_node(node)
spin_guarded(executor, node, rclpy.ok)
"""


def _stamp_us(msg) -> int:
    """Stamp in whole µs: the Odometry stamp went through float seconds, the Imu one did not."""
    return round((msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec) / 1000)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=120.0, help="bag length [s]")
    parser.add_argument(
        "--output-rate",
        type=float,
        default=134.0,
        help="node output_rate [Hz]; 134 = one Odometry per IMU sample",
    )
    parser.add_argument(
        "--executor",
        choices=("events", "single"),
        default="events",
        help="the node's executor ($GNSS_INS_EXECUTOR, gnss_ins_common/ros_node_main.py)",
    )
    parser.add_argument("--profile", type=Path, help="write the node's cProfile pstats here")
    parser.add_argument("--tree", type=Path, help="run the node from this source tree")
    parser.add_argument(
        "--floor", action="store_true", help="a node that takes the inputs and drops them"
    )
    args = parser.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(40 + os.getpid() % 50))
    bin_dir = Path(sys.executable).parent

    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "drive"
        write_bag(SimulationConfig(duration_s=args.duration, seed=2), bag)

        imu_rx: dict[int, float] = {}  # stamp [µs] -> receive time
        odom_rx: dict[int, float] = {}
        lock = threading.Lock()
        rclpy.init()
        listener = rclpy.create_node("bench_fusion_listener")
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)

        # The node's CPU [s] and the time at the first Odometry: the steady state after it.
        first_output: dict[str, float] = {}
        node_pid: list[int] = []

        def store(table: dict[int, float]):
            def callback(msg) -> None:
                now = time.perf_counter()
                with lock:
                    table[_stamp_us(msg)] = now

            return callback

        store_odometry = store(odom_rx)

        def on_odometry(msg) -> None:
            store_odometry(msg)
            if not first_output and node_pid:
                first_output["cpu"] = process_cpu_s(node_pid[0])
                first_output["wall"] = time.monotonic()

        listener.create_subscription(Imu, "imu/data_raw", store(imu_rx), qos)
        listener.create_subscription(Odometry, "ins/odometry", on_odometry, qos)
        executor = SingleThreadedExecutor()
        executor.add_node(listener)
        threading.Thread(target=executor.spin, daemon=True).start()

        node_env = {**os.environ, EXECUTOR_ENV: args.executor}
        if args.tree:
            node_env["PYTHONPATH"] = str(args.tree.resolve())
            warm_up = "from ins_fusion.core.engine.warm_up import warm_up; warm_up()"
            subprocess.run([sys.executable, "-c", warm_up], env=node_env, check=True)
        node_args = ["--ros-args", "-p", f"output_rate:={args.output_rate}"]
        command = [bin_dir / "ins_fusion_node", *node_args]
        if args.profile:
            command = [sys.executable, "-c", _PROFILED.format(str(args.profile)), *node_args]
        if args.floor:
            every = max(1, round(IMU400CC_RATE_HZ / args.output_rate))
            command = [sys.executable, "-c", _FLOOR.format(every=every)]
        node = subprocess.Popen(
            command,
            stderr=subprocess.DEVNULL,
            env=node_env,
        )
        time.sleep(3.0)  # discovery
        cpu0, wall0 = process_cpu_s(node.pid), time.monotonic()
        node_pid.append(node.pid)
        threads0 = thread_cpu_s(node.pid)
        subprocess.run(
            [
                bin_dir / "gnss_ins",
                "play",
                str(bag),
                "--wait-for-subscribers",
                "--topics",
                IMU_DATA,
                GNSS_FIX,
                GNSS_VEL,
                GNSS_ATTITUDE,
            ],
            check=True,
            capture_output=True,
        )
        cpu1, wall1 = process_cpu_s(node.pid), time.monotonic()
        threads1 = thread_cpu_s(node.pid)
        load = os.getloadavg()
        time.sleep(0.5)
        node.terminate()
        node.wait(timeout=30)
        executor.shutdown()
        listener.destroy_node()
        rclpy.shutdown()

    with lock:
        common = sorted(set(imu_rx) & set(odom_rx))
        latency_ms = np.array([(odom_rx[s] - imu_rx[s]) * 1e3 for s in common])
    print(
        f"ins_fusion_node, {args.duration:.0f} s bag played in real time, "
        f"output_rate {args.output_rate:g} Hz, {args.executor} executor"
        + (", floor (inputs dropped, outputs from templates)" if args.floor else "")
    )
    print(f"  Imu messages received {len(imu_rx)}, Odometry {len(odom_rx)}, matched {len(common)}")
    if len(odom_rx) > 1:
        stamps = np.array(sorted(odom_rx)) * 1e-6  # header stamps [µs] -> [s]
        spacing_ms = np.diff(stamps) * 1e3
        print(
            f"  Odometry rate by stamp {(len(stamps) - 1) / (stamps[-1] - stamps[0]):.3f} Hz; "
            f"spacing [ms] min {spacing_ms.min():.1f} median {np.median(spacing_ms):.1f} "
            f"max {spacing_ms.max():.1f}"
        )
    if len(latency_ms):
        print(
            "  latency Imu -> Odometry [ms]: "
            f"p50 {np.percentile(latency_ms, 50):.3f}  p99 {np.percentile(latency_ms, 99):.3f}  "
            f"max {latency_ms.max():.3f}"
        )
    print_cpu(cpu1 - cpu0, (threads0, threads1), wall1 - wall0, load, 1)
    if first_output:
        steady = wall1 - first_output["wall"]
        print(
            f"  node CPU from the first Odometry on ({steady:.0f} s): "
            f"{100 * (cpu1 - first_output['cpu']) / steady:.1f} % of one core"
        )


if __name__ == "__main__":
    main()
