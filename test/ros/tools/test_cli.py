"""The gnss_ins tool: every registered sub-command imports and explains itself, with every
option's default in its --help."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ins_fusion.tools.cli import (
    GROUPS,
    SUBCOMMANDS,
    DefaultsHelpFormatter,
    build_parser,
    main,
)

GNSS_INS = Path(sys.executable).parent / "gnss_ins"


def test_every_sub_command_is_in_one_group_of_the_help():
    grouped = [name for names in GROUPS.values() for name in names]
    assert sorted(grouped) == sorted(SUBCOMMANDS)  # each once


def test_top_level_help_lists_every_sub_command():
    result = subprocess.run([GNSS_INS, "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    for name in SUBCOMMANDS:
        assert name in result.stdout


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_sub_command_help(name, capsys):
    """In this process (the console script's own process is tested above): the sub-command's
    module imports, adds its options and prints its help."""
    with pytest.raises(SystemExit) as exited:
        main([name, "--help"])
    out, err = capsys.readouterr()
    assert exited.value.code == 0, err
    assert f"usage: gnss_ins {name}" in out


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_every_option_with_a_default_explains_it_once(name):
    parser = build_parser(name)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    formatter = DefaultsHelpFormatter(name)
    for action in sub.choices[name]._actions:
        if not action.option_strings or action.help == argparse.SUPPRESS:
            continue
        text = formatter._get_help_string(action)
        assert action.help, f"{name} {action.option_strings[-1]}: no help text"
        default = action.default
        unset = default is None or default is False or default in ([], (), argparse.SUPPRESS)
        if not unset:
            shown = text.replace("%(default)s", "")
            assert shown.count("default") == 1, f"{name} {action.option_strings[-1]}: {text!r}"


def test_help_shows_zero_defaults_and_hides_empty_ones():
    parser = argparse.ArgumentParser(formatter_class=DefaultsHelpFormatter)
    parser.add_argument("--seed", type=int, default=0, help="seed")
    parser.add_argument("--extra", nargs="*", default=(), help="extras")
    text = parser.format_help()
    assert "seed (default: 0)" in text and "extras\n" in text


def test_unknown_sub_command_is_refused():
    result = subprocess.run([GNSS_INS, "fly"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert "invalid choice" in result.stderr


@pytest.mark.ros
def test_imu_demo_runs_the_node_on_an_emulated_device():
    """Its rclpy half (ins_fusion/tools/ros_imu_demo.py) in a process of its own."""
    result = subprocess.run(
        [GNSS_INS, "imu-demo", "--duration", "3", "--every", "1000"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "imu/data_raw  t=" in result.stdout and "Imu messages over" in result.stdout
    assert "mean specific force (FLU)" in result.stdout


@pytest.mark.parametrize(
    ("name", "before", "after"),
    [("replay", None, "1"), ("replay", "2", "2"), ("allan", None, None)],
)
def test_replay_runs_blas_single_threaded_unless_the_user_says(name, before, after, monkeypatch):
    """`gnss_ins replay` sets OPENBLAS_NUM_THREADS=1 before numpy loads, a user's value
    stands, and other sub-commands leave it alone."""
    environment = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if before is not None:
        environment["OPENBLAS_NUM_THREADS"] = before
    monkeypatch.setattr(os, "environ", environment)
    with pytest.raises(SystemExit):
        main([name, "--help"])
    assert environment.get("OPENBLAS_NUM_THREADS") == after
