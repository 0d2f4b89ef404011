"""The supervisor of `gnss_ins launch` (ins_fusion/runtime/processes.py) on small real child
processes: restarts after an exit or a SIGKILL, the backoff, stopping, the appended and rotated
logs and their problem lines; the recorder's command (ins_fusion/runtime/recorder.py) and the
launch loop with stand-in nodes. Timings are injected (a fake clock, short delays) so that each
test takes at most a few seconds."""

from __future__ import annotations

import argparse
import os
import re
import shlex
import signal
import sys
import threading
from collections.abc import Callable
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from support.pacing import pause
from support.paths import REPO
from support.waiting import wait_for

from ins_fusion.runtime.processes import (
    Backoff,
    LogRotation,
    ProcessGroup,
    default_log_dir,
    describe_exit,
)
from ins_fusion.runtime.recorder import Recording, read_topics, recording_name
from ins_fusion.runtime.vehicle_nodes import LEICA, VEHICLE
from ins_fusion.tools import launch
from ins_fusion.tools.cli import build_parser

pytestmark = pytest.mark.slow

SLEEPER = [sys.executable, "-c", "import time; time.sleep(120)"]
#: Ignores SIGINT, then says so on its output.
STUBBORN = [
    sys.executable,
    "-c",
    "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
    "print('ready', flush=True); time.sleep(120)",
]
BANNER = re.compile(
    r"^=== \d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ (\w+) started \(pid (\d+)(, restart \d+)?\): (.*)$"
)


def exiting(code: int, text: str = "") -> list[str]:
    """A child that prints ``text`` and exits with ``code``."""
    return [sys.executable, "-c", f"print({text!r}, flush=True); raise SystemExit({code})"]


