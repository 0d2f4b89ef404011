"""gnss_ins demo never deletes what it did not write: its output directory is created, or
cleared of an earlier demo's entries, or refused; SIGTERM/SIGHUP stop its children; a whole
(short) demo writes one report and one figure and stops its children without shutdown noise."""

from __future__ import annotations

import json
import os
import signal
import subprocess
from pathlib import Path

import pytest

from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import VEHICLE
from ins_fusion.tools import cli
from ins_fusion.tools.demo import (
    DURATION_LIMIT_ENV,
    STANDSTILL_S,
    _default_outages,
    _describe_outages,
    _duration_s,
    _prepare_output,
    window_s,
)


def test_a_new_directory_is_created_and_marked(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    assert _prepare_output(out) is None
    assert (out / "logs").is_dir() and (out / ".gnss_ins_demo").is_file()


def test_an_earlier_demo_is_replaced(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    assert _prepare_output(out) is None
    (out / "replay.png").write_bytes(b"old")
    (out / "drive").mkdir()
    (out / "drive" / "drive.mcap").write_bytes(b"old")
    assert _prepare_output(out) is None
    assert not (out / "replay.png").exists() and not (out / "drive").exists()


def test_a_directory_with_the_users_files_is_refused_and_kept(tmp_path: Path, capsys) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("years of work")
    assert "thesis.tex" in (_prepare_output(out) or "")
    # Through the command line: exit 2, a message, the file untouched.
    assert cli.main(["demo", "--output-dir", str(out)]) == 2
    assert "nothing was deleted" in capsys.readouterr().err
    assert (out / "thesis.tex").read_text() == "years of work"
    # An earlier demo's directory to which the user added a file: refused as well.
    demo = tmp_path / "demo"
    assert _prepare_output(demo) is None
    (demo / "notes.txt").write_text("mine")
    assert "notes.txt" in (_prepare_output(demo) or "")
    assert (demo / "notes.txt").exists()


def test_a_file_in_the_way_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "demo"
    path.write_text("x")
    assert "not a directory" in (_prepare_output(path) or "")


@pytest.mark.parametrize("duration_s", [66.0, 75.0, 90.0, 104.0, 120.0, 150.0, 300.0])
def test_the_default_outages_lie_inside_any_drive_and_are_said(duration_s: float) -> None:
    outages = _default_outages(duration_s)
    assert outages, duration_s  # a drive of 6 s or more after the standstill has one
    for window in map(window_s, outages):
        assert window["start_s"] >= STANDSTILL_S  # after the alignment's standstill
        assert window["start_s"] + window["duration_s"] <= duration_s - 2.0
    assert len(outages) == (2 if duration_s >= STANDSTILL_S + 80 else 1)
    said = _describe_outages(outages, duration_s)
    assert said.count(" s at ") == len(outages), said


def test_a_drive_without_room_for_an_outage_says_so() -> None:
    assert _default_outages(62.0) == []
    assert "without GNSS outages" in _describe_outages([], 62.0)


def test_the_duration_limit_only_shortens(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _duration_s(90.0) == 90.0
    monkeypatch.setenv(DURATION_LIMIT_ENV, "40")
    assert _duration_s(90.0) == 40.0 and _duration_s(30.0) == 30.0


@pytest.mark.ros
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_a_terminated_demo_stops_its_children(tmp_path: Path, signum: int) -> None:
    demo = subprocess.Popen(
        gnss_ins_command("demo", "--duration", "40", "--output-dir", str(tmp_path / "demo")),
        stdout=subprocess.PIPE,
        text=True,
    )
    assert demo.stdout is not None
    lines = []
    for line in demo.stdout:  # until the nodes and the recorder run
        lines.append(line)
        if "recording:" in line:
            break
    assert any("ROS_DOMAIN_ID=" in line for line in lines), lines
    children = subprocess.run(
        ["ps", "-o", "pid=", "--ppid", str(demo.pid)], capture_output=True, text=True
    ).stdout.split()
    assert len(children) == 6  # simulator, four nodes, recorder
    demo.send_signal(signum)
    demo.communicate(timeout=120)
    assert demo.returncode == 130
    for pid in map(int, children):
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


#: Lines a driver logs when its device vanishes before it or when it publishes after ROS shut
#: down: what a shutdown in the wrong order (emulators before nodes) leaves in the logs.
SHUTDOWN_NOISE = ("disconnected", "could not open port", "context is invalid", "callback error")


@pytest.mark.ros
def test_a_short_demo_writes_one_report_and_figure_and_shuts_down_in_order(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    # 30 s of the test pattern's standstill: the nodes start (late on a loaded machine), align
    # (10 s) and navigate.
    result = subprocess.run(
        gnss_ins_command("demo", "--duration", "30", "--output-dir", str(out)),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "ROS_DOMAIN_ID=" in result.stdout and "recording: 30 s of 30 s left" in result.stdout
    report = json.loads((out / "demo_report.json").read_text())
    for run in ("live", "replay"):  # the same errors against the truth for both runs
        assert report[run]["samples"] > 100, report[run]
        assert report[run]["horizontal_rms"] < 1.0 and report[run]["yaw_rms"] < 2.0, report[run]
    # No default outage fits a 30 s drive (the IMU may start late on a loaded machine, so
    # an outage given here could fall after its data).
    assert report["outages"] == [] and report["replay_report"]["outages"] == []
    assert "offline replay without GNSS outages" in result.stdout
    assert (out / "demo.png").read_bytes()[:4] == b"\x89PNG"
    assert not (out / "replay_report.json").exists() and not (out / "replay.png").exists()
    for spec in VEHICLE:
        log = (out / "logs" / f"{spec.name}.log").read_text()
        noise = [line for line in log.splitlines() if any(n in line for n in SHUTDOWN_NOISE)]
        assert not noise, f"{spec.name}: {noise}"
