"""`gnss_ins batch` on eight bags: six simulated drives (60 s of the figure-eight scenario, six
seeds), the real comma2k19 segment (test/fixtures/comma2k19) and a corrupt MCAP file; on a
LocalCluster and on a `dask scheduler` with two `dask worker` processes on localhost.

Each bag's report.json must equal what `gnss_ins replay --report` writes for that bag alone
(wall times aside), the corrupt file must be in the summary with its error, a second run must
replay nothing, and a run interrupted with SIGINT must complete the rest when run again.
"""

from __future__ import annotations

import csv
import json
import signal
import socket
import subprocess
import sys
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

import psutil
import pytest
from distributed import Client
from support.paths import FIXTURES
from support.waiting import wait_for

from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.simulated_bag import write_bag
from ins_fusion.tools import cli

pytestmark = pytest.mark.slow

REAL = FIXTURES / "comma2k19" / "comma2k19_ex1_seg40"
SEEDS = (31, 32, 33, 34, 35, 36)
#: The replay options of every run: an outage in the second lap and the smoother.
OPTIONS = ("--outage", "30:10", "--smooth")
#: Report keys that are wall times, different at each run.
WALL = {"read_time_s", "fusion_time_s", "wall_time_s", "realtime_factor", "smoothing_time_s"}


def _timeless(report: dict) -> dict:
    plain = {k: v for k, v in report.items() if k not in WALL}
    if isinstance(report.get("smoothed"), dict):
        plain["smoothed"] = _timeless(report["smoothed"])
    return plain


@pytest.fixture(scope="module")
def bags(tmp_path_factory) -> dict[str, Path]:
    """name -> path of the eight bags (the simulated ones written once per module)."""
    root = tmp_path_factory.mktemp("fleet")
    found = {}
    for seed in SEEDS:
        path = root / f"sim_{seed}"
        with redirect_stdout(StringIO()):
            write_bag(SimulationConfig(scenario="figure_eight", duration_s=60.0, seed=seed), path)
        found[path.name] = path
    found[REAL.name] = REAL
    corrupt = root / "corrupt.mcap"  # a recording cut short: no MCAP footer
    corrupt.write_bytes(next((root / "sim_31").glob("*.mcap")).read_bytes()[:100_000])
    found[corrupt.name] = corrupt
    return found


@pytest.fixture(scope="module")
def singles(bags, tmp_path_factory) -> dict[str, dict]:
    """`gnss_ins replay OPTIONS --report` of each readable bag alone."""
    out = tmp_path_factory.mktemp("singles")
    reports = {}
    for name, path in bags.items():
        if name == "corrupt.mcap":
            continue
        report = out / f"{name}.json"
        with redirect_stdout(StringIO()):
            assert cli.main(["replay", str(path), *OPTIONS, "--report", str(report)]) == 0
        reports[name] = json.loads(report.read_text())
    return reports


def _batch(capsys, out: Path, *argv: str) -> tuple[int, str, str]:
    code = cli.main(["batch", *argv, "--out", str(out)])
    stdout, stderr = capsys.readouterr()
    return code, stdout, stderr


def _bag_arguments(bags: dict[str, Path]) -> list[str]:
    """The simulated bags as one glob pattern, the others by path."""
    pattern = str(bags["sim_31"].parent / "sim_*")
    return [pattern, *(str(p) for name, p in bags.items() if not name.startswith("sim_"))]


