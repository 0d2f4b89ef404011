"""`gnss_ins calibrate` end to end on small simulated bags: the calibration file the fusion node
reads, the report, the figure, merging into a base file, the axes check, and bad input (exit 2
with a clear message)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from support.paths import REPO

from gnss_ins_common.axes import AxisMap
from ins_fusion.bags.imu import write_imu_bag
from ins_fusion.calibration_id import procedures
from ins_fusion.calibration_id.model import Site
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2, deg_s, mg
from ins_fusion.sim.imu_model import IMU400CC
from ins_fusion.tools.cli import main

GNSS_INS = Path(sys.executable).parent / "gnss_ins"
SITE = Site.at(57.0, 50.0)
LEVEL_DEG = 0.05
STATIC = ["--latitude", "57", "--height", "50", "--level-sigma", str(LEVEL_DEG)]
#: six positions of 15 s with 4-s turns: position k held from 19 k to 19 k + 15 s
HOLD_S, TURN_S = 15.0, 4.0


@pytest.fixture(scope="module")
def six_bag(tmp_path_factory):
    steps = procedures.six_position(HOLD_S, TURN_S, level_sigma_rad=math.radians(LEVEL_DEG))
    record, model = procedures.simulate(steps, IMU400CC, SITE, 44, name="six")
    path = tmp_path_factory.mktemp("bags") / "six"
    write_imu_bag(path, record)
    return path, record, model


@pytest.fixture(scope="module")
def rotated_unit_bag(tmp_path_factory):
    """A unit whose x and y the default axis_map swaps (mounted rotated 90° in its case)."""
    device = (AxisMap.from_spec(["y", "x", "-z"]), 1.0)
    driver = (AxisMap.from_spec(["x", "-y", "-z"]), -1.0)
    steps = procedures.six_position(HOLD_S, TURN_S)
    record, _ = procedures.simulate(steps, IMU400CC, SITE, 42, device_map=device, driver_map=driver)
    path = tmp_path_factory.mktemp("bags") / "rotated"
    write_imu_bag(path, record)
    return path


def _calibrate(*args):
    return main(["calibrate", *map(str, args)])


@pytest.fixture(scope="module")
def noise_file(tmp_path_factory):
    """The simulated unit's bias instability as ins_fusion_node parameters (--noise)."""
    path = tmp_path_factory.mktemp("noise") / "noise.yaml"
    noise = {
        "gyro_bias_instability": [math.degrees(v) * 3600 for v in IMU400CC.gyro.bias_instability],
        "accel_bias_instability": [v / mg(1.0) for v in IMU400CC.accel.bias_instability],
        "bias_correlation_time": IMU400CC.gyro.bias_correlation_time_s[0],
    }
    path.write_text(yaml.safe_dump({"ins_fusion_node": {"ros__parameters": {"imu_noise": noise}}}))
    return path


def test_six_position_writes_the_file_the_fusion_node_reads(six_bag, tmp_path, capsys):
    bag, record, model = six_bag
    out, report, plot = tmp_path / "cal.yaml", tmp_path / "report.md", tmp_path / "seg.png"
    code = _calibrate(
        "six-position",
        bag,
        *STATIC,
        "-o",
        out,
        "--report",
        report,
        "--plot",
        plot,
        "--sensor",
        "IMU400CC sn 7",
    )
    assert code == 0
    assert "accel bias [mg]" in capsys.readouterr().out
    calibration = ImuCalibration.from_yaml(out)
    section = yaml.safe_load(out.read_text())["imu_calibration"]
    assert section["sensor"] == "IMU400CC sn 7"
    assert "six-position" in section["source"]
    low, high = calibration.temperature_range_c
    assert record.temperature_c.min() - 0.1 <= low <= high <= record.temperature_c.max() + 0.1
    for triad, truth in ((calibration.accel, model.accel), (calibration.gyro, model.gyro)):
        assert np.all(np.abs(np.subtract(triad.bias, truth.bias)) < 3 * np.array(triad.bias_sigma))
    accel = calibration.accel
    for estimate, sigma, truth in (
        # one range: the six positions see ±1 g, the simulated IMU400CC's large range
        (accel.scale_positive, accel.scale_positive_sigma, model.accel.scale_large_pos),
        (accel.scale_negative, accel.scale_negative_sigma, model.accel.scale_large_neg),
    ):
        assert np.all(np.abs(np.subtract(estimate, truth)) < 3 * np.array(sigma))
    assert np.all(np.array(calibration.g_sensitivity_sigma) > 0.0)
    text = report.read_text()
    for heading in ("## Estimates", "## Segments used", "## Residuals", "![segments](seg.png)"):
        assert heading in text
    assert text.count("| static | ") == 6
    assert plot.stat().st_size > 10_000


