"""`gnss_ins launch` on the emulated devices with a collector of its topics, and the PIDs of the
nodes it started."""

from __future__ import annotations

import signal
import subprocess
from contextlib import contextmanager
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Imu, NavSatFix

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.profiles import Receiver
from imu400cc_driver.emulator import Imu400ccEmulator
from ins_fusion.runtime.processes import gnss_ins_command
from support.ros_harness import Collector, spinning

NODE_NAMES = {"imu400cc_node", "leica_gnss", "adu5_gnss", "ins_fusion_node"}


TOPICS = {
    "imu/data_raw": Imu,
    "leica/gnss/fix": NavSatFix,
    "adu5/gnss/attitude": Imu,
    "/diagnostics": DiagnosticArray,
    "/gnss_ins/status": DiagnosticArray,
}


@contextmanager
def launched(log_dir: Path, *options: str):
    """`gnss_ins launch` on the three emulated devices, with a Collector of TOPICS spinning;
    stopped with SIGINT at the end. Yields (launcher, collector, output: filled at the end, the
    emulated IMU)."""
    leica = GnssEmulator(
        constant_velocity((3.0, 4.0, 0.0)), EmulatorConfig(receiver=Receiver.LEICA)
    )
    adu5 = GnssEmulator(constant_velocity((3.0, 4.0, 0.0)), EmulatorConfig(receiver=Receiver.ADU5))
    with Imu400ccEmulator() as imu, leica, adu5:
        collector = Collector(TOPICS)
        ports = ("--imu-port", imu.path, "--leica-port", leica.path, "--adu5-port", adu5.path)
        launcher = subprocess.Popen(
            gnss_ins_command("launch", *ports, "--log-dir", str(log_dir), *options),
            stdout=subprocess.PIPE,
            text=True,
        )
        output: list[str] = []
        try:
            with spinning(collector.node):
                yield launcher, collector, output, imu
        finally:
            launcher.send_signal(signal.SIGINT)
            output.append(launcher.communicate(timeout=60)[0])
            collector.node.destroy_node()


def node_pids(parent: int, markers: dict[str, str] | None = None) -> dict[str, int]:
    """PID of each running node process started by ``parent``, by node name (psutil when
    installed, else /proc); a killed node not yet reaped (a zombie) has no command line.
    ``markers``: name -> an argument that identifies the process (default: the node names)."""
    markers = markers or {name: f"__node:={name}" for name in NODE_NAMES}
    children: list[tuple[int, list[str]]] = []
    try:
        import psutil
    except ImportError:
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                stat = (entry / "stat").read_text()
                cmdline = (entry / "cmdline").read_bytes().decode(errors="replace")
            except OSError:  # ended meanwhile
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == parent:  # the field after comm: ppid
                children.append((int(entry.name), cmdline.split("\0")))
    else:
        for child in psutil.Process(parent).children():
            try:
                children.append((child.pid, child.cmdline()))
            except psutil.Error:
                continue
    return {name: pid for pid, args in children for name, mark in markers.items() if mark in args}
