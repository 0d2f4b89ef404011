"""`gnss_ins demo`: the whole system on this machine, with a simulated vehicle instead of hardware.

1. ``gnss_ins simulate --live --hold`` drives an emulated IMU400CC, Leica RTK rover and ADU5 on
   pseudo-terminals in real time (the test pattern: a 60 s standstill, then urban driving) and
   writes the truth to a bag;
2. the fusion kernels are loaded (compiled into numba's cache after an install or an update,
   so that the live node does not spend the drive compiling them); the real nodes read the
   devices: imu400cc_node, gnss_node twice (namespaces ``leica`` and ``adu5``) and
   ins_fusion_node (remapped to those namespaces), each in its own process, logging to
   ``logs/``; their warnings are printed with the time left every 10 s;
3. ``gnss_ins record`` records the sensor topics and the fused output; when the drive ends the
   recorder, the nodes and then the emulators are stopped, in that order;
4. the recorded sensor data are replayed offline through the same core (``gnss_ins replay``)
   with 20 s GNSS outages; the live node's and the replay's fused outputs are compared with the
   truth the same way, into one JSON report and one figure.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

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
)
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.replay.recorded import RecordedErrors, recorded_errors, truth_track
from ins_fusion.runtime.processes import ProcessGroup, gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import ADU5, LEICA, VEHICLE, command
from ins_fusion.sim.launch_config import parameter_arguments, simulated_vehicle_parameters

#: The demo's report (live and replay errors, the replay's own report) and figure.
REPORT, FIGURE = "demo_report.json", "demo.png"
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


def _window(text: str) -> str:
    """An ``--outage`` value: START:DURATION in seconds, duration positive."""
    try:
        start, duration = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected START:DURATION in seconds, got {text!r}"
        ) from None
    if not duration > 0.0 or start < 0.0:
        raise argparse.ArgumentTypeError(f"{text!r}: START >= 0 and DURATION > 0 [s]")
    return text


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Demo options."""
    parser.add_argument("--duration", type=float, default=150.0, help="simulated drive [s]")
    parser.add_argument("--seed", type=int, default=1, help="seed of the sensor errors")
    parser.add_argument(
        "--output-dir",
        type=Path,
        default=Path("gnss_ins_demo"),
        help="where the bags, logs, report and figure go; an earlier demo's are replaced, a"
        " directory with other files is refused",
    )
    parser.add_argument(
        "--outage",
        type=_window,
        action="append",
        default=None,
        metavar="START:DURATION",
        help="a GNSS outage for the offline replay, START and DURATION in seconds, START counted "
        "from the first IMU sample (repeatable). Default: two 20 s outages, at "
        f"{STANDSTILL_S + 20:g} s and {STANDSTILL_S + 55:g} s (20 s and 55 s into the drive, "
        f"which starts after a {STANDSTILL_S:g} s standstill); an outage is left out when the "
        "drive ends less than 5 s after it, and a drive too short for either gets one over its "
        "middle third",
    )
    parser.epilog = (
        f"Writes into the output directory: {REPORT} (live and replay errors against the truth,"
        f" and the replay's full report), {FIGURE} (track, horizontal/vertical/yaw errors of"
        " both), drive/ (the recorded bag), truth/, drive_with_truth/, replay_fused/ (the"
        " replay's /ins/* output) and logs/ (one log per process). The live run takes the"
        " --duration in real time; the ROS domain it uses is printed first."
    )


def _default_outages(duration_s: float) -> list[str]:
    """20 s outages 20 s and 55 s into the drive that end at least 5 s before the data do; a
    drive too short for either gets one outage over its middle third (none below 6 s)."""
    starts = (STANDSTILL_S + 20.0, STANDSTILL_S + 55.0)
    fitting = [f"{start:g}:20" for start in starts if start + 25.0 <= duration_s]
    third_s = (duration_s - STANDSTILL_S) / 3.0
    if fitting or third_s < 2.0:
        return fitting
    return [f"{STANDSTILL_S + third_s:.4g}:{third_s:.4g}"]