def test_merging_into_a_base_file_keeps_its_other_terms(six_bag, tmp_path):
    bag, record, _ = six_bag
    base = REPO / "config" / "imu400cc_calibration.yaml"
    out = tmp_path / "merged.yaml"
    assert _calibrate("six-position", bag, *STATIC, "-o", out, "--base", base) == 0
    merged, original = ImuCalibration.from_yaml(out), ImuCalibration.from_yaml(base)
    assert merged.gyro.scale_positive == original.gyro.scale_positive  # D2 terms kept
    assert merged.accel.bias != original.accel.bias  # S2 terms replaced
    assert merged.sensor == original.sensor
    low, high = merged.temperature_range_c  # the base's range, widened by the data's
    assert low == min(24.0, round(record.temperature_c.min(), 2))
    assert high == max(28.0, round(record.temperature_c.max(), 2))


def test_six_positions_with_scale_ranges_give_the_large_range(six_bag, tmp_path):
    """--scale-ranges 0.6: the six positions (±1 g) give the report's S2 range (the simulated
    IMU400CC carries Fig. 5-35's ±1 g values from 0.6 g on); merged into the shipped file, whose
    ±0.2 g values (S1 mod) stay, the result is the report's two-range model."""
    bag, _, model = six_bag
    out = tmp_path / "ranges.yaml"
    base = REPO / "config" / "imu400cc_calibration.yaml"
    argv = ("-o", out, "--scale-ranges", "0.6", "--base", base)
    assert _calibrate("six-position", bag, *STATIC, *argv) == 0
    merged, original = ImuCalibration.from_yaml(out), ImuCalibration.from_yaml(base)
    assert merged.accel.large_input == pytest.approx(0.6 * STANDARD_GRAVITY_M_S2)
    assert merged.accel.scale_positive == original.accel.scale_positive
    for estimate, sigma, truth in (
        (
            merged.accel.scale_large_positive,
            merged.accel.scale_large_positive_sigma,
            model.accel.scale_large_pos,
        ),
        (
            merged.accel.scale_large_negative,
            merged.accel.scale_large_negative_sigma,
            model.accel.scale_large_neg,
        ),
    ):
        assert np.all(np.abs(np.subtract(estimate, truth)) < 3 * np.array(sigma))
    assert _calibrate("rate-table", bag, "--rate", "15", "--scale-ranges", "0.6") == 2


def test_bias_instability_from_the_fusion_parameters_widens_the_sigmas(six_bag, tmp_path):
    bag, _, _ = six_bag
    plain, noisy = tmp_path / "plain.yaml", tmp_path / "noisy.yaml"
    assert _calibrate("six-position", bag, *STATIC, "-o", plain) == 0
    noise = REPO / "config" / "ins_fusion.yaml"  # gyro bias instability 10.8, 6.84, 18.4 deg/h
    assert _calibrate("six-position", bag, *STATIC, "-o", noisy, "--noise", noise) == 0
    a, b = ImuCalibration.from_yaml(plain), ImuCalibration.from_yaml(noisy)
    assert np.all(np.array(b.gyro.bias_sigma) > np.array(a.gyro.bias_sigma))
    assert np.all(np.array(b.gyro.bias_sigma) > deg_s(6.84 / 3600.0) / 2)


