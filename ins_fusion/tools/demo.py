"""`gnss_ins demo`: the whole system on this machine, with a simulated vehicle instead of hardware.

1. ``gnss_ins simulate --live`` drives an emulated IMU400CC, Leica RTK rover and ADU5 on
   pseudo-terminals in real time (seed test pattern: standstill, then urban driving) and writes the
   truth to a bag;
2. the real nodes read them: imu400cc_node, gnss_node twice (namespaces ``leica`` and ``adu5``)
   and ins_fusion_node (remapped to those namespaces), each in its own process;
3. ``gnss_ins record`` records the sensor topics and the fused output;
4. afterwards the live fused output is compared with the truth, and the recorded sensor data are
   replayed offline through the same core (``gnss_ins replay``) with 20 s GNSS outages, giving a
   JSON report and a plot.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gnss_driver.profiles import Receiver
from gnss_ins_common.paths import config_file
from ins_fusion.adapters.messages_in import stamp_s
from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.bags.topics import (
    GNSS_ATTITUDE,
    GNSS_FIX,
    GNSS_TIME,
    GNSS_VEL,
    IMU_DATA,
    IMU_TEMPERATURE,
    INS_FIX,
    INS_ODOMETRY,
    TRUTH_FIX,
)
from ins_fusion.runtime.processes import ProcessGroup, gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import ADU5, FUSION, LEICA, VEHICLE, command
from ins_fusion.sim.receivers import emulator_config
from ins_fusion.sim.scenarios import SURVEY_CAR

#: Sensor and output topics recorded during the live run.
RECORDED = (
    IMU_DATA,
    IMU_TEMPERATURE,
    f"/{LEICA.namespace}{GNSS_FIX}",
    f"/{LEICA.namespace}{GNSS_VEL}",
    f"/{LEICA.namespace}{GNSS_TIME}",
    f"/{ADU5.namespace}{GNSS_ATTITUDE}",
    INS_ODOMETRY,
    INS_FIX,
    "/diagnostics",
)
#: Roles of the replay inputs in the recorded bag.
REPLAY_TOPICS = f"imu={IMU_DATA},fix={RECORDED[2]},vel={RECORDED[3]},attitude={RECORDED[5]}"


#: The test pattern's standstill before the drive [s] (ins_fusion.sim.scenarios).
STANDSTILL_S = 60.0


def _stop_on_signal(signum: int, _frame: object) -> None:
    """SIGTERM/SIGHUP end the demo as Ctrl-C does: the children are stopped in ``finally``."""
    raise KeyboardInterrupt(signal.Signals(signum).name)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Demo options."""
    parser.add_argument("--duration", type=float, default=150.0, help="simulated drive [s]")
    parser.add_argument("--seed", type=int, default=1, help="seed of the sensor errors")
    parser.add_argument(
        "--output-dir", type=Path, default=Path("gnss_ins_demo"), help="bags, logs, report, plot"
    )
    parser.add_argument(
        "--outage",
        action="append",
        default=None,
        metavar="START:DURATION",
        help="GNSS outage injected in the offline replay [s after the first IMU sample] "
        f"(default: 20 s outages at {STANDSTILL_S + 20:g} s and {STANDSTILL_S + 55:g} s, i.e."
        f" 20 s and 55 s after the {STANDSTILL_S:g} s standstill, where the drive is long"
        " enough)",
    )


def _default_outages(duration_s: float) -> list[str]:
    """20 s outages 20 s and 55 s into the drive that end at least 5 s before the data do."""
    starts = (STANDSTILL_S + 20.0, STANDSTILL_S + 55.0)
    return [f"{start:g}:20" for start in starts if start + 25.0 <= duration_s]


def _read_ports(process: subprocess.Popen[str], timeout_s: float = 30.0) -> dict[str, str]:
    """The ``name: path`` lines the live simulator prints before it starts."""
    assert process.stdout is not None
    ports: dict[str, str] = {}
    deadline = time.monotonic() + timeout_s
    while {"imu", "gnss", "adu5"} - ports.keys() and time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        name, _, path = line.strip().partition(": ")
        if path.startswith("/"):
            ports[name] = path
    missing = {"imu", "gnss", "adu5"} - ports.keys()
    if missing:
        raise RuntimeError(f"the live simulator did not report the ports {sorted(missing)}")
    return ports


def _merge(inputs: Sequence[Path], output: Path) -> None:
    """One bag with every topic of ``inputs`` (raw messages, original log times)."""
    with BagWriter(output) as writer:
        for path in inputs:
            with BagReader(path) as reader:
                for name, topic in reader.topics.items():
                    writer.add_topic(name, topic.msgtype, topic.qos)
                for message in reader.messages():
                    writer.write(message.topic, message.log_time_ns, message.message)


