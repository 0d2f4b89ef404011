"""ins_fusion.runtime.health: the system's view from the latest statuses and the supervisor."""

from __future__ import annotations

import json
from pathlib import Path

from ins_fusion.runtime.health import (
    ERROR,
    OK,
    STALE_AFTER_S,
    WARN,
    Health,
    Status,
    exit_code,
    format_view,
    write_supervisor_state,
)


def status(name: str, level: int, at: float, **values: str) -> Status:
    return Status(name, level, f"message of {name}", values, at)


def healthy(at: float) -> Health:
    health = Health()
    health.add(status("imu400cc_node: IMU400CC", OK, at, rate_hz="134", packets="9", port="x"))
    health.add(status("leica_gnss: GNSS leica", OK, at, last_fix_type="RTK_FIXED"))
    health.add(status("adu5_gnss: GNSS adu5", OK, at, last_fix_type="SPS"))
    health.add(status("ins_fusion_node: INS", OK, at, state="navigating"))
    return health


def test_all_ok_then_the_worst_level_wins():
    health = healthy(10.0)
    view = health.view(10.5)
    assert view["level"] == "OK" and exit_code(view) == 0
    assert list(view["processes"]) == [
        "imu400cc_node",
        "leica_gnss",
        "adu5_gnss",
        "ins_fusion_node",
    ]
    assert view["processes"]["imu400cc_node"]["values"] == {"rate_hz": "134", "packets": "9"}
    health.add(status("ins_fusion_node: INS", WARN, 10.6, state="degraded"))
    assert health.view(11.0)["level"] == "WARN" and exit_code(health.view(11.0)) == 1
    health.add(status("leica_gnss: GNSS leica", ERROR, 10.7))
    assert health.view(11.0)["level"] == "ERROR" and exit_code(health.view(11.0)) == 2


def test_a_silent_or_missing_process_is_stale():
    health = healthy(10.0)
    for name in ("leica_gnss", "adu5_gnss", "ins_fusion_node"):
        health.add(status(f"{name}: x", OK, 10.0 + STALE_AFTER_S))
    view = health.view(10.0 + STALE_AFTER_S + 0.1)
    imu = view["processes"]["imu400cc_node"]
    assert (view["level"], imu["level"]) == ("STALE", "STALE")
    assert imu["message"] == "silent for 3 s"
    assert exit_code(view) == 2
    assert Health().view(0.0)["processes"]["leica_gnss"]["message"] == "no status received"


def test_the_supervisor_file_names_the_expected_processes_and_their_restarts(tmp_path: Path):
    state = {
        "imu400cc_node": {"pid": 10, "restarts": 0, "running": True},
        "leica_gnss": {"pid": 11, "restarts": 3, "running": True},
        "recorder": {"pid": 12, "restarts": 1, "running": True},
        "status": {"pid": 13, "restarts": 0, "running": True},  # itself: not shown
    }
    write_supervisor_state(tmp_path, state)
    assert json.loads((tmp_path / "supervisor.json").read_text())["processes"] == state
    health = healthy(5.0)
    health.read_supervisor(tmp_path)
    health.add(status("recorder: recording", OK, 5.0, bag="/data/b", free_bytes="7"))
    # A recorder started by hand (`gnss_ins record`, node gnss_ins_record): a row of its own.
    health.add(status("gnss_ins_record: recording", WARN, 5.0, bag="/tmp/mine"))
    view = health.view(5.1)
    assert list(view["processes"]) == [
        "imu400cc_node", "leica_gnss", "recorder", "adu5_gnss", "ins_fusion_node",
        "gnss_ins_record",
    ]  # fmt: skip
    assert view["processes"]["leica_gnss"]["restarts"] == 3
    assert view["processes"]["recorder"]["values"] == {"bag": "/data/b", "free_bytes": "7"}
    assert view["processes"]["recorder"]["level"] == "OK"
    assert view["processes"]["gnss_ins_record"]["values"] == {"bag": "/tmp/mine"}
    text = format_view(view, "title")
    assert text.splitlines()[0] == "title   system: WARN"
    assert "leica_gnss" in text and "bag /data/b, free_bytes 7" in text


def test_an_unreadable_supervisor_file_changes_nothing(tmp_path: Path):
    (tmp_path / "supervisor.json").write_text("{ not json")
    health = healthy(1.0)
    health.read_supervisor(tmp_path)
    assert health.supervised == {} and health.view(1.0)["level"] == "OK"


def test_a_restarted_process_never_shows_the_status_of_the_one_before(tmp_path: Path):
    """The Leica node dies at 20 s with its last status OK (19.5 s): while it is down its row
    says so, after launch restarts it (21 s) the old status is not shown as the new process's,
    and the new one's first status (22 s) is."""
    health = healthy(19.5)

    def supervisor(running: bool, restarts: int, started_s: float) -> None:
        write_supervisor_state(
            tmp_path,
            {
                "leica_gnss": {
                    "pid": 7,
                    "restarts": restarts,
                    "running": running,
                    "started_s": started_s,
                }
            },
        )
        health.read_supervisor(tmp_path)

    supervisor(True, 0, 1.0)
    assert health.view(19.6)["processes"]["leica_gnss"]["level"] == "OK"
    supervisor(False, 0, 1.0)  # died, not yet restarted
    row = health.view(20.2)["processes"]["leica_gnss"]
    assert (row["level"], row["message"]) == ("ERROR", "not running")
    supervisor(True, 1, 21.0)
    row = health.view(21.5)["processes"]["leica_gnss"]
    assert (row["level"], row["restarts"]) == ("WARN", 1)
    assert row["message"] == "restarted 0 s ago, no status since" and row["values"] == {}
    assert health.view(21.0 + STALE_AFTER_S + 1)["processes"]["leica_gnss"]["level"] == "STALE"
    health.add(status("leica_gnss: GNSS leica", OK, 22.0, last_fix_type="RTK_FIXED"))
    row = health.view(22.1)["processes"]["leica_gnss"]
    assert (row["level"], row["values"]) == ("OK", {"last_fix_type": "RTK_FIXED"})


def test_unheard_are_the_running_processes_without_a_status_since_their_start():
    health = Health()
    assert health.unheard() == ["imu400cc_node", "leica_gnss", "adu5_gnss", "ins_fusion_node"]
    health = healthy(10.0)
    assert health.unheard() == []
    health.supervised = {
        "imu400cc_node": {"running": True, "started_s": 11.0},  # restarted after its status
        "leica_gnss": {"running": False, "started_s": 1.0},  # ended: not waited for
        "adu5_gnss": {"running": True, "started_s": 1.0},
    }
    assert health.unheard() == ["imu400cc_node"]
    health.add(status("imu400cc_node: IMU400CC", OK, 11.5))
    assert health.unheard() == []