def test_axes_check_exits_1_and_names_the_mapping(rotated_unit_bag, tmp_path, capsys):
    report = tmp_path / "axes.md"
    assert _calibrate("axes", rotated_unit_bag, "--report", report) == 1
    out = capsys.readouterr().out
    assert "found axis_map ['y', 'x', '-z'], accel_sign 1" in out
    assert "DISAGREE" in out
    assert "`axis_map: ['y', 'x', '-z']`" in report.read_text()


def test_axes_check_exits_0_when_the_driver_agrees(six_bag, capsys):
    bag, _, _ = six_bag
    assert _calibrate("axes", bag) == 0
    assert "agree" in capsys.readouterr().out


def _windows(*spans):
    return ",".join(f"{a}:{b}" for a, b in spans)


POSITIONS = [(19 * k + 2, 19 * k + 13) for k in range(6)]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--imu-topic", "/imu/nothing"], "no topic /imu/nothing (Imu topics: /imu/data_raw)"),
        (["--segments", _windows((2, 13), (10, 30))], "is not static or steady"),
        (["--segments", _windows((2, 13), (21, 25))], "shorter than the minimum 10 s"),
        (["--segments", _windows(*POSITIONS[:5])], "missing -y up"),
        (
            ["--segments", _windows(*POSITIONS), "--positions", "+x,-x,+y,-y,+z,-z"],
            "--positions says +x,-x,+y,-y,+z,-z but the data put +g on +z,-z,+x,-x,+y,-y",
        ),
        (["--segments", "2@2:13"], "there are 1 bags"),
    ],
)
def test_bad_input_exits_2_with_a_clear_message(six_bag, extra, message, capsys):
    bag, _, _ = six_bag
    assert _calibrate("six-position", bag, *STATIC, *extra) == 2
    assert message in capsys.readouterr().err


def test_malformed_windows_are_refused_by_the_parser(six_bag, capsys):
    bag, _, _ = six_bag
    with pytest.raises(SystemExit) as exit_info:
        _calibrate("six-position", bag, *STATIC, "--segments", "3:x")
    assert exit_info.value.code == 2
    assert "expected [BAG@]T0:T1" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["six-position"], "six-position needs --latitude"),
        (["known-attitude", "--latitude", "57"], "known-attitude needs --attitudes"),
        (["known-angle"], "known-angle needs --angle"),
        (["axes", "-o", "x.yaml"], "axes writes no calibration file"),
    ],
)
def test_missing_or_misplaced_options_exit_2(six_bag, argv, message, capsys):
    bag, _, _ = six_bag
    assert _calibrate(argv[0], bag, *argv[1:]) == 2
    assert message in capsys.readouterr().err


def test_moving_record_has_no_positions(tmp_path, capsys):
    """A unit turned over continuously: no static segment, a clear error."""
    steps = [
        procedures.Hold(procedures.up_attitude(2, 1.0), 2.0),
        procedures.Spin(np.array([1.0, 0.0, 0.0]), 6.0 * math.pi, math.radians(20.0)),
    ]
    record, _ = procedures.simulate(steps, IMU400CC, SITE, 43)
    write_imu_bag(tmp_path / "moving", record)
    assert _calibrate("six-position", tmp_path / "moving", *STATIC) == 2
    assert "no static or steady segment found" in capsys.readouterr().err


def test_console_script(six_bag, tmp_path):
    bag, _, _ = six_bag
    out = tmp_path / "cal.yaml"
    result = subprocess.run(
        [GNSS_INS, "calibrate", "six-position", bag, *STATIC, "-o", out],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert ImuCalibration.from_yaml(out).accel.bias[2] == pytest.approx(mg(7.1), abs=mg(2.0))
