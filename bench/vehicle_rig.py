"""The operator's set-up without hardware, for the daemon's benchmarks (bench_soak.py,
bench_record_kill.py): the three devices emulated (``gnss_ins emulate-imu``, ``emulate-gnss``
for the Leica and the ADU5) and ``gnss_ins launch`` on them, in a domain of its own; and the
launch's processes found by their command lines in /proc."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from ins_fusion.runtime.processes import gnss_ins_command

#: The launch's processes: name -> an argument of its command line that names it.
PROCESSES = {
    "imu400cc_node": "__node:=imu400cc_node",
    "leica_gnss": "__node:=leica_gnss",
    "adu5_gnss": "__node:=adu5_gnss",
    "ins_fusion_node": "__node:=ins_fusion_node",
    "recorder": "--resume",
    "status_server": "--serve",
}


@contextmanager
def emulated_vehicle(
    work: Path,
    *launch_options: str,
    velocity: tuple[str, str, str] = ("0", "0", "0"),
    output: IO[str] | None = None,
) -> Iterator[subprocess.Popen[bytes]]:
    """The emulators (the receivers moving at ``velocity`` ENU m/s, the IMU at rest) and
    ``gnss_ins launch --log-dir WORK/logs LAUNCH_OPTIONS`` on them (its console to ``output``,
    else nowhere); stopped at the end, launch first (SIGINT, which it handles itself)."""
    # A domain of its own: nothing of a system running beside it reaches the bench's nodes.
    os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
    ports = {name: str(work / name) for name in ("imu", "leica", "adu5")}
    moving = ["--velocity", *velocity]
    emulators = [
        subprocess.Popen(gnss_ins_command("emulate-imu", "--link", ports["imu"])),
        subprocess.Popen(
            gnss_ins_command(
                "emulate-gnss", "--receiver", "leica", "--link", ports["leica"], *moving
            )
        ),
        subprocess.Popen(
            gnss_ins_command(
                "emulate-gnss", "--receiver", "adu5", "--link", ports["adu5"], *moving, "--att"
            )
        ),
    ]
    try:
        while not all(Path(p).exists() for p in ports.values()):
            time.sleep(0.1)
        launcher = subprocess.Popen(
            gnss_ins_command(
                "launch",
                *[f"--{role}-port={port}" for role, port in ports.items()],
                f"--log-dir={work / 'logs'}",
                *launch_options,
            ),
            stdout=output if output is not None else subprocess.DEVNULL,
            stderr=subprocess.STDOUT,
        )
        try:
            yield launcher
        finally:
            launcher.send_signal(signal.SIGINT)
            launcher.wait(timeout=120)
    finally:
        for emulator in emulators:  # SIGTERM: a shell's background job ignores SIGINT
            emulator.terminate()
            emulator.wait(timeout=30)


def children(parent: int, markers: Mapping[str, str] = PROCESSES) -> dict[str, int]:
    """PID of each process of ``markers`` (name -> argument) that ``parent`` started."""
    found: dict[str, int] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            args = (entry / "cmdline").read_bytes().decode(errors="replace").split("\0")
        except OSError:
            continue
        if ppid == parent:
            found.update({n: int(entry.name) for n, mark in markers.items() if mark in args})
    return found