#: Caps the live drive [s] whatever --duration says (the documentation test runs the pages'
#: demo in less time); the demo prints the shortened duration.
DURATION_LIMIT_ENV = "GNSS_INS_DEMO_DURATION_LIMIT_S"


def _duration_s(requested_s: float) -> float:
    """``--duration``, capped by DURATION_LIMIT_ENV when it is set."""
    limit = os.environ.get(DURATION_LIMIT_ENV)
    return min(requested_s, float(limit)) if limit else requested_s


def _describe_outages(outages: Sequence[str], duration_s: float) -> str:
    """The terminal's line on the replay's outages (or why there is none)."""
    if not outages:
        return (
            f"  offline replay without GNSS outages: a {duration_s:g} s drive leaves less than"
            f" 6 s after the {STANDSTILL_S:g} s standstill"
        )
    windows = [window_s(text) for text in outages]
    listed = ", ".join(f"{w['duration_s']:g} s at {w['start_s']:g} s" for w in windows)
    return f"  offline replay with GNSS outages: {listed}"


class _Lines:
    """Lines of a child's stdout, read on a thread so that a wait never blocks past its time-out."""

    def __init__(self, stream: IO[str]) -> None:
        self._queue: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self._queue.put(line.rstrip("\n"))
        self._queue.put(None)  # end of output: the process ended

    def next(self, timeout_s: float) -> str | None:
        """The next line; None at the end of the output; TimeoutError after ``timeout_s``."""
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            raise TimeoutError from None


def _read_ports(lines: _Lines, timeout_s: float = 30.0) -> dict[str, str]:
    """The ``name: path`` lines the live simulator prints before it starts."""
    ports: dict[str, str] = {}
    deadline = time.monotonic() + timeout_s
    while {"imu", "gnss", "adu5"} - ports.keys():
        try:
            line = lines.next(max(deadline - time.monotonic(), 0.0))
        except TimeoutError:
            break
        if line is None:
            break
        name, _, path = line.partition(": ")
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


#: What a demo writes into its output directory (and may replace on the next run), and the
#: file that marks the directory as a demo's.
_DEMO_ENTRIES = (
    "logs",
    "drive",
    "truth",
    "drive_with_truth",
    "replay_fused",
    REPORT,
    FIGURE,
    "replay_report.json",  # the two files of demos before the combined report
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
    """Run the demo; returns 0 when every stage produced its output, 1 when one failed, 2 for
    an output directory that holds someone else's files."""
    out: Path = args.output_dir
    problem = _prepare_output(out)
    if problem is not None:
        print(f"gnss_ins demo: error: {problem}", file=sys.stderr)
        return 2
    env = dict(os.environ)
    env.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    started = time.monotonic()
    requested_s, args.duration = args.duration, _duration_s(args.duration)
    shortened = f" (shortened by {DURATION_LIMIT_ENV})" if args.duration < requested_s else ""
    print(
        f"gnss_ins demo: {args.duration:.0f} s simulated drive in real time{shortened},"
        f" output in {out}/"
    )
    outages = args.outage or _default_outages(args.duration)
    print(_describe_outages(outages, args.duration))
    print(
        f"  ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} (localhost only): watch with e.g."
        f" ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} .venv/bin/gnss_ins echo /ins/odometry"
        " (or gnss_ins topics)",
        flush=True,
    )
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, _stop_on_signal)
    print("  fusion kernels: loading (compiled once after an install or an update: minutes)")
    print(f"  fusion kernels ready in {warm_up():.0f} s", flush=True)
    failed = _live_run(args, out, env)
    if failed:
        print(f"gnss_ins demo: error: {failed}; logs in {out / 'logs'}", file=sys.stderr)
        return 1
    print(
        f"  live run finished after {time.monotonic() - started:.0f} s; replaying offline ...",
        flush=True,
    )
    _merge([out / "drive", out / "truth"], out / "drive_with_truth")
    replay = _replay(out, outages, env)
    if replay is None:
        return 1
    live = recorded_errors(out / "drive", out / "truth")
    offline = recorded_errors(out / "replay_fused", out / "truth")
    t0_s = _first_imu_stamp(out / "drive")
    report = {
        "duration_s": args.duration,
        "seed": args.seed,
        "ros_domain_id": int(env["ROS_DOMAIN_ID"]),
        "live": live.summary() if live is not None else None,
        "replay": offline.summary() if offline is not None else None,
        "outages": [window_s(text) for text in outages],
        "replay_report": replay,
    }
    (out / REPORT).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    _plot(out, live, offline, t0_s, replay, args)
    _print_summary(report, out, time.monotonic() - started)
    return 0 if live is not None and offline is not None else 1