def _live_errors(bag: Path, truth: Path) -> dict[str, float]:
    """Horizontal error of the live /ins/fix against /ground_truth/fix at its stamps [m]."""
    import pymap3d

    def fixes(path: Path, topic: str) -> np.ndarray:
        with BagReader(path) as reader:
            if topic not in reader.topics:
                return np.zeros((0, 4))
            rows = [
                (
                    stamp_s(m.message),
                    m.message.latitude,
                    m.message.longitude,
                    m.message.status.status,
                )
                for m in reader.messages([topic], deserialize=True)
            ]
        return np.array(rows) if rows else np.zeros((0, 4))

    fused, reference = fixes(bag, INS_FIX), fixes(truth, TRUTH_FIX)
    fused = fused[fused[:, 3] >= 0] if len(fused) else fused
    if len(fused) == 0 or len(reference) == 0:
        return {}
    inside = (fused[:, 0] >= reference[0, 0]) & (fused[:, 0] <= reference[-1, 0])
    fused = fused[inside]
    lat = np.interp(fused[:, 0], reference[:, 0], reference[:, 1])
    lon = np.interp(fused[:, 0], reference[:, 0], reference[:, 2])
    east, north, _ = pymap3d.geodetic2enu(fused[:, 1], fused[:, 2], 0.0, lat, lon, 0.0)
    error = np.hypot(east, north)
    return {
        "samples": float(len(error)),
        "horizontal_rms": float(np.sqrt(np.mean(error**2))),
        "horizontal_p95": float(np.percentile(error, 95)),
        "horizontal_max": float(error.max()),
    }


#: What a demo writes into its output directory (and may replace on the next run), and the
#: file that marks the directory as a demo's.
_DEMO_ENTRIES = (
    "logs",
    "drive",
    "truth",
    "drive_with_truth",
    "replay_report.json",
    "replay.png",
)
_MARKER = ".gnss_ins_demo"


def _prepare_output(out: Path) -> str | None:
    """Make ``out`` ready for a run: create it, or clear what an earlier demo wrote there.
    Anything else in it is the user's: refuse (the reason), never delete it."""
    if out.exists() and not out.is_dir():
        return f"{out} exists and is not a directory"
    if out.exists() and any(out.iterdir()):
        foreign = sorted(p.name for p in out.iterdir() if p.name not in {*_DEMO_ENTRIES, _MARKER})
        if not (out / _MARKER).exists() or foreign:
            shown = ", ".join(foreign[:5]) or "no demo marker"
            return (
                f"{out} is not empty and not (only) an earlier demo's output ({shown}); "
                "choose another --output-dir, nothing was deleted"
            )
        for name in _DEMO_ENTRIES:
            path = out / name
            if path.is_dir():
                shutil.rmtree(path)
            elif path.exists():
                path.unlink()
    (out / "logs").mkdir(parents=True)
    (out / _MARKER).write_text("written by gnss_ins demo; its entries are replaced on a rerun\n")
    return None


