"""`gnss_ins launch` and the shared vehicle node table (also used by launch/vehicle.launch.py):
the nodes on emulated devices, a node killed with SIGKILL started again; the ROS launch file's
respawn, recorder and NTRIP client, read with stand-ins of the ``launch`` packages."""

from __future__ import annotations

import ast
import importlib.util
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
import types
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import rclpy
from support.launching import NODE_NAMES, TOPICS, launched, node_pids
from support.pacing import pause
from support.paths import REPO
from support.ros_harness import Collector, wait_for

from ins_fusion.bags.bag_io import BagReader
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import (
    FUSION,
    VEHICLE,
    discovery_environment,
    ros_arguments,
)
from ins_fusion.runtime.watchdog import read_heard

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def test_node_table_wires_the_fusion_node_to_the_receivers_namespaces():
    namespaces = {spec.name: spec.namespace for spec in VEHICLE}
    assert namespaces == {
        "imu400cc_node": "",
        "leica_gnss": "leica",
        "adu5_gnss": "adu5",
        "ins_fusion_node": "",
    }
    args = ros_arguments(FUSION, None, None)
    assert "gnss/fix:=/leica/gnss/fix" in args
    assert "gnss/attitude:=/adu5/gnss/attitude" in args
    assert (REPO / "config" / "ins_fusion.yaml").samefile(args[args.index("--params-file") + 1])