def window_s(text: str) -> dict[str, float]:
    """``START:DURATION`` as the report's {"start_s", "duration_s"}."""
    start, duration = (float(v) for v in text.split(":"))
    return {"start_s": start, "duration_s": duration}


def _live_run(args: argparse.Namespace, out: Path, env: dict[str, str]) -> str | None:
    """The simulator, the nodes and the recorder, until the drive ends; then stopped in reverse
    start order (recorder, nodes, emulators last, so no node sees its port vanish). Returns what
    failed, or None."""
    processes = ProcessGroup(out / "logs", env)
    try:
        simulator = processes.start(
            "simulate",
            gnss_ins_command(
                "simulate",
                "--live",
                "--hold",
                "--scenario",
                "test_pattern",
                "--imu",
                "imu400cc",
                "--duration",
                str(args.duration),
                "--seed",
                str(args.seed),
                "--truth-output",
                str(out / "truth"),
            ),
            stdout=subprocess.PIPE,
        )
        assert simulator.stdout is not None
        lines = _Lines(simulator.stdout)
        ports = _read_ports(lines)
        print(f"  emulated devices: {', '.join(f'{k} {v}' for k, v in ports.items())}")
        port_of = {"imu": ports["imu"], "leica": ports["gnss"], "adu5": ports["adu5"]}
        # The simulated car's lever arms and the emulated receivers' output latency, which
        # gnss_node takes off the stamps, as on a real vehicle.
        extras = {
            spec: parameter_arguments(values)
            for spec, values in simulated_vehicle_parameters().items()
        }
        for spec in VEHICLE:
            port = port_of[spec.port_role] if spec.port_role else None
            processes.start(spec.name, command(spec, None, port, extras.get(spec, ())))
        processes.start("record", gnss_ins_command("record", "-o", str(out / "drive"), *RECORDED))
        print("  nodes running: imu400cc_node, leica/gnss_node, adu5/gnss_node, ins_fusion_node")
        ended = _wait_recording(lines, processes, args.duration)
        if ended is not None:
            return ended
        time.sleep(1.0)  # the last messages reach the recorder
    finally:
        failed = processes.stop_all()
    for line in processes.problems():
        print(f"  {line}")
    return f"{', '.join(failed)} stopped during the run" if failed else None


def _wait_recording(lines: _Lines, processes: ProcessGroup, duration_s: float) -> str | None:
    """Wait for the simulator's ``drive ended``, printing the time left and the children's
    warnings every 10 s; returns what ended the run early, or None."""
    start = time.monotonic()
    report_at = start
    while True:
        left = duration_s - (time.monotonic() - start)
        if time.monotonic() >= report_at:
            print(f"  recording: {max(left, 0.0):.0f} s of {duration_s:.0f} s left", flush=True)
            for problem in processes.problems():
                print(f"  {problem}", flush=True)
            report_at += 10.0
        if stopped := [name for name in processes.exited() if name != "simulate"]:
            return f"{', '.join(stopped)} stopped during the run"
        try:
            line = lines.next(max(report_at - time.monotonic(), 0.1))
        except TimeoutError:
            if left < -60.0:
                return "the simulator did not end the drive"
            continue
        if line is None:
            return "the simulator stopped during the run"
        if line == "drive ended":
            return None