def run(args: argparse.Namespace) -> int:
    """Run the demo; returns 0 when every stage produced its output, 2 for an output
    directory that holds someone else's files."""
    out: Path = args.output_dir
    problem = _prepare_output(out)
    if problem is not None:
        print(f"gnss_ins demo: error: {problem}", file=sys.stderr)
        return 2
    env = dict(os.environ)
    env.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    processes = ProcessGroup(out / "logs", env)
    drive, truth, merged = out / "drive", out / "truth", out / "drive_with_truth"
    started = time.monotonic()
    print(f"gnss_ins demo: {args.duration:.0f} s simulated drive in real time, output in {out}/")
    print(
        f"  ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} (localhost only): watch with e.g."
        f" ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} ros2 topic echo /ins/odometry"
    )
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, _stop_on_signal)
    try:
        simulator = processes.start(
            "simulate",
            gnss_ins_command(
                "simulate",
                "--live",
                "--scenario",
                "test_pattern",
                "--imu",
                "imu400cc",
                "--duration",
                str(args.duration),
                "--seed",
                str(args.seed),
                "--truth-output",
                str(truth),
            ),
            stdout=subprocess.PIPE,
        )
        ports = _read_ports(simulator)
        print(f"  emulated devices: {', '.join(f'{k} {v}' for k, v in ports.items())}")
        car = SURVEY_CAR
        lever_arms = (
            "-p",
            f"imu_lever_arm:={list(car.imu.lever_arm_flu_m)}",
            "-p",
            f"gnss_lever_arm:={list(car.gnss_antenna_flu_m)}",
        )
        port_of = {"imu": ports["imu"], "leica": ports["gnss"], "adu5": ports["adu5"]}
        # The emulated receivers send each epoch output_latency_s after its UTC time; as on a
        # real vehicle, gnss_node is told that latency so it stamps the epoch time itself.
        extras = {
            FUSION: lever_arms,
            LEICA: ("-p", f"latency:={emulator_config(Receiver.LEICA).output_latency_s}"),
            ADU5: ("-p", f"latency:={emulator_config(Receiver.ADU5).output_latency_s}"),
        }
        for spec in VEHICLE:
            port = port_of[spec.port_role] if spec.port_role else None
            processes.start(spec.name, command(spec, None, port, extras.get(spec, ())))
        processes.start("record", gnss_ins_command("record", "-o", str(drive), *RECORDED))
        print("  nodes running: imu400cc_node, leica/gnss_node, adu5/gnss_node, ins_fusion_node")
        _wait_recording(simulator, args.duration)
        time.sleep(1.0)  # the last messages reach the recorder
    finally:
        failed = processes.stop_all()
    if failed:
        print(f"error: {', '.join(failed)} stopped during the run; logs in {out / 'logs'}")
        return 1
    live_s = time.monotonic() - started
    print(f"  live run finished after {live_s:.0f} s; replaying offline ...", flush=True)

    _merge([drive, truth], merged)
    live = _live_errors(drive, truth)
    outages = args.outage or _default_outages(args.duration)
    report_path, plot_path = out / "replay_report.json", out / "replay.png"
    replay = subprocess.run(
        gnss_ins_command(
            "replay",
            str(merged),
            "--params",
            str(config_file("ins_fusion.yaml")),
            "--topics",
            REPLAY_TOPICS,
            *[f"--outage={window}" for window in outages],
            "--report",
            str(report_path),
            "--plot",
            str(plot_path),
        ),
        env=env,
        capture_output=True,
        text=True,
    )
    (out / "logs" / "replay.log").write_text(replay.stdout + replay.stderr)
    if replay.returncode != 0:
        print(replay.stdout + replay.stderr)
        print("replay failed; logs in", out / "logs")
        return 1
    report = json.loads(report_path.read_text())
    _print_summary(live, report, out, time.monotonic() - started)
    return 0 if live else 1


def _wait_recording(simulator: subprocess.Popen[str], duration_s: float) -> None:
    """Wait for the simulated drive to end, printing the time left every 10 s."""
    start = time.monotonic()
    while True:
        left = duration_s - (time.monotonic() - start)
        print(f"  recording: {max(left, 0.0):.0f} s of {duration_s:.0f} s left", flush=True)
        try:
            simulator.wait(timeout=10.0 if left > -60.0 else None)
            return
        except subprocess.TimeoutExpired:
            continue


def _print_summary(
    live: dict[str, float], report: dict[str, Any], out: Path, total_s: float
) -> None:
    position = report["position_error_m"]
    attitude = report["attitude_error_deg"]
    print()
    print("                                 horizontal [m]              vertical  yaw")
    print("                                 rms     p95     max         rms [m]   rms [deg]")
    if live:
        print(
            f"live ins_fusion_node           {live['horizontal_rms']:6.3f}  "
            f"{live['horizontal_p95']:6.3f}  {live['horizontal_max']:6.3f}"
        )
    else:
        print("live ins_fusion_node           no fused output recorded (see logs/)")
    print(
        f"offline replay with outages    {position['horizontal_rms']:6.3f}  "
        f"{position['horizontal_p95']:6.3f}  {position['horizontal_max']:6.3f}      "
        f"{position['vertical_rms']:6.3f}    {attitude['yaw_rms']:6.3f}"
    )
    for outage in report.get("outages", []):
        print(
            f"  {outage['duration_s']:.0f} s GNSS outage at {outage['start_s']:.0f} s: "
            f"horizontal error at its end {outage['horizontal_error_end_m']:.2f} m, "
            f"max {outage['horizontal_error_max_m']:.2f} m"
        )
    nees = report.get("nees", {})
    if nees:
        print(
            f"  position NEES mean {nees['position_mean']:.2f} (3 dof), inside 3 sigma "
            f"{100 * nees['position_within_3sigma_fraction']:.1f} %"
        )
    print(
        f"  replay at {report['realtime_factor']:.0f}x real time; "
        f"report {out / 'replay_report.json'}, plot {out / 'replay.png'}; total {total_s:.0f} s"
    )