def test_the_nodes_talk_over_udp_only_never_fast_dds_shared_memory():
    """Fast DDS 2.14's shared-memory transport stalled every publication of a process for 333 ms
    when another process joined: the launched nodes use UDP only."""
    localhost = discovery_environment("LOCALHOST", {})
    assert localhost["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    profile = Path(localhost["FASTRTPS_DEFAULT_PROFILES_FILE"]).read_text()
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in profile
    assert "<type>UDPv4</type>" in profile and "SHM" not in profile
    assert "<address>127.0.0.1</address>" in profile  # this machine only, as LOCALHOST
    assert discovery_environment("SUBNET", {}) == {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
        "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
    }
    other = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    assert discovery_environment("LOCALHOST", other) == {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"
    }


def test_ros_launch_file_uses_the_shared_table():
    source = (REPO / "launch" / "vehicle.launch.py").read_text()
    tree = ast.parse(source)
    imported = {
        alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module == "ins_fusion.runtime.vehicle_nodes"
        for alias in node.names
    }
    assert {"VEHICLE", "DEFAULT_PORTS"} <= imported
    assert "generate_launch_description" in source


class _Action:
    """Stand-in of a ROS launch action or description: keeps its arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Configuration:
    """Stand-in of LaunchConfiguration: the context is a dict of the arguments' values."""

    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context[self.name]


def _stub_launch_modules(monkeypatch):
    """The parts of the ``launch`` and ``launch_ros`` packages vehicle.launch.py uses."""
    stubs = {
        "launch": {"LaunchContext": dict, "LaunchDescription": _Action},
        "launch.actions": dict.fromkeys(
            ("DeclareLaunchArgument", "ExecuteProcess", "OpaqueFunction"), _Action
        ),
        "launch.conditions": {
            "evaluate_condition_expression": lambda context, expression: (
                expression[0].perform(context).lower() in ("true", "1")
            )
        },
        "launch.substitutions": {"LaunchConfiguration": _Configuration},
        "launch_ros": {},
        "launch_ros.actions": {"Node": type("Node", (_Action,), {})},
    }
    for name, attributes in stubs.items():
        module = types.ModuleType(name)
        module.__dict__.update(attributes)
        monkeypatch.setitem(sys.modules, name, module)


def _launch_file(monkeypatch) -> tuple[dict[str, str], Callable[[dict[str, str]], list]]:
    """vehicle.launch.py read with the stand-ins: its arguments' defaults, and the function that
    gives its processes for the arguments' values."""
    _stub_launch_modules(monkeypatch)
    source = importlib.util.spec_from_file_location(
        "vehicle_launch", REPO / "launch" / "vehicle.launch.py"
    )
    module = importlib.util.module_from_spec(source)
    source.loader.exec_module(module)
    (*arguments, opaque) = module.generate_launch_description().args[0]
    return {a.args[0]: a.kwargs["default_value"] for a in arguments}, opaque.kwargs["function"]


@pytest.mark.parametrize("respawn", ["true", "false"])
def test_ros_launch_file_respawns_the_nodes_and_starts_the_recorder(monkeypatch, tmp_path, respawn):
    context, processes = _launch_file(monkeypatch)
    assert (context["respawn"], context["record_dir"]) == ("true", "")
    *nodes, status = processes(context)  # no record_dir: no recorder
    assert len(nodes) == len(VEHICLE) and status.kwargs["cmd"][-2:] == ["status", "--serve"]
    context.update(respawn=respawn, record_dir=str(tmp_path / "bags"))
    *nodes, status, recorder = processes(context)
    assert [node.kwargs["name"] for node in nodes] == [spec.name for spec in VEHICLE]
    leica = nodes[[spec.name for spec in VEHICLE].index("leica_gnss")]
    assert {"port": "/dev/ttyUSB1"} in leica.kwargs["parameters"]
    for process in [*nodes, status, recorder]:
        assert process.kwargs["respawn"] is (respawn == "true")
        assert process.kwargs["respawn_delay"] == 1.0
        assert process.kwargs["additional_env"] == discovery_environment("LOCALHOST")
    command = recorder.kwargs["cmd"]
    output = Path(command[command.index("-o") + 1])
    assert output.parent == tmp_path / "bags" and output.parent.is_dir()
    assert re.fullmatch(r"vehicle_\d{8}_\d{6}", output.name)
    assert "--resume" in command and "/leica/gnss/fix" in command
    assert command[command.index("--max-bag-duration") + 1] == "600.0"


def test_ros_launch_file_starts_the_ntrip_client_with_the_url_only(monkeypatch, tmp_path):
    """``ntrip_url:=`` adds the NTRIP client in the rover's namespace with its file, the URL and
    the password file's path as parameters; the recording holds the corrections and the rover's
    sentences."""
    monkeypatch.setenv("NTRIP_PASSWORD", "launch-S3cret")
    url, secret = "http://rover@caster.example.net:2101/AAU00DNK", "/etc/gnss_ins/ntrip"
    defaults, launch_file = _launch_file(monkeypatch)
    arguments = {**defaults, "ntrip_url": url, "ntrip_password_file": secret}
    processes = launch_file({**arguments, "record_dir": str(tmp_path)})
    (client,) = [p for p in processes if p.kwargs.get("name") == "ntrip_client"]
    assert (client.kwargs["executable"], client.kwargs["namespace"]) == ("ntrip_node", "leica")
    config, parameters = client.kwargs["parameters"]
    assert (REPO / "config" / "ntrip.yaml").samefile(config)
    assert parameters == {"url": url, "password_file": secret}
    assert "launch-S3cret" not in repr([(p.args, p.kwargs) for p in processes])
    recorder = processes[-1].kwargs["cmd"]
    assert {"/leica/rtcm", "/leica/nmea"} <= set(recorder)
    without_file = launch_file({**arguments, "ntrip_password_file": ""})[len(VEHICLE)]
    assert without_file.kwargs["name"] == "ntrip_client"
    assert without_file.kwargs["parameters"][1] == {"url": url}  # NTRIP_PASSWORD, inherited


def test_a_hung_node_is_killed_and_restarted_and_the_others_left(tmp_path):
    """A node that stops without ending (SIGSTOP: hung in a call) goes silent on /diagnostics:
    launch kills it after --restart-silent and starts it again; the others keep their PIDs."""
    with launched(tmp_path, "--restart-silent", "6") as (launcher, collector, output, _):
        assert wait_for(lambda: collector.count("imu/data_raw") > 100, 60.0)
        assert wait_for(lambda: set(node_pids(launcher.pid)) == NODE_NAMES, 10.0)

        # The status server has heard the IMU node and listened for the 6 s it needs to judge.
        def judging() -> bool:
            heard = read_heard(tmp_path)
            return (
                heard is not None
                and "imu400cc_node" in heard.last_status_s
                and heard.written_s - heard.since_s > 6.0
            )

        assert wait_for(judging, 60.0)
        before = node_pids(launcher.pid)
        hung = before["imu400cc_node"]
        os.kill(hung, signal.SIGSTOP)
        stopped_at = time.monotonic()
        assert wait_for(lambda: node_pids(launcher.pid).get("imu400cc_node", hung) != hung, 20.0)
        restarted_after_s = time.monotonic() - stopped_at
        print(f"restarted {restarted_after_s:.1f} s after the stop")
        after = node_pids(launcher.pid)
        assert {n: p for n, p in after.items() if n != "imu400cc_node"} == {
            n: p for n, p in before.items() if n != "imu400cc_node"
        }
        packets = collector.count("imu/data_raw")
        assert wait_for(lambda: collector.count("imu/data_raw") > packets + 100, 30.0)
        assert launcher.poll() is None
    assert launcher.returncode == 0, output[0]
    # Killed for the silence it was given, not before.
    found = re.search(r"imu400cc_node killed: no status on /diagnostics for ([\d.]+) s", output[0])
    assert found and float(found.group(1)) >= 6.0, output[0]  # printed to 0.1 s
    assert "imu400cc_node exited (signal SIGKILL)" in output[0]
    log = (tmp_path / "imu400cc_node.log").read_text()
    assert "imu400cc_node killed: no status on /diagnostics for " in log


RECORDER = {"recorder": "--resume"}


def _reporters(collector: Collector) -> set[str]:
    """Node names in the /diagnostics statuses received so far."""
    return {
        status.name.split(":")[0]
        for array in collector.get("/diagnostics")
        for status in array.status
    }


def test_launch_refuses_a_missing_config_directory(tmp_path):
    result = subprocess.run(
        gnss_ins_command("launch", "--config", str(tmp_path / "nope")),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert "not a directory" in result.stdout


def test_launch_refuses_a_free_space_limit_the_recorder_would_refuse(tmp_path):
    result = subprocess.run(
        gnss_ins_command("launch", "--record", str(tmp_path), "--min-free", "12 parsecs"),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert "bad size" in result.stderr
    assert not list(tmp_path.iterdir())  # nothing started, nothing recorded


def test_launch_runs_every_node_restarts_a_killed_one_and_status_shows_it(tmp_path):
    """`gnss_ins launch` on the emulated devices: every node started, publishing and reporting on
    /diagnostics; a kill -9 of the Leica node restarts it alone (the others keep their PIDs) and
    it publishes again. `gnss_ins status --json` beside it: every node, OK IMU, then the Leica
    node's restart; the aggregate on /gnss_ins/status. The IMU unplugged for 5 s: the IMU and the
    fusion (no_imu) in ERROR, both back within 3 s of the replug. SIGINT stops it cleanly."""
    with launched(tmp_path) as (launcher, collector, output, imu):
        assert wait_for(lambda: all(collector.count(t) > 2 for t in TOPICS), 60.0), {
            t: collector.count(t) for t in TOPICS
        }
        # Every node reports on /diagnostics (the fusion node starts slowest).
        assert wait_for(lambda: _reporters(collector) >= NODE_NAMES, 60.0), _reporters(collector)
        assert wait_for(lambda: set(node_pids(launcher.pid)) == NODE_NAMES, 10.0)
        view = _status(tmp_path)
        assert set(view["processes"]) == NODE_NAMES
        assert view["processes"]["imu400cc_node"]["level"] == "OK", view
        assert {p["restarts"] for p in view["processes"].values()} == {0}

        before = node_pids(launcher.pid)
        killed = before["leica_gnss"]
        os.kill(killed, signal.SIGKILL)
        restarted = lambda: node_pids(launcher.pid).get("leica_gnss", killed) != killed  # noqa: E731
        assert wait_for(restarted, 3.0)
        after = node_pids(launcher.pid)
        assert {n: p for n, p in after.items() if n != "leica_gnss"} == {
            n: p for n, p in before.items() if n != "leica_gnss"
        }
        assert _status(tmp_path)["processes"]["leica_gnss"]["restarts"] == 1
        # The new process opens the emulated port again and publishes.
        fixes = collector.count("leica/gnss/fix")
        assert wait_for(lambda: collector.count("leica/gnss/fix") > fixes + 2, 30.0)
        assert node_pids(launcher.pid) == after
        system = collector.get("/gnss_ins/status")[-1].status[0]
        assert system.name == "gnss_ins: system"

        unplugged = time.time()
        imu.unplug()
        assert wait_for(lambda: _levels_since(collector, unplugged) >= BOTH_ERROR, 5.0)
        took = max(_first_since(collector, unplugged, name, level) for name, level in BOTH_ERROR)
        # The fusion said so as soon as its IMU watchdog saw imu_timeout (0.5 s) of silence
        # (ticks every 0.25 s): the silence its status reports, well within 1.5 s.
        assert _fusion_silence_s(collector, unplugged) <= 1.5
        pause(5.0)  # unplugged for 5 s
        plugged = time.time()
        imu.plug()

        def back():
            return ("imu400cc_node", 0) in _levels_since(collector, plugged) and bool(
                _fusion_states_since(collector, plugged) - {"no_imu"}
            )

        assert wait_for(back, 3.0), _levels_since(collector, plugged)
        print(f"unplug seen after {took - unplugged:.2f} s")
    assert launcher.returncode == 0, output[0]
    for spec in VEHICLE:
        assert f"started {spec.name}" in output[0]
        assert (tmp_path / f"{spec.name}.log").exists()
    assert "leica_gnss exited (signal SIGKILL) after " in output[0]
    assert "leica_gnss restarted (pid " in output[0]
    log = (tmp_path / "leica_gnss.log").read_text()
    assert f"leica_gnss started (pid {after['leica_gnss']}, restart 1)" in log


#: (status name prefix, level) of the IMU node and the fusion node once the IMU is unplugged.
BOTH_ERROR = {("imu400cc_node", 2), ("ins_fusion_node", 2)}


def _diagnostics_since(collector: Collector, since: float):
    arrays = zip(
        collector.receive_times["/diagnostics"], collector.get("/diagnostics"), strict=True
    )
    for at, array in arrays:
        if at >= since:
            for status in array.status:
                yield at, status.name.split(":")[0], status


def _recorder_takes_imu_since(collector: Collector, since: float) -> bool:
    """A status received after ``since`` [s, host time] reports an IMU message taken by a
    recorder less than 0.5 s before it."""
    for _, _, status in _diagnostics_since(collector, since):
        values = {kv.key: kv.value for kv in status.values}
        if float(values.get("/imu/data_raw age_s", "inf")) < 0.5:
            return True
    return False


def _levels_since(collector: Collector, since: float) -> set[tuple[str, int]]:
    return {(name, status.level[0]) for _, name, status in _diagnostics_since(collector, since)}


def _fusion_states_since(collector: Collector, since: float) -> set[str]:
    return {
        kv.value
        for _, name, status in _diagnostics_since(collector, since)
        if name == "ins_fusion_node"
        for kv in status.values
        if kv.key == "state"
    }


def _fusion_silence_s(collector: Collector, since: float) -> float:
    """The IMU silence [s] the fusion's first no_imu status after ``since`` reports."""
    for _, name, status in _diagnostics_since(collector, since):
        found = re.match(r"no_imu: no IMU message for ([\d.]+) s", status.message)
        if name == "ins_fusion_node" and found:
            return float(found.group(1))
    raise AssertionError("no no_imu status of the fusion")


def _first_since(collector: Collector, since: float, name: str, level: int) -> float:
    return min(
        at
        for at, found, status in _diagnostics_since(collector, since)
        if found == name and status.level[0] == level
    )


def _status(log_dir: Path) -> dict:
    ros_logs = log_dir.parent / "status_ros_logs"
    result = subprocess.run(
        gnss_ins_command("status", "--json", "--log-dir", str(log_dir)),
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "ROS_LOG_DIR": str(ros_logs)},
    )
    view = json.loads(result.stdout)
    assert result.returncode == min(["OK", "WARN", "ERROR", "STALE"].index(view["level"]), 2)
    assert not ros_logs.exists() or not any(ros_logs.iterdir())  # a look leaves no ROS log file
    return view


#: Per node, the recorded topic it publishes, and the recorded topics that go on while it is
#: down (the fusion's output needs the IMU), with the longest gap allowed in them [s].
OWN_TOPIC = {
    "imu400cc_node": "/imu/data_raw",
    "leica_gnss": "/leica/gnss/fix",
    "adu5_gnss": "/adu5/gnss/attitude",
    "ins_fusion_node": "/ins/odometry",
}
#: The window around a kill in which the other topics' gaps are judged: seconds before, after.
KILL_WINDOW_S = (2.0, 3.0)
LONGEST_GAP_S = {
    "/imu/data_raw": 0.5,
    "/leica/gnss/fix": 1.6,
    "/adu5/gnss/attitude": 0.6,
    "/ins/odometry": 0.5,
}


def test_each_node_and_the_recorder_killed_in_turn_come_back_and_the_recording_goes_on(tmp_path):
    """kill -9 of each node in turn under `launch --record`: running again within 3 s with the
    other PIDs unchanged, publishing again; the recording has a gap in that node's topic only.
    Then a kill -9 of the recorder: the next one continues the same recording, complete."""
    bags = tmp_path / "bags"
    kills: dict[str, float] = {}
    with launched(tmp_path, "--record", str(bags)) as (launcher, collector, output, _imu):
        assert wait_for(lambda: _reporters(collector) >= NODE_NAMES, 60.0), _reporters(collector)
        recording = lambda: "recording /ins/odometry" in (tmp_path / "recorder.log").read_text()  # noqa: E731
        assert wait_for(recording, 30.0)
        pause(KILL_WINDOW_S[0])  # recorded before the first kill's window
        for name in OWN_TOPIC:
            before = node_pids(launcher.pid)
            kills[name] = time.time()
            os.kill(before[name], signal.SIGKILL)
            again = lambda n=name, b=before: node_pids(launcher.pid).get(n, b[n]) != b[n]  # noqa: E731
            assert wait_for(again, 3.0), name
            after = node_pids(launcher.pid)
            assert {n: p for n, p in after.items() if n != name} == {
                n: p for n, p in before.items() if n != name
            }

            def back(n=name, t=kills[name]):
                return (n, 0) in _levels_since(collector, t) or (
                    n == "ins_fusion_node" and bool(_fusion_states_since(collector, t))
                )

            assert wait_for(back, 30.0), name  # its status again: it runs and reports
            # The next kill outside the window this one's gaps are judged in.
            pause(max(0.0, kills[name] + sum(KILL_WINDOW_S) - time.time()))

        killed = node_pids(launcher.pid, RECORDER)["recorder"]
        os.kill(killed, signal.SIGKILL)
        killed_at = time.time()
        assert wait_for(
            lambda: node_pids(launcher.pid, RECORDER).get("recorder", killed) != killed, 3.0
        )
        # The second recorder has written (its log says so) and more than 2 s after the kill.
        log = tmp_path / "recorder.log"
        continued = lambda: "recording continued: gap of" in log.read_text()  # noqa: E731
        assert wait_for(continued, 30.0)
        # It takes IMU messages later than 2 s after the kill (its own status says so: its
        # first writes may be another topic's, its IMU subscription matched later).
        assert wait_for(lambda: _recorder_takes_imu_since(collector, killed_at + 2.5), 30.0)
    assert launcher.returncode == 0, output[0]
    (bag,) = bags.iterdir()
    assert "continuing " in log.read_text()
    with BagReader(bag) as reader:
        times = {
            topic: np.array([m.log_time_ns / 1e9 for m in reader.messages([topic])])
            for topic in LONGEST_GAP_S
        }
    before_s, after_s = KILL_WINDOW_S
    for name, killed in kills.items():
        for topic, t in times.items():
            around = t[(t > killed - before_s) & (t < killed + after_s)]
            gap = float(np.diff(around).max()) if len(around) > 1 else math.inf
            own = topic == OWN_TOPIC[name] or (name == "imu400cc_node" and topic == "/ins/odometry")
            if own:
                assert t[t > killed + 1.0].size, (name, topic, "never again")
            else:
                assert gap <= LONGEST_GAP_S[topic], (name, topic, gap)
    # The recorder's kill: a gap in every topic (closed by the second recorder: complete).
    imu = times["/imu/data_raw"]
    before, after = imu[imu < killed_at], imu[imu > killed_at]
    assert before.size and after.size and after[-1] > killed_at + 2.0
    gap = after[0] - before[-1]
    print(f"recording gap at the recorder's kill: {gap:.2f} s")
    assert gap < 10.0  # 3.9 s on an idle machine: the restart and the recorder's start-up
