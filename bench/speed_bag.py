"""The bag of the speed benchmarks (issue 18): `gnss_ins simulate` of the 437 s test pattern with
the imu400cc at 200 Hz, the position receiver (fix + velocity) at 5 Hz, no ADU5, truth at 50 Hz,
seed 1. Shared by bench_vs_kfgins.py and bench_replay_profile.py."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SIMULATE_ARGS = (
    "--duration=437",
    "--imu-rate=200",
    "--gnss-rate=5",
    "--no-adu5",
    "--seed=1",
)


def gnss_ins_command() -> list[str]:
    """The `gnss_ins` console script next to this Python, else the module."""
    script = Path(sys.executable).with_name("gnss_ins")
    return [str(script)] if script.exists() else [sys.executable, "-m", "ins_fusion.tools.cli"]


def simulated_bag(directory: Path, duration_s: int = 437) -> Path:
    """The benchmark bag in ``directory`` (simulated on first use, ~15 s); another
    ``duration_s`` gives the same drive, shorter or longer."""
    path = directory / f"speed{duration_s}"
    if not path.exists():
        arguments = (f"--duration={duration_s}", *SIMULATE_ARGS[1:])
        command = [*gnss_ins_command(), "simulate", *arguments, f"--output={path}"]
        print("simulating:", " ".join(["gnss_ins", *command[-len(arguments) - 2 :]]))
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return path
