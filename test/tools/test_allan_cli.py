"""`gnss_ins allan` end to end on small simulated static bags, and its refusals (exit status 2).

The main bag: 300 s of a resting IMU400CC (the simulator's band-limited imu400cc profile) at the
driver's 134 Hz, imu/data_raw as the driver publishes it: enough for white noise, far too short
for bias instability (hours). The other bags are 50 Hz and short to stay fast.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gnss_ins_common.message_fields import fill_temperature
from gnss_ins_common.params import load_yaml
from ins_fusion.bags.bag_io import BagWriter
from ins_fusion.bags.messages import new_message
from ins_fusion.core.nav.units import deg_s
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.noise_id.synthetic import static_record, write_static_bag
from ins_fusion.sim.imu_model import PROFILES
from ins_fusion.tools import cli

IMU400CC = PROFILES["imu400cc"]


def _allan(capsys, *argv):
    """(exit status, stdout, stderr) of ``gnss_ins allan ARGV``."""
    try:
        code = cli.main(["allan", *map(str, argv)])
    except SystemExit as exc:  # argparse refusals
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("allan") / "static"
    write_static_bag(path, static_record(IMU400CC, 300.0, seed=4, band_limited=True))
    return path


def test_white_noise_from_a_static_bag(bag, tmp_path, capsys):
    output, plot = tmp_path / "noise.yaml", tmp_path / "allan.png"
    code, out, err = _allan(capsys, bag, "--terms", "white", "-o", output, "--plot", plot)
    assert code == 0, err
    assert "134.000 Hz" in out and "ARW N (-1/2 at 1 s)" in out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    loaded = load_yaml(output, "ins_fusion_node", PARAMETERS)
    # The profile's densities (Aalborg (7.14) σ through (5.21)); 300 s reads them within 10 %.
    assert loaded["imu_noise.gyro_arw"] == pytest.approx([2.82, 2.75, 3.30], rel=0.10)
    assert loaded["imu_noise.accel_vrw"] == pytest.approx([0.0201, 0.0263, 0.0249], rel=0.10)
    text = output.read_text()
    assert f"# source: bag {bag}, topic /imu/data_raw" in text
    assert "# record: 300.0 s, 40200 samples at 134.000 Hz (0 missing)" in text


def test_strict_terms_refuse_a_bias_the_record_does_not_pin(bag, tmp_path, capsys):
    output = tmp_path / "noise.yaml"
    code, out, err = _allan(capsys, bag, "--terms", "white,bias", "-o", output)
    assert code == 2
    assert "ARW N" in out  # the table is printed all the same
    assert "does not give the requested terms (white, bias)" in err
    assert "bias instability" in err and "no parameter file written" in err
    assert not output.exists()


@pytest.fixture(scope="module")
def bag_40_min(tmp_path_factory):
    path = tmp_path_factory.mktemp("allan") / "static40"
    write_static_bag(path, static_record(IMU400CC, 2400.0, seed=10, band_limited=True))
    return path


def test_a_40_min_record_gives_a_provisional_bias(bag_40_min, tmp_path, capsys):
    """Issue 14: a user's 40 min static record writes a noise file: white noise within 5 %, the
    bias instability within a factor 2 of the simulated unit's, marked provisional, with the
    record length that would pin it."""
    output = tmp_path / "noise.yaml"
    code, out, err = _allan(capsys, bag_40_min, "-o", output)
    assert code == 0, err
    loaded = load_yaml(output, "ins_fusion_node", PARAMETERS)
    # Where the table is printed: the values written and why they are not the table's.
    assert f"{output}: bias instability written for the node: the PROVISIONAL values" in out
    for name in ("gyro_bias_instability", "accel_bias_instability"):
        written = ", ".join(map(str, loaded[f"imu_noise.{name}"]))
        assert f"  {name} [" in out and f"] {written}\n" in out
    assert f"  bias_correlation_time [s] {loaded['imu_noise.bias_correlation_time']}" in out
    assert loaded["imu_noise.gyro_arw"] == pytest.approx([2.82, 2.75, 3.30], rel=0.05)
    assert loaded["imu_noise.accel_vrw"] == pytest.approx([0.0201, 0.0263, 0.0249], rel=0.05)
    gyro = np.array(loaded["imu_noise.gyro_bias_instability"]) / [10.8, 6.84, 18.4]  # deg/h
    accel = np.array(loaded["imu_noise.accel_bias_instability"]) / 0.4  # mg
    assert np.all((np.concatenate([gyro, accel]) > 0.5) & (np.concatenate([gyro, accel]) < 2.0))
    # T: the hump of the longest cluster time the record gives (480 s / 1.89).
    assert loaded["imu_noise.bias_correlation_time"] == pytest.approx(254.0, rel=0.01)
    text = output.read_text()
    assert "# PROVISIONAL bias instability: this record does not pin it on 6 axes" in text
    assert text.count("; PROVISIONAL (above)") == 3
    for name in ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z"):
        assert f"warning: {name}: B " in err
    assert err.count("of record would pin it") == 6


def test_missing_topic_wrong_type_and_bad_bag_are_refused(bag, tmp_path, capsys):
    code, _, err = _allan(capsys, bag, "--topic", "/imu/raw")
    assert code == 2 and "no topic /imu/raw (Imu topics: /imu/data_raw)" in err
    other = tmp_path / "temperature"
    with BagWriter(other) as writer:
        message = fill_temperature(new_message("sensor_msgs/msg/Temperature"), 1, "imu_link", 25, 0)
        writer.write("/imu/temperature", 1, message)
    code, _, err = _allan(capsys, other, "--topic", "/imu/temperature")
    assert code == 2 and "is sensor_msgs/msg/Temperature, not sensor_msgs/msg/Imu" in err
    code, _, err = _allan(capsys, tmp_path / "nothing")
    assert code == 2 and "no such bag" in err
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a bag")
    code, _, err = _allan(capsys, junk)
    assert code == 2 and "error" in err


def test_short_and_moving_records_are_refused(tmp_path, capsys):
    short = tmp_path / "short"
    write_static_bag(short, static_record(IMU400CC, 60.0, rate_hz=50.0, seed=5))
    code, _, err = _allan(capsys, short, "--terms", "white")
    assert code == 2 and "too short: the record is 60.0 s" in err and "≥ 133 s" in err

    resting = static_record(IMU400CC, 200.0, rate_hz=50.0, seed=6)
    rates = resting.rate_flu_rad_s.copy()
    rates[(resting.t_s >= 100.0) & (resting.t_s < 103.0), 0] += deg_s(10.0)
    moved = tmp_path / "moved"
    write_static_bag(moved, replace(resting, rate_flu_rad_s=rates))
    code, _, err = _allan(capsys, moved, "--terms", "white")
    assert code == 2 and "not static: gyro x moves 3" in err
    code, _, err = _allan(capsys, moved, "--terms", "white", "--max-rate-change", "5")
    assert code == 0, err


def test_bad_options_are_refused(bag, capsys):
    for argv in (["--terms", "white,drift"], ["--confidence", "1.5"], ["--max-accel-change", "0"]):
        code, _, err = _allan(capsys, bag, *argv)
        assert code == 2 and "error: argument" in err


def test_record_with_dropped_samples_is_joined(tmp_path, capsys):
    resting = static_record(IMU400CC, 200.0, rate_hz=50.0, seed=7)
    keep = np.ones(len(resting.t_s), dtype=bool)
    keep[1000::500] = False
    gappy = tmp_path / "gappy"
    write_static_bag(
        gappy,
        replace(
            resting,
            t_s=resting.t_s[keep],
            rate_flu_rad_s=resting.rate_flu_rad_s[keep],
            force_flu_m_s2=resting.force_flu_m_s2[keep],
        ),
    )
    code, out, err = _allan(capsys, gappy, "--terms", "white")
    assert code == 0, err
    assert f"({(~keep).sum()} missing)" in out
