"""gnss_ins echo and gnss_ins topics (what `ros2 topic echo` / `ros2 topic list -v` show, on a
machine without `ros2`): the text of messages (unit), and the commands against a publisher in
another process that is not ours: a NavSatFix and a DiagnosticArray at 10 Hz."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import Imu, NavSatFix
from support.ros_harness import other_process

from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.tools.echo import SHOWN_ELEMENTS, field, lines


# ---- the text of a message ------------------------------------------------------------------
def test_nested_fields_indented_and_numeric_arrays_on_one_line() -> None:
    imu = Imu()
    imu.header.frame_id = "imu_link"
    imu.linear_acceleration.z = 9.81
    imu.orientation_covariance = np.arange(9.0)
    text = list(lines(imu))
    assert text[:4] == ["header:", "  stamp:", "    sec: 0", "    nanosec: 0"]
    assert "  frame_id: 'imu_link'" in text and "  z: 9.81" in text
    assert "orientation_covariance: [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]" in text


def test_a_sequence_of_messages_as_a_yaml_list() -> None:
    array = DiagnosticArray(
        status=[
            DiagnosticStatus(name="imu", message="OK", values=[KeyValue(key="rate", value="134")]),
            DiagnosticStatus(name="leica", level=b"\x01"),
        ]
    )
    text = "\n".join(lines(array))
    assert "status:\n- level: 0\n  name: 'imu'" in text
    assert "  values:\n  - key: 'rate'\n    value: '134'" in text
    assert "- level: 1\n  name: 'leica'" in text


def test_a_long_sequence_is_shortened_and_says_how_much() -> None:
    text = list(lines(np.zeros(SHOWN_ELEMENTS + 5)))
    assert text[0].endswith(", ... 5 more]") and text[0].count("0.0") == SHOWN_ELEMENTS


def test_a_field_path_and_a_wrong_one() -> None:
    fix = NavSatFix()
    fix.status.status = 2
    assert field(fix, "status.status") == 2
    with pytest.raises(AttributeError, match="no field 'sats' in NavSatStatus"):
        field(fix, "status.sats")


# ---- the commands against another process's publishers ----------------------------------------
PUBLISHER = """
import rclpy, sys
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import NavSatFix
rclpy.init()
node = rclpy.create_node("not_ours")
fixes = node.create_publisher(NavSatFix, "/echo_test/fix", 10)
diagnostics = node.create_publisher(DiagnosticArray, "/echo_test/diagnostics", 10)
count = 0
def tick():
    global count
    count += 1
    fixes.publish(NavSatFix(latitude=57.0 + count, altitude=float(count)))
    diagnostics.publish(DiagnosticArray(status=[DiagnosticStatus(name="n", message=str(count))]))
node.create_timer(0.1, tick)
"""


@pytest.fixture(scope="module")
def publisher() -> Iterator[subprocess.Popen[str]]:
    with other_process(PUBLISHER) as process:
        yield process


#: How long a look may wait to discover the publisher [s]. A look runs 10 below its parent's
#: priority (runtime.priority): with the suite's other workers busy on both cores it gets a few
#: percent of one, and importing rclpy and discovering took it more than 20 s (seen in the
#: suite). Passing tests never wait this long: the look ends as soon as it has seen the topic.
DISCOVERY_WAIT_S = "90"


def _gnss_ins(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(gnss_ins_command(*args), capture_output=True, text=True, timeout=150)


@pytest.mark.ros
def test_echo_prints_count_messages_of_another_process(publisher) -> None:
    done = _gnss_ins("echo", "/echo_test/fix", "--count", "3", "--wait", DISCOVERY_WAIT_S)
    assert done.returncode == 0, done.stderr
    messages = done.stdout.split("---\n")
    assert messages[-1] == "" and len(messages) == 4
    latitudes = [float(m.split("latitude: ")[1].split("\n")[0]) for m in messages[:3]]
    assert np.all(np.diff(latitudes) >= 1.0)  # three different messages in order
    assert "status:\n  status: -2\n  service: 0" in messages[0] and done.stderr == ""


@pytest.mark.ros
def test_echo_of_one_field_and_of_a_list_of_messages(publisher) -> None:
    done = _gnss_ins("echo", "/echo_test/fix", "--count", "1", "--field", "altitude")
    assert done.returncode == 0 and float(done.stdout.split("\n")[0]) >= 1.0
    done = _gnss_ins("echo", "/echo_test/diagnostics", "--count", "1", "--field", "status")
    assert done.returncode == 0 and done.stdout.startswith("- level: 0\n  name: 'n'\n")


@pytest.mark.ros
def test_echo_refuses_a_missing_field_and_a_topic_nobody_publishes(publisher) -> None:
    done = _gnss_ins("echo", "/echo_test/fix", "--field", "status.sats", "--wait", DISCOVERY_WAIT_S)
    assert done.returncode == 1 and "no field 'sats' in NavSatStatus" in done.stderr
    done = _gnss_ins("echo", "/echo_test/nobody", "--wait", "1")
    assert done.returncode == 1 and "no publisher of /echo_test/nobody within 1 s" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.ros
def test_topics_lists_types_and_publishers(publisher) -> None:
    done = _gnss_ins("topics", "--wait", DISCOVERY_WAIT_S)
    assert done.returncode == 0, done.stderr
    rows = {line.split()[0]: line.split()[1:] for line in done.stdout.splitlines()[1:]}
    assert rows["/echo_test/fix"] == ["1", "0", "sensor_msgs/msg/NavSatFix"]
    assert rows["/echo_test/diagnostics"] == ["1", "0", "diagnostic_msgs/msg/DiagnosticArray"]
