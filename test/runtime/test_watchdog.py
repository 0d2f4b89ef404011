"""Which processes launch kills as silent (ins_fusion.runtime.watchdog), from what the status
server heard: the rules of the module docstring, and heard.json written whole."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from ins_fusion.runtime.watchdog import (
    FRESH_S,
    HEARD_FILE,
    START_GRACE_S,
    Heard,
    read_heard,
    silent,
    write_heard,
)

REPORTING = frozenset({"imu400cc_node", "ins_fusion_node", "recorder"})
SERVER = "status"
AFTER_S = 10.0


def _silent(started: dict[str, float], heard: Heard | None, now_s: float) -> dict[str, str]:
    return silent(started, REPORTING, SERVER, heard, now_s, AFTER_S)


def test_a_node_that_stopped_reporting_is_silent_and_the_others_are_not() -> None:
    heard = Heard(1000.0, 100.0, {"imu400cc_node": 999.5, "ins_fusion_node": 989.0})
    started = {"imu400cc_node": 50.0, "ins_fusion_node": 50.0, SERVER: 90.0}
    assert _silent(started, heard, 1000.2) == {
        "ins_fusion_node": "no status on /diagnostics for 11.2 s"
    }
    # Not a process that reports (the simulator, say): never judged by /diagnostics.
    assert _silent({"simulate": 0.0}, heard, 1000.2) == {}


def test_a_new_start_has_the_grace_for_its_first_status() -> None:
    # Restarted at 900 s: its statuses before that are of the run that was killed.
    heard = Heard(1000.0, 100.0, {"ins_fusion_node": 890.0})
    assert _silent({"ins_fusion_node": 900.0}, heard, 1000.0) == {}
    heard = Heard(900.0 + START_GRACE_S + 1.0, 100.0, {"ins_fusion_node": 890.0})
    found = _silent({"ins_fusion_node": 900.0}, heard, heard.written_s)
    assert found == {"ins_fusion_node": "no status on /diagnostics in 301 s since its start"}


def test_nothing_is_decided_about_the_nodes_without_a_fresh_file_or_enough_listening() -> None:
    started = {"ins_fusion_node": 0.0, SERVER: 0.0}
    old = {"ins_fusion_node": 500.0}
    assert "ins_fusion_node" not in _silent(started, None, 1000.0)
    assert "ins_fusion_node" not in _silent(started, Heard(1000.0 - FRESH_S - 0.1, 0, old), 1000)
    # A server listening for 5 s (restarted) has not heard every node yet.
    assert _silent(started, Heard(1000.0, 995.0, old), 1000.0) == {}


def test_the_server_is_silent_when_its_file_is_old_or_never_came() -> None:
    assert _silent({SERVER: 0.0}, Heard(989.0, 10.0, {}), 1000.0) == {
        SERVER: f"no {HEARD_FILE} for 11.0 s"
    }
    assert _silent({SERVER: 0.0}, None, START_GRACE_S - 1.0) == {}
    assert _silent({SERVER: 0.0}, None, START_GRACE_S + 1.0) == {
        SERVER: f"no {HEARD_FILE} for {START_GRACE_S + 1.0:.1f} s"
    }
    # A file of the server's earlier run (before its restart) does not count for this one.
    assert _silent({SERVER: 500.0}, Heard(499.0, 10.0, {}), 600.0) == {}
    # Nor one written before a reboot (monotonic time started again): as no file.
    before_reboot = Heard(90_000.0, 80_000.0, {"ins_fusion_node": 89_999.0})
    started = {SERVER: 10.0, "ins_fusion_node": 10.0}
    assert _silent(started, before_reboot, 20.0) == {}
    assert _silent(started, before_reboot, START_GRACE_S + 11.0) == {
        SERVER: f"no {HEARD_FILE} for {START_GRACE_S + 1.0:.1f} s"
    }


@given(
    last=st.dictionaries(st.sampled_from(sorted(REPORTING)), st.floats(0.0, 2000.0)),
    started=st.dictionaries(st.sampled_from(sorted(REPORTING)), st.floats(0.0, 2000.0)),
    written=st.floats(0.0, 2000.0),
    now=st.floats(0.0, 2000.0),
)
def test_a_node_heard_within_the_limit_since_its_start_is_never_killed(
    last: dict[str, float], started: dict[str, float], written: float, now: float
) -> None:
    found = _silent(started, Heard(written, 0.0, last), now)
    for name in found:
        assert name in started
        heard_since_start = last.get(name, -1.0) >= started[name]
        assert not (heard_since_start and now - last[name] <= AFTER_S)
        assert heard_since_start or now - started[name] > START_GRACE_S


def test_heard_is_written_whole_and_a_damaged_file_reads_as_none(tmp_path: Path) -> None:
    heard = Heard(12.5, 3.0, {"imu400cc_node": 12.0})
    write_heard(tmp_path, heard)
    assert read_heard(tmp_path) == heard
    assert [p.name for p in tmp_path.iterdir()] == [HEARD_FILE]
    for text in (
        "",
        "{",
        '{"written_s": 1}',
        '{"written_s": "x", "since_s": 0, "last_status_s": {}}',
    ):
        (tmp_path / HEARD_FILE).write_text(text)
        assert read_heard(tmp_path) is None
    assert read_heard(tmp_path / "absent") is None
