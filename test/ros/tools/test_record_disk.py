"""``gnss_ins record`` on a file system that fills: a real 4 MiB tmpfs (mounted where the test runs
as root; elsewhere skipped: test_recording_writer.py covers the guard with a fake statvfs), a
publisher of 10 kB messages at 50 Hz, the real recorder process."""

from __future__ import annotations

import os
import signal
import subprocess
import threading
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from support.pacing import pause
from support.ros_harness import Collector, spinning, wait_for

from ins_fusion.bags.bag_io import BagReader
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.tools.cli import main

pytestmark = pytest.mark.ros
TOPIC = "/test/bulk"


@pytest.fixture
def small_disk(tmp_path: Path):
    mount = tmp_path / "disk"
    mount.mkdir()
    if (
        os.geteuid() != 0
        or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(mount)], capture_output=True
        ).returncode
    ):
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


@pytest.fixture
def publisher():
    """10 kB strings at 50 Hz (500 kB/s) on TOPIC until the test ends; yields the sent count."""
    rclpy.init()
    node = rclpy.create_node("bulk_publisher")
    pub = node.create_publisher(
        String, TOPIC, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    )
    done = threading.Event()
    sent = [0]

    def run() -> None:
        while not done.is_set():
            pub.publish(String(data=f"{sent[0]:08d}" + "x" * 10_000))
            sent[0] += 1
            pause(0.02)  # 50 messages/s

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield pub
    finally:
        done.set()
        thread.join()
        node.destroy_node()
        rclpy.shutdown()


def record(bag: Path, *options: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        gnss_ins_command("record", "-o", str(bag), *options, TOPIC),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def numbers(bag: Path) -> list[int]:
    with BagReader(bag) as reader:
        return [int(m.message.data[:8]) for m in reader.messages(deserialize=True)]


def recorder_errors(collector: Collector) -> list[str]:
    """The messages of the recorder's ERROR statuses on /diagnostics."""
    return [
        status.message
        for array in collector.get("/diagnostics")
        for status in array.status
        if status.name.startswith("gnss_ins_record") and status.level == DiagnosticStatus.ERROR
    ]


def record_until_it_stops(bag: Path, *options: str) -> tuple[int, str, str]:
    """A recorder that stops on its own: its exit code, its stderr and the last ERROR status it
    sent on /diagnostics (waited for: it must come before the exit)."""
    collector = Collector({"/diagnostics": DiagnosticArray})
    try:
        with spinning(collector.node):
            recorder = record(bag, *options)
            _out, err = recorder.communicate(timeout=60)
            assert wait_for(lambda: recorder_errors(collector), 5.0)
    finally:
        collector.node.destroy_node()
    return recorder.returncode, err, recorder_errors(collector)[-1]


def test_guard_stops_before_the_disk_is_full_with_a_complete_bag(small_disk, publisher):
    """... and says why on /diagnostics before it exits."""
    returncode, err, error = record_until_it_stops(small_disk / "bag", "--min-free", "1M")
    assert returncode == 3, err
    assert "disk space low" in err and "recording stopped" in err
    assert error.startswith("free disk space") and "recording stopped" in error
    got = numbers(small_disk / "bag")  # metadata.yaml written: no recover needed
    assert len(got) > 100 and got == list(range(got[0], got[0] + len(got)))


def test_rotation_keeps_recording_and_deletes_the_oldest_files(small_disk, publisher):
    recorder = record(
        small_disk / "bag",
        "--min-free",
        "1M",
        "--on-disk-full",
        "rotate",
        "--max-bag-duration",
        "1",
    )
    # Until the disk guard has deleted the first file and the recording went on into a third.
    files = lambda: {p.name for p in (small_disk / "bag").glob("*.mcap")}  # noqa: E731
    assert wait_for(lambda: "bag_0.mcap" not in files() and bool(files() - {"bag_1.mcap"}), 60.0)
    assert recorder.poll() is None
    recorder.send_signal(signal.SIGINT)
    out, err = recorder.communicate(timeout=60)
    assert recorder.returncode == 0, err
    assert "deleted the oldest file bag_0.mcap" in err
    assert "deleted by the disk guard: bag_0.mcap" in out
    got = numbers(small_disk / "bag")
    assert got == list(range(got[0], got[0] + len(got)))  # the newest files, contiguous
    assert got[0] > 0


def test_without_the_guard_a_full_disk_leaves_a_bag_that_recover_restores(
    small_disk, publisher, tmp_path
):
    returncode, err, error = record_until_it_stops(small_disk / "bag", "--min-free", "0")
    assert returncode == 1, err
    assert "No space left on device" in err and "gnss_ins recover" in err
    assert error.startswith("writing failed") and "No space left on device" in error
    assert not (small_disk / "bag" / "metadata.yaml").exists()
    assert main(["recover", str(small_disk / "bag"), "-o", str(tmp_path / "recovered")]) == 0
    got = numbers(tmp_path / "recovered")
    assert got == list(range(got[0], got[0] + len(got)))
    # Lost at most the last chunk: the recording filled ~4 MiB with 10 kB messages.
    assert len(got) * 10_000 > 3.0 * 2**20
