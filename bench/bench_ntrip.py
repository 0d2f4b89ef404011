"""CPU of the NTRIP client at a given correction rate, and the corrections' way to the rover.

The test caster (ntrip_client.caster_emulator) serves the real RTCM 3 capture of
test/fixtures/rtcm/ at ``--rate`` bytes/s (default 1000) on 127.0.0.1, with a password. Two
processes as on the vehicle: ``ntrip_node`` (the client, connected to the caster) and
``gnss_node`` for the Leica on an emulated rover (``--rtk-from-corrections``), which writes every
frame the client publishes to the rover's pseudo-terminal. After a warm-up, CPU time of each
process is read from /proc/<pid>/stat over ``--seconds``; at the end the bytes the rover received
are compared with the caster's frames from the first one the rover got (the client connects
before gnss_node's subscription is matched): exact, in order, none lost. Prints numbers, asserts
nothing.

    .venv/bin/python bench/bench_ntrip.py [--seconds 60] [--rate 1000]
"""

from __future__ import annotations

import argparse
import os
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CAPTURE = REPO / "test" / "fixtures" / "rtcm" / "pygpsdata-NTRIP-USCL00CHL0.log"
TICKS_PER_S = os.sysconf("SC_CLK_TCK")
WARM_UP_S = 8.0
PASSWORD = "bench-password"


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS_PER_S


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="measured span [s]")
    parser.add_argument("--rate", type=float, default=1000.0, help="corrections [bytes/s]")
    args = parser.parse_args()

    from gnss_driver.emulator import EmulatorConfig, GnssEmulator
    from ntrip_client.caster_emulator import CasterEmulator

    os.environ.setdefault("ROS_DOMAIN_ID", str(101 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    bin_dir = Path(sys.executable).parent
    with tempfile.TemporaryDirectory() as work:
        password_file = Path(work) / "password"
        password_file.write_text(PASSWORD + "\n")
        password_file.chmod(stat.S_IRUSR | stat.S_IWUSR)
        with (
            CasterEmulator(
                CAPTURE.read_bytes(),
                {"AAU00DNK": (57.01, 9.99)},
                ("rover", PASSWORD),
                rate_bytes_s=args.rate,
            ) as caster,
            GnssEmulator(config=EmulatorConfig(rtk_from_corrections=True)) as rover,
        ):
            config = REPO / "config"
            common = ["-r", "__ns:=/leica"]
            processes = {
                "ntrip_node": subprocess.Popen(
                    [
                        str(bin_dir / "ntrip_node"),
                        "--ros-args",
                        "--params-file",
                        str(config / "ntrip.yaml"),
                        *common,
                        "-p",
                        f"url:=http://rover@127.0.0.1:{caster.port}/AAU00DNK",
                        "-p",
                        f"password_file:={password_file}",
                    ]
                ),
                "gnss_node": subprocess.Popen(
                    [
                        str(bin_dir / "gnss_node"),
                        "--ros-args",
                        "--params-file",
                        str(config / "gnss_leica.yaml"),
                        *common,
                        "-p",
                        f"port:={rover.path}",
                    ]
                ),
            }
            try:
                time.sleep(WARM_UP_S)
                start = {name: cpu_seconds(p.pid) for name, p in processes.items()}
                frames_before = len(caster.sent_frames)
                t0 = time.monotonic()
                time.sleep(args.seconds)
                span = time.monotonic() - t0
                used = {name: cpu_seconds(p.pid) - start[name] for name, p in processes.items()}
                frames = len(caster.sent_frames) - frames_before
                sent_bytes = sum(len(f) for f in caster.sent_frames[frames_before:])
                caster.stop()
                time.sleep(2.0)  # the last frames on their way to the rover
            finally:
                for process in processes.values():
                    process.send_signal(2)
                for process in processes.values():
                    process.wait(timeout=30)
            received = rover.rtcm_received
            sent_frames = list(caster.sent_frames)

    print(
        f"corrections: {sent_bytes / span:.0f} bytes/s, {frames / span:.1f} frames/s "
        f"over {span:.0f} s"
    )
    for name, seconds in used.items():
        print(f"{name:10s} CPU {100.0 * seconds / span:5.2f} % of a core")
    # The frames published before gnss_node's subscription was matched are not the rover's.
    first = next((i for i, f in enumerate(sent_frames) if received.startswith(f)), None)
    expected = b"".join(sent_frames[first:]) if first is not None else b""
    print(
        f"rover received {len(received)} bytes of frames from the caster's frame {first} on, "
        f"of {len(sent_frames)}; identical to the caster's from there: {received == expected}"
    )


if __name__ == "__main__":
    main()
