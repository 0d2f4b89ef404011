"""`gnss_ins launch` is closed to the network by default: two network namespaces of this machine
joined by a veth pair (a vehicle's network in miniature), the launcher in one, a publisher of a
GNSS fix in the other with the same ROS_DOMAIN_ID. Closed (the default), the publisher finds no
subscriber while a probe beside the nodes finds the fusion node's; with ``--discovery subnet``
it finds it. Needs root and iproute2 (skipped elsewhere)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import uuid

import pytest

from ins_fusion.runtime.processes import gnss_ins_command

pytestmark = pytest.mark.ros

#: Prints the number of subscriptions matched by a NavSatFix publisher on /leica/gnss/fix,
#: as soon as there is one or after argv[1] seconds.
PROBE = """
import sys, time
import rclpy
from sensor_msgs.msg import NavSatFix
rclpy.init()
node = rclpy.create_node("network_probe")
pub = node.create_publisher(NavSatFix, "/leica/gnss/fix", 10)
deadline = time.monotonic() + float(sys.argv[1])
while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
    time.sleep(0.1)
print(pub.get_subscription_count(), flush=True)
"""
DOMAIN = "77"


def ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True)


@pytest.fixture
def two_hosts():
    """Network namespaces A (10.231.7.1) and B (10.231.7.2) on one veth link; their names."""
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("needs root and iproute2 for network namespaces")
    tag = uuid.uuid4().hex[:6]
    hosts = (f"gi_a_{tag}", f"gi_b_{tag}")
    try:
        for host in hosts:
            ip("netns", "add", host)
        ip("link", "add", f"va{tag}", "type", "veth", "peer", "name", f"vb{tag}")
        for host, link, address in zip(
            hosts, (f"va{tag}", f"vb{tag}"), ("10.231.7.1/24", "10.231.7.2/24"), strict=True
        ):
            ip("link", "set", link, "netns", host)
            ip("-n", host, "addr", "add", address, "dev", link)
            ip("-n", host, "link", "set", link, "up", "multicast", "on")
            ip("-n", host, "link", "set", "lo", "up")
            ip("-n", host, "route", "add", "224.0.0.0/4", "dev", link)
    except subprocess.CalledProcessError as exc:
        for host in hosts:
            subprocess.run(["ip", "netns", "del", host], check=False)
        pytest.skip(f"network namespaces unavailable: {exc.stderr!r}")
    try:
        yield hosts
    finally:
        for host in hosts:
            subprocess.run(["ip", "netns", "del", host], check=False)


def probe(host: str, seconds: float, discovery: str) -> int:
    env = {**os.environ, "ROS_DOMAIN_ID": DOMAIN, "ROS_AUTOMATIC_DISCOVERY_RANGE": discovery}
    result = subprocess.run(
        ["ip", "netns", "exec", host, sys.executable, "-c", PROBE, str(seconds)],
        env=env,
        capture_output=True,
        text=True,
        timeout=seconds + 60,
    )
    assert result.returncode == 0, result.stderr
    return int(result.stdout.split()[-1])


@pytest.mark.parametrize("opened", [False, True], ids=["default", "discovery-subnet"])
def test_a_publisher_on_another_host_reaches_the_nodes_only_when_opened(
    two_hosts, tmp_path, opened
):
    vehicle, other = two_hosts
    options = ["--discovery", "subnet"] if opened else []
    launcher = subprocess.Popen(
        [
            "ip",
            "netns",
            "exec",
            vehicle,
            *gnss_ins_command("launch", "--log-dir", str(tmp_path), "--no-adu5", *options),
        ],
        env={**os.environ, "ROS_DOMAIN_ID": DOMAIN},
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        # The fusion node (it subscribes to /leica/gnss/fix) is up and found from its own host.
        assert probe(vehicle, 60.0, "LOCALHOST") > 0
        found = probe(other, 15.0, "SUBNET")
    finally:
        launcher.send_signal(signal.SIGINT)
        output = launcher.communicate(timeout=60)[0]
    assert ("ROS discovery: SUBNET" if opened else "ROS discovery: LOCALHOST") in output
    assert (found > 0) is opened, found