def _replay(out: Path, outages: list[str], env: dict[str, str]) -> dict[str, Any] | None:
    """``gnss_ins replay`` of the recorded sensor data with the outages: its report (the fused
    output in ``replay_fused``), or None after printing why it failed."""
    with tempfile.TemporaryDirectory() as scratch:
        report_path = Path(scratch) / "replay.json"
        replay = subprocess.run(
            gnss_ins_command(
                "replay",
                str(out / "drive_with_truth"),
                "--params",
                str(config_file("ins_fusion.yaml")),
                "--topics",
                REPLAY_TOPICS,
                *[f"--outage={window}" for window in outages],
                "--report",
                str(report_path),
                "--output",
                str(out / "replay_fused"),
            ),
            env=env,
            capture_output=True,
            text=True,
        )
        (out / "logs" / "replay.log").write_text(replay.stdout + replay.stderr)
        if replay.returncode != 0:
            print(replay.stdout + replay.stderr)
            print(f"gnss_ins demo: error: the replay failed; logs in {out / 'logs'}")
            return None
        result: dict[str, Any] = json.loads(report_path.read_text(encoding="utf-8"))
        return result


def _first_imu_stamp(bag: Path) -> float:
    """Stamp of the bag's first IMU message [s]: time 0 of the replay's outage windows."""
    with BagReader(bag) as reader:
        first = next(reader.messages([IMU_DATA], deserialize=True))
        return stamp_s(first.message)


def _plot(
    out: Path,
    live: RecordedErrors | None,
    offline: RecordedErrors | None,
    t0_s: float,
    replay: dict[str, Any],
    args: argparse.Namespace,
) -> None:
    from ins_fusion.replay.plot_demo import plot_demo

    datum = (
        next(run.datum for run in (live, offline) if run is not None) if live or offline else None
    )
    if datum is None:
        return
    windows = [(o["start_s"], o["start_s"] + o["duration_s"]) for o in replay.get("outages", [])]
    plot_demo(
        out / FIGURE,
        (live, offline),
        truth_track(out / "truth", datum),
        t0_s,
        windows,
        f"gnss_ins demo: {args.duration:g} s test pattern, seed {args.seed}",
    )


def _row(name: str, errors: dict[str, float] | None) -> str:
    if errors is None:
        return f"{name:<31}no fused output recorded (see logs/)"
    return (
        f"{name:<31}{errors['horizontal_rms']:6.3f}  {errors['horizontal_p95']:6.3f}  "
        f"{errors['horizontal_max']:6.3f}      {errors['vertical_rms']:6.3f}    "
        f"{errors['yaw_rms']:6.3f}"
    )


def _print_summary(report: dict[str, Any], out: Path, total_s: float) -> None:
    replay = report["replay_report"]
    print()
    print("                                 horizontal [m]              vertical  yaw")
    print("                                 rms     p95     max         rms [m]   rms [deg]")
    print(_row("live ins_fusion_node", report["live"]))
    replay_row = "offline replay with outages" if report["outages"] else "offline replay"
    print(_row(replay_row, report["replay"]))
    for outage in replay.get("outages", []):
        what = f"  {outage['duration_s']:.0f} s GNSS outage at {outage['start_s']:.0f} s: "
        end, peak = outage.get("horizontal_error_end_m"), outage.get("horizontal_error_max_m")
        if end is None or peak is None:
            print(what + "not evaluated (no aligned solution inside it)")
        else:
            print(what + f"horizontal error at its end {end:.2f} m, max {peak:.2f} m")
    nees = replay.get("nees") or {}
    if nees.get("position_mean") is not None:
        print(
            f"  replay position NEES mean {nees['position_mean']:.2f} (3 dof), inside 3 sigma "
            f"{100 * nees['position_within_3sigma_fraction']:.1f} %"
        )
    print(
        f"  replay at {replay['realtime_factor']:.0f}x real time; report {out / REPORT},"
        f" plot {out / FIGURE}; total {total_s:.0f} s"
    )