def _check_results(out: Path, bags: dict[str, Path], singles: dict[str, dict]) -> None:
    """Every readable bag's report equals its single replay; the summary lists all eight,
    the corrupt one failed with the reader's error."""
    for name, single in singles.items():
        report = json.loads((out / name / "report.json").read_text())
        assert _timeless(report) == _timeless(single), name
        assert json.loads((out / name / "outcome.json").read_text())["status"] == "ok"
    with (out / "summary.csv").open() as file:
        rows = {row["bag"]: row for row in csv.DictReader(file)}
    assert set(rows) == set(bags)
    assert rows["corrupt.mcap"]["status"] == "failed"
    assert "cannot read bag" in rows["corrupt.mcap"]["error"]
    for name in singles:
        assert rows[name]["status"] == "ok" and not rows[name]["error"]
        nees = singles[name]["nees"]["position_mean"]
        assert float(rows[name]["nees_mean"]) == pytest.approx(nees, rel=1e-12)
        assert float(rows[name]["smoothed_horizontal_rms_m"]) > 0.0
    assert (out / "summary.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.glob(".partial-*")) and not list(out.glob(".old-*"))


def _done_times(out: Path) -> dict[str, int]:
    return {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/outcome.json")}


def test_local_cluster_batch_equals_single_replays_and_a_rerun_does_nothing(
    bags, singles, tmp_path, capsys
):
    out = tmp_path / "fleet"
    argv = [*_bag_arguments(bags), *OPTIONS, "--export", "track.csv", "--workers", "2"]
    code, stdout, _ = _batch(capsys, out, *argv)
    assert code == 1  # the corrupt bag failed
    assert "8 bags: 8 to replay, 0 done" in stdout
    _check_results(out, bags, singles)
    assert "corrupt.mcap: cannot read bag" in stdout  # the printed summary names the error
    for name in singles:
        assert (out / name / "plot.png").stat().st_size > 10_000
        track = (out / name / "track.csv").read_text().splitlines()
        assert len(track) > 100, name  # a header and the smoothed epochs past alignment
    done = _done_times(out)
    assert len(done) == 8
    code, stdout, _ = _batch(capsys, out, *argv)
    assert code == 1 and "8 bags: 0 to replay, 8 done" in stdout
    assert _done_times(out) == done  # nothing replayed again
    # Other options in the same folder are refused, not mixed with these results.
    code, _, stderr = _batch(capsys, out, *_bag_arguments(bags), "--outage", "20:10")
    assert code == 2 and "other options (exports, outage, smooth)" in stderr
    assert _done_times(out) == done


def test_an_interrupted_batch_completes_when_run_again(bags, singles, tmp_path, capsys):
    out = tmp_path / "fleet"
    argv = [*_bag_arguments(bags), *OPTIONS, "--no-plot", "--workers", "1"]
    command = [sys.executable, "-m", "ins_fusion.tools.cli", "batch", *argv, "--out", str(out)]
    batch = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # As from a terminal: under `make test` this session runs as a background job, whose
        # children inherit SIGINT ignored (and Python then installs no KeyboardInterrupt).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        wait_for(lambda: bool(_done_times(out)), 120.0, poll_s=0.05)
        children = psutil.Process(batch.pid).children(recursive=True)
        batch.send_signal(signal.SIGINT)
        _, stderr = batch.communicate(timeout=60)
    finally:
        if batch.poll() is None:
            batch.kill()
    assert batch.returncode == 130, stderr
    assert "interrupted:" in stderr and "the same command replays the other" in stderr
    before = _done_times(out)
    assert 1 <= len(before) < 8
    _, alive = psutil.wait_procs(children, timeout=20)  # the local cluster's processes end
    for process in alive:
        process.kill()
    assert not alive
    code, stdout, _ = _batch(capsys, out, *argv)
    assert code == 1
    assert f"8 bags: {8 - len(before)} to replay, {len(before)} done" in stdout
    after = _done_times(out)
    assert len(after) == 8
    assert {name: after[name] for name in before} == before  # the saved bags kept
    _check_results(out, bags, singles)


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """A `dask scheduler` and two single-threaded `dask worker` processes on localhost."""
    dask = str(Path(sys.executable).parent / "dask")
    address = f"tcp://127.0.0.1:{_free_port()}"
    logs = tmp_path_factory.mktemp("dask")
    host, port = address.removeprefix("tcp://").split(":")
    commands = [[dask, "scheduler", "--host", host, "--port", port, "--no-dashboard"]]
    commands += [
        [dask, "worker", address, "--nthreads", "1", "--no-dashboard", "--name", f"w{i}"]
        for i in (1, 2)
    ]
    processes = []
    try:
        for index, command in enumerate(commands):
            log = (logs / f"{index}.log").open("w")
            processes.append(
                subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, cwd=logs)
            )
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def test_a_scheduler_with_two_workers_gives_the_same_results(
    bags, singles, scheduler, tmp_path, capsys
):
    out = tmp_path / "fleet"
    argv = [*_bag_arguments(bags), *OPTIONS, "--no-plot", "--scheduler", scheduler]
    code, stdout, _ = _batch(capsys, out, *argv)
    assert code == 1 and "8 bags: 8 to replay, 0 done" in stdout
    _check_results(out, bags, singles)
    code, stdout, _ = _batch(capsys, out, *argv)
    assert code == 1 and "8 bags: 0 to replay, 8 done" in stdout


def test_a_sweep_runs_on_the_scheduler(bags, scheduler, tmp_path, capsys):
    bag = str(bags["sim_32"])
    sweep = tmp_path / "sweep.json"
    argv = ["replay", bag, "--outage", "30:10", "--sweep", "use_nhc=true,false"]
    assert cli.main([*argv, "--scheduler", scheduler, "--report", str(sweep)]) == 0
    single = tmp_path / "single.json"
    argv = ["replay", bag, "--outage", "30:10", "--set", "use_nhc=false", "--report", str(single)]
    assert cli.main(argv) == 0
    capsys.readouterr()
    runs = {
        run["setting"]["use_nhc"]: run["report"] for run in json.loads(sweep.read_text())["runs"]
    }
    assert set(runs) == {True, False}
    assert _timeless(runs[False]) == _timeless(json.loads(single.read_text()))
    assert _timeless(runs[True]) != _timeless(runs[False])


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["{tmp}/none_*"], "matches no bag"),
        (["{tmp}/a/x", "{tmp}/b/x"], "two bags named x"),
        (["{tmp}/a/x", "--export", "report.json"], "--export report.json"),
        (["{tmp}/a/x", "--export", "x.kml"], "the suffix must be one of"),
        (["{tmp}/a/x", "--export-solution", "smoothed"], "needs --smooth"),
        (["{tmp}/a/x", "--workers", "0"], "--workers must be at least 1"),
    ],
)
def test_bad_input_is_refused_before_any_replay(argv, message, tmp_path, capsys):
    for folder in ("a", "b"):
        (tmp_path / folder / "x").mkdir(parents=True)
    argv = [arg.format(tmp=tmp_path) for arg in argv]
    code, _, stderr = _batch(capsys, tmp_path / "out", *argv)
    assert code == 2 and message in stderr, stderr
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())