class FakeClock:
    """A monotonic clock that moves only when told."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def make_group(tmp_path):
    """ProcessGroups in tmp_path/logs, all stopped at the end of the test."""
    groups: list[ProcessGroup] = []

    def make(**options) -> ProcessGroup:
        options.setdefault("stop_timeout_s", 2.0)
        group = ProcessGroup(tmp_path / "logs", **options)
        groups.append(group)
        return group

    yield make
    for group in groups:
        group.stop_all()


def supervise(group: ProcessGroup, done: Callable[[], bool], timeout_s: float) -> list[str]:
    """``group.poll()`` every 20 ms until ``done()``; the console lines. Fails after
    ``timeout_s``."""
    lines: list[str] = []

    def polled() -> bool:
        if done():
            return True
        lines.extend(group.poll())
        return False

    assert wait_for(polled, timeout_s), lines
    return lines


def test_a_process_that_exits_is_started_again_and_the_others_are_not_touched(make_group):
    group = make_group(backoff=Backoff(first_s=0.1))
    first = group.start("first", SLEEPER)
    quitter = group.start("quitter", exiting(0, "bye"))
    last = group.start("last", SLEEPER)
    lines = supervise(group, lambda: group.restarts()["quitter"] >= 1, 3.0)
    assert re.fullmatch(r"quitter exited \(code 0\) after [\d.]+ s; restart 1 in 0\.1 s", lines[0])
    assert lines[1] == f"quitter restarted (pid {group.children['quitter'].process.pid})"
    assert group.children["quitter"].process is not quitter
    assert group.children["first"].process is first and first.poll() is None
    assert group.children["last"].process is last and last.poll() is None
    assert group.restarts() == {"first": 0, "quitter": 1, "last": 0}


def test_a_killed_process_runs_again_within_3_s_with_the_default_backoff(make_group):
    group = make_group(backoff=Backoff())
    processes = {name: group.start(name, SLEEPER) for name in ("imu", "gnss", "fusion")}
    killed = processes["gnss"].pid
    os.kill(killed, signal.SIGKILL)
    lines = supervise(group, lambda: group.children["gnss"].process.pid != killed, 3.0)
    assert group.children["gnss"].process.poll() is None
    assert "gnss exited (signal SIGKILL)" in lines[0] and lines[0].endswith("restart 1 in 0.5 s")
    for name in ("imu", "fusion"):
        assert group.children[name].process is processes[name]
        assert processes[name].poll() is None


def test_backoff_doubles_up_to_its_cap_and_starts_again_after_a_long_run(make_group):
    clock = FakeClock()
    group = make_group(backoff=Backoff(first_s=1.0, max_s=4.0, reset_after_s=10.0), clock=clock)
    group.start("crasher", exiting(3))
    delays = []
    for restart in range(1, 6):
        group.children["crasher"].process.wait(timeout=30)
        clock.now += 0.5
        (line,) = group.poll()
        assert line.startswith(f"crasher exited (code 3) after 0.5 s; restart {restart} in ")
        delays.append(float(line.split(" in ")[-1].removesuffix(" s")))
        clock.now += delays[-1] - 0.01
        assert group.poll() == []  # not before its time
        clock.now += 0.01
        (line,) = group.poll()
        assert line.startswith("crasher restarted (pid ")
    assert delays == [1.0, 2.0, 4.0, 4.0, 4.0]
    assert group.children["crasher"].failures == 5
    group.children["crasher"].process.wait(timeout=30)
    clock.now += 10.0  # it ran reset_after_s: its failures count from 1 again
    (line,) = group.poll()
    assert line.endswith("after 10.0 s; restart 6 in 1.0 s")
    assert group.children["crasher"].failures == 1
    assert group.restarts() == {"crasher": 5}


def test_backoff_delays():
    backoff = Backoff()
    assert [backoff.delay_s(n) for n in range(1, 10)] == [0.5, 1, 2, 4, 8, 16, 30, 30, 30]
    assert backoff.delay_s(10**6) == 30.0  # a process failing for weeks


def test_five_kills_in_a_row_do_not_end_the_supervision(make_group):
    group = make_group(backoff=Backoff(first_s=0.05, max_s=0.2))
    other = group.start("other", SLEEPER)
    group.start("node", SLEEPER)
    for kills in range(1, 6):
        os.kill(group.children["node"].process.pid, signal.SIGKILL)
        supervise(group, lambda n=kills: group.restarts()["node"] == n, 5.0)
    assert group.children["node"].process.poll() is None
    assert group.children["node"].failures == 5
    assert group.children["other"].process is other and other.poll() is None


def test_stop_all_stops_everything_and_nothing_is_restarted_after_it(make_group, capsys):
    group = make_group(backoff=Backoff(first_s=0.2), stop_timeout_s=0.5)
    for name in ("first", "second"):
        group.start(name, SLEEPER)
    group.start("stubborn", STUBBORN)
    group.start("quitter", exiting(3))
    group.children["quitter"].process.wait(timeout=30)
    ready = group.log_path("stubborn")
    supervise(group, lambda: "ready" in ready.read_text().splitlines(), 10.0)
    group.poll()
    assert group.children["quitter"].restart_at_s is not None  # due in 0.2 s
    assert group.stop_all() == ["quitter (exit code 3)"]
    assert "stubborn did not stop; killing it" in capsys.readouterr().out
    assert group.children["stubborn"].process.returncode == -signal.SIGKILL
    processes = {name: child.process for name, child in group.children.items()}
    assert all(process.poll() is not None for process in processes.values())
    pause(0.3)  # past the restart that was due in 0.2 s: none after the stop
    assert group.poll() == []
    assert {name: child.process for name, child in group.children.items()} == processes
    assert group.restarts() == {"first": 0, "second": 0, "stubborn": 0, "quitter": 0}
    last = {name: group.log_path(name).read_text().splitlines()[-1] for name in processes}
    stamp = r"^=== \d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ "
    # SIGINT stops a started interpreter; one still starting on a loaded machine is killed.
    ended = r"first (stopped|killed \(no stop within 0.5 s\)) by the supervisor"
    assert re.match(stamp + ended, last["first"])
    assert re.match(
        stamp + r"stubborn killed \(no stop within 0.5 s\) by the supervisor \(signal SIGKILL\)",
        last["stubborn"],
    )
    assert "quitter exited (code 3)" in last["quitter"]  # it had ended: nothing stopped


def test_logs_are_appended_with_a_banner_at_each_start(make_group, tmp_path):
    log = tmp_path / "logs" / "talker.log"
    log.parent.mkdir()
    log.write_text("a previous run\n")
    clock = FakeClock()
    group = make_group(backoff=Backoff(first_s=1.0), clock=clock)
    command = exiting(0, "hello")
    pids = [group.start("talker", command).pid]
    group.children["talker"].process.wait(timeout=30)
    group.poll()
    clock.now += 1.0
    group.poll()
    pids.append(group.children["talker"].process.pid)
    group.children["talker"].process.wait(timeout=30)
    lines = log.read_text().splitlines()
    assert lines[0] == "a previous run"
    banners = [(i, BANNER.match(line)) for i, line in enumerate(lines) if BANNER.match(line)]
    assert [int(match[2]) for _, match in banners] == pids
    assert [match[3] for _, match in banners] == [None, ", restart 1"]
    assert all(match[4] == shlex.join(command) for _, match in banners)
    said = [i for i, line in enumerate(lines) if line == "hello"]
    assert len(said) == 2 and banners[0][0] < said[0] < banners[1][0] < said[1]
    assert any(
        re.search(r"talker exited \(code 0\) after [\d.]+ s; restart 1 in", x) for x in lines
    )


def test_logs_are_rotated_by_size_at_a_start(make_group, tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "node.log").write_text("x" * 200)
    (logs / "node.log.1").write_text("one")
    (logs / "node.log.2").write_text("two")
    (logs / "small.log").write_text("y" * 50)
    group = make_group(rotation=LogRotation(max_bytes=100, keep=2))
    group.start("node", SLEEPER)
    group.start("small", SLEEPER)
    assert (logs / "node.log.1").read_text() == "x" * 200
    assert (logs / "node.log.2").read_text() == "one"  # "two" was the oldest beyond keep
    assert not (logs / "node.log.3").exists()
    assert BANNER.match((logs / "node.log").read_text().splitlines()[0])
    assert (logs / "small.log").read_text().startswith("y" * 50 + "===")
    assert not (logs / "small.log.1").exists()
    assert LogRotation() == LogRotation(max_bytes=10 * 1024 * 1024, keep=5)


def test_problems_reports_each_new_line_once_and_not_the_old_runs(make_group, tmp_path):
    log = tmp_path / "logs" / "node.log"
    log.parent.mkdir()
    log.write_text("[ERROR] a previous launch's error\n")
    clock = FakeClock()
    group = make_group(backoff=Backoff(first_s=1.0), clock=clock)
    group.start("node", exiting(1, "[WARN] now"))

    def next_run() -> None:
        """Wait for the run to end, then start the next one."""
        group.children["node"].process.wait(timeout=30)
        group.poll()
        clock.now += 10.0
        group.poll()

    group.children["node"].process.wait(timeout=30)
    assert group.problems() == ["node: [WARN] now"]
    assert group.problems() == []
    next_run()
    next_run()  # the second run's line is read at the third start, before the log moves on
    group.children["node"].process.wait(timeout=30)
    assert group.problems() == ["node: [WARN] now", "node: [WARN] now"]
    assert group.restarts() == {"node": 2}


def test_default_log_dir_follows_xdg_state_home():
    home_state = Path.home() / ".local" / "state" / "gnss_ins" / "logs"
    assert default_log_dir({"XDG_STATE_HOME": "/var/lib/car"}) == Path("/var/lib/car/gnss_ins/logs")
    assert default_log_dir({}) == home_state
    assert default_log_dir({"XDG_STATE_HOME": "relative"}) == home_state
    assert describe_exit(0) == "code 0" and describe_exit(-9) == "signal SIGKILL"


def test_the_recorder_continues_one_recording_named_once():
    tz = timezone(timedelta(hours=2))
    assert recording_name(datetime(2024, 6, 1, 14, 30, 5, tzinfo=tz)) == "vehicle_20240601_123005"
    assert re.fullmatch(r"vehicle_\d{8}_\d{6}", recording_name())
    topics = read_topics(REPO / "config" / "recorded_topics.yaml")
    command = Recording(Path("/data/vehicle_1"), tuple(topics)).command()
    assert command[command.index("record") :] == [
        "record",
        "-o",
        "/data/vehicle_1",
        "--resume",
        "--max-bag-duration",
        "600.0",
        "--name",
        "recorder",
        "--storage",
        "mcap",
        *topics,
    ]
    command = Recording(Path("d"), ("/a",), 60.0, "sqlite3", "2G").command()
    assert command[command.index("--storage") :] == [
        *("--storage", "sqlite3", "--min-free", "2G", "/a")
    ]


def test_recorded_topics_are_the_nodes_topics():
    topics = read_topics(REPO / "config" / "recorded_topics.yaml")
    assert topics == [
        "/imu/data_raw",
        "/imu/temperature",
        "/leica/gnss/fix",
        "/leica/gnss/vel",
        "/leica/gnss/time_reference",
        "/adu5/gnss/attitude",
        "/adu5/gnss/fix",
        "/imu/raw",
        "/leica/nmea",
        "/adu5/nmea",
        "/leica/port_events",
        "/adu5/port_events",
        "/leica/to_device/nmea",
        "/adu5/to_device/nmea",
        "/leica/rtcm",
        "/leica/to_device/rtcm",
        "/ins/odometry",
        "/ins/fix",
        "/diagnostics",
    ]
    namespaces = {spec.namespace for spec in VEHICLE if spec.namespace}
    assert {t.split("/")[1] for t in topics if "/gnss/" in t} == namespaces


@pytest.mark.parametrize(
    "text", ["", "topics: []\n", "topics: [imu/data_raw]\n", "- /imu/data_raw\n"]
)
def test_a_wrong_topics_file_is_refused(tmp_path, text):
    path = tmp_path / "topics.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match="topics"):
        read_topics(path)


def launch_args(tmp_path: Path, *options: str) -> argparse.Namespace:
    """``gnss_ins launch`` options as parsed, the ports existing files."""
    ports = [f"--{role}-port={os.devnull}" for role in ("imu", "leica", "adu5")]
    argv = ["launch", *ports, "--log-dir", str(tmp_path / "logs"), *options]
    return build_parser("launch").parse_args(argv)


def test_launch_record_options(tmp_path):
    args = launch_args(tmp_path, "--record", str(tmp_path / "bags"))
    record = launch.recording(args)
    assert record.output.parent == tmp_path / "bags"
    assert (record.split_s, record.storage, record.min_free) == (600.0, "mcap", None)
    assert "/leica/gnss/fix" in record.topics
    bad = tmp_path / "bad.yaml"
    bad.write_text("topics: 3\n")
    args = launch_args(tmp_path, "--record", str(tmp_path / "bags"), "--record-topics", str(bad))
    assert launch.run(args) == 2


@pytest.fixture
def stand_ins(monkeypatch):
    """The launch loop with stand-in nodes (the Leica's exits with 3 at once, the others
    sleep) and its stop handler, kept instead of being installed."""
    handlers: dict[int, Callable[..., None]] = {}
    monkeypatch.setattr(
        signal, "signal", lambda number, handler: handlers.setdefault(number, handler)
    )
    monkeypatch.setattr(
        launch,
        "command",
        lambda spec, *_: exiting(3, "[ERROR] no port") if spec is LEICA else SLEEPER,
    )
    return handlers


def test_launch_stop_on_failure_stops_everything(tmp_path, stand_ins, capsys):
    assert launch.run(launch_args(tmp_path, "--stop-on-failure")) == 1
    out = capsys.readouterr().out
    assert "leica_gnss: [ERROR] no port" in out
    assert "error: leica_gnss stopped on its own" in out and "restart" not in out


def test_launch_restarts_a_node_until_stopped(tmp_path, stand_ins, capsys):
    timer = threading.Timer(2.5, lambda: stand_ins[signal.SIGTERM]())
    timer.start()
    try:
        assert launch.run(launch_args(tmp_path)) == 0
    finally:
        timer.cancel()
    out = capsys.readouterr().out
    assert out.splitlines()[-1].startswith("stopped; logs in ")  # Ctrl-C/SIGTERM: said
    assert re.search(r"leica_gnss exited \(code 3\) after [\d.]+ s; restart 1 in 0\.5 s", out)
    assert "leica_gnss restarted (pid " in out and "leica_gnss: [ERROR] no port" in out
    assert "stopped on its own" not in out
