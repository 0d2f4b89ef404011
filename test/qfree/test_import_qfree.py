"""Q-Free OBU log parsing (ins_fusion.qfree) and ``gnss_ins import-qfree`` on fixture logs.

The fixtures (test/fixtures/qfree/README.md) follow the layouts of
shared/reference/gnss-ins-ntnu-notes.md §4 and plant bad lines and a 16-bit gyro wrap.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.paths import FIXTURES

from gnss_ins_common.navsat import CovarianceType, NavSatStatus
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.qfree import checks, logs, mems_conversion
from ins_fusion.tools.cli import main

FIXTURES = FIXTURES / "qfree"
GNSS = FIXTURES / "Rosenborg-test-pos-2.txt"
MEMS = FIXTURES / "Rosenborg-test-mems-2.txt"
REFERENCE = FIXTURES / "Rosenborg-test-pos-6.txt"
T0 = 1_377_511_200_000_000_000  # 2013-08-26T10:00:00Z
G0 = 9.80665


def gnss_line(**overrides: str) -> str:
    """A valid 35-column line; overrides by column name."""
    values = {c.name: "1" for c in logs.GNSS_COLUMNS}
    values.update(date="2013-08-26", time="10:00:00.000", latitude="63.4", longitude="10.4")
    values.update(overrides)
    return " ".join(values[c.name] for c in logs.GNSS_COLUMNS)


def import_fixtures(tmp_path: Path, *extra: str) -> tuple[int, Path]:
    bag = tmp_path / "bag"
    argv = ["import-qfree", "--gnss", str(GNSS), "--mems", str(MEMS), "-o", str(bag), *extra]
    return main(argv), bag


def read(bag: Path) -> dict[str, list]:
    out: dict[str, list] = {}
    with BagReader(bag) as reader:
        for msg in reader.messages(deserialize=True):
            out.setdefault(msg.topic, []).append((msg.log_time_ns, msg.message))
    return out


# ------------------------------------------------------------------------------------ parsing


def test_layouts_have_the_documented_columns():
    assert len(logs.GNSS_COLUMNS) == 35 and len(logs.MEMS_COLUMNS) == 14
    names = [c.name for c in logs.GNSS_COLUMNS]
    # 1-based column numbers of appendix 6.1 / 6.2
    assert names.index("latitude") + 1 == 11
    assert names.index("height_ellipsoid") + 1 == 13
    assert names.index("std_north") + 1 == 22
    assert names.index("vel_north") + 1 == 27
    assert names.index("sbas_active") + 1 == 32
    assert [c.name for c in logs.MEMS_COLUMNS][8:] == [
        "accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"
    ]  # fmt: skip


def test_unit_conversions_d2():
    assert 1000 * mems_conversion.ACCEL_UNITS["mg"] == pytest.approx(9.80665)
    assert 1000 * mems_conversion.GYRO_UNITS["mdps"] == pytest.approx(0.0174533, abs=1e-7)
    half_period = mems_conversion.GYRO_WRAP_PERIOD_RAD_S / 2
    assert half_period == pytest.approx(0.5719, abs=1e-4)


def test_utc_time_is_exact_to_the_nanosecond():
    assert logs.utc_ns("2013-08-26", "10:00:00.000") == T0
    assert logs.utc_ns("2013-08-26", "10:00:01.25") == T0 + 1_250_000_000
    assert logs.utc_ns("2013-08-26", "23:59:59.999999999") == T0 + (14 * 3600 - 1) * 10**9 + (
        10**9 - 1
    )
    for date, clock in [("2013-13-01", "10:00:00"), ("2013-08-26", "24:00:00"), ("x", "1:2:3")]:
        with pytest.raises(logs.LineError):
            logs.utc_ns(date, clock)


def test_fields_split_on_commas_semicolons_or_whitespace():
    assert logs.split_fields(" 1  2\t3 ") == ["1", "2", "3"]
    assert logs.split_fields("1, 2,,3") == ["1", "2", "", "3"]
    assert logs.split_fields("1;2; 3") == ["1", "2", "3"]


def test_gnss_line_fields_units_and_quality():
    epoch = logs.parse_gnss_line(GNSS.read_text().splitlines()[1], "pos", 2)
    assert (epoch.stamp.equipment_id, epoch.stamp.utc_ns, epoch.stamp.line) == (2, T0, 2)
    assert epoch.stamp.obu_time_s == 5000.0 and epoch.stamp.gps_week == 1759
    assert (epoch.latitude_deg, epoch.longitude_deg, epoch.height_m) == (63.4195, 10.402, 50.0)
    assert epoch.good and not epoch.sbas
    assert epoch.vel_enu_m_s == (2.0, 1.0, 0.1)  # (v_E, v_N, -v_D)
    covariance, kind = epoch.position_covariance_enu_m2
    assert kind == CovarianceType.DIAGONAL_KNOWN and epoch.status == NavSatStatus.FIX
    np.testing.assert_allclose(np.reshape(covariance, (3, 3)), np.diag([0.36, 0.64, 2.25]))


def test_missing_optional_values_mean_no_velocity_and_default_covariance():
    epoch = logs.parse_gnss_line(
        gnss_line(vel_north="nan", vel_east="nan", vel_down="nan", std_north="-")
    )
    assert epoch.vel_enu_m_s is None  # E6 data: "no velocity", not zeros (D1)
    covariance, kind = epoch.position_covariance_enu_m2
    assert kind == CovarianceType.APPROXIMATED
    assert covariance[0] == covariance[4] == covariance[8] == 36.0
    comma = logs.parse_gnss_line(",".join(gnss_line(vel_east="").split(" ")))
    assert comma.vel_enu_m_s is None


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        (gnss_line()[:-2], "expected 35 columns, got 34"),
        (gnss_line(latitude="north"), "column 11 (latitude): 'north' is not a number"),
        (gnss_line(latitude="nan"), "column 11 (latitude) is missing"),
        (gnss_line(latitude="91"), "out of range"),
        (gnss_line(good="2"), "column 9 (good)"),
        (gnss_line(equipment_id="2.5"), "integers"),
        (gnss_line(time="10:61:00"), "bad UTC"),
    ],
)
def test_bad_gnss_lines_say_why(line: str, reason: str):
    with pytest.raises(logs.LineError, match=reason.replace("(", r"\(").replace(")", r"\)")):
        logs.parse_gnss_line(line)


def test_logs_collect_bad_lines_with_numbers_and_skip_comments():
    log = logs.parse_gnss(GNSS.read_text().splitlines(), "pos-2")
    assert len(log.records) == 10 and log.skipped == 2  # header comment, blank line
    assert [(b.source, b.line) for b in log.bad_lines] == [
        ("pos-2", 5),
        ("pos-2", 8),
        ("pos-2", 12),
    ]
    mems = logs.parse_mems(MEMS.read_text().splitlines(), "mems-2")
    assert len(mems.records) == 150
    assert [str(b) for b in mems.bad_lines] == [
        "mems-2:41: expected 14 columns, got 13",
        "mems-2:81: column 10 (accel_y): 'abc' is not a number",
        "mems-2:121: column 14 (gyro_z) is missing",
    ]


column_value = st.floats(-1e6, 1e6, allow_nan=False).map(repr)


@given(st.lists(column_value, min_size=27, max_size=27), st.integers(0, 86399))
def test_any_well_formed_gnss_line_parses_back_exactly(values: list[str], second: int):
    names = [c.name for c in logs.GNSS_COLUMNS[8:]]
    fields = dict(zip(names, values, strict=True))
    fields.update(good="1", latitude=repr(float(values[2]) % 90), longitude="-0.5")
    clock = f"{second // 3600:02d}:{second // 60 % 60:02d}:{second % 60:02d}.125"
    epoch = logs.parse_gnss_line(gnss_line(time=clock, **fields))
    assert epoch.stamp.utc_ns == T0 - 10 * 3600 * 10**9 + second * 10**9 + 125_000_000
    assert epoch.latitude_deg == float(fields["latitude"])
    assert epoch.height_m == float(values[4])
    assert epoch.vel_ned_m_s == tuple(float(v) for v in values[18:21])


@given(st.text(max_size=300))
def test_garbage_never_raises_anything_but_a_reported_bad_line(text: str):
    lines = text.splitlines()
    for log in (logs.parse_gnss(lines, "g"), logs.parse_mems(lines, "m")):
        assert len(log.records) + len(log.bad_lines) + log.skipped == len(lines)


# ------------------------------------------------------------------------- MEMS conversion


def test_ramp_through_the_16_bit_wrap_is_detected_at_0_572_rad_s_and_undone():
    true_rad_s = np.linspace(0.0, 1.0, 501)  # 10 s at 50 Hz
    mdps = np.degrees(true_rad_s) * 1000
    logged = (np.round(mdps).astype(np.int64) + 32768) % 65536 - 32768  # int16 wrap
    samples = [
        logs.MemsSample(
            logs.Stamp("ramp", k + 1, 2, 1, 1, T0 + k * 20_000_000, 0, 0, 0),
            (0.0, 0.0, 1000.0),
            (0.0, 0.0, float(v)),
        )
        for k, v in enumerate(logged)
    ]
    series = mems_conversion.imu_series(samples)
    assert [(w.line, w.axis) for w in series.wraps] == [(int(np.argmax(mdps > 32767.5)) + 1, "z")]
    assert true_rad_s[series.wraps[0].line - 1] == pytest.approx(0.572, abs=0.002)
    np.testing.assert_allclose(series.rate_rad_s[:, 2], true_rad_s, atol=1e-5)
    kept = mems_conversion.imu_series(samples, unwrap=False)
    assert len(kept.wraps) == 1 and kept.rate_rad_s[-1, 2] < 0  # wrong sign, as logged


def test_unwrapping_restarts_after_a_time_gap():
    stamps = [0, 20, 40, 2040, 2060]  # ms: a 2 s gap (power cycle) before the 4th sample
    rates = [32000.0, 32500.0, 32700.0, -30000.0, -30100.0]
    samples = [
        logs.MemsSample(logs.Stamp("g", k, 2, 1, 1, T0 + ms * 10**6, 0, 0, 0), (0, 0, 0), (r, 0, 0))
        for k, (ms, r) in enumerate(zip(stamps, rates, strict=True))
    ]
    series = mems_conversion.imu_series(
        samples, gyro=mems_conversion.SensorTransform("mdps", np.eye(3))
    )
    assert series.wraps == []
    np.testing.assert_allclose(series.rate_rad_s[:, 0], np.radians(np.array(rates) / 1000))


def test_mounting_rotation_is_proper_and_rotates_vectors_and_covariances():
    rot = mems_conversion.mounting_rotation(-1.04, 25.10, 180.0)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    np.testing.assert_allclose(
        mems_conversion.mounting_rotation(0, 0, 90) @ [1, 0, 0], [0, 1, 0], atol=1e-12
    )
    np.testing.assert_allclose(
        mems_conversion.mounting_rotation(90, 0, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-12
    )
    sample = logs.MemsSample(logs.Stamp("m", 1, 2, 1, 1, T0, 0, 0, 0), (1000, 0, 0), (0, 0, 500))
    series = mems_conversion.imu_series(
        [sample],
        accel=mems_conversion.SensorTransform.mounted("mg", (0, 0, 90)),
        gyro=mems_conversion.SensorTransform.mounted("dps", (0, 0, 90)),
    )
    np.testing.assert_allclose(series.accel_m_s2[0], [0, G0, 0], atol=1e-12)
    np.testing.assert_allclose(series.rate_rad_s[0], [0, 0, math.radians(500)])
    variances = series.accel_variance_m2_s4
    np.testing.assert_allclose(variances, [2.189e-4, 1.877e-4, 3.517e-4])  # x, y swapped


def test_thesis_preset_reproduces_its_program_lines():
    """NTNU notes §5 (thesis appendix 6.5), with (2.1)-(2.3) as printed and orientation =
    [0, 0.438057067391664, -0.01816728115647]:
    fis_b = Rz(pi)*Ry(o2)*Rx(o3) * 0.97396*9.82171*acc/1000 and
    ois_b = deg2rad(Rz(0)*Ry(o2)*Rx(-o3) * (-gyro/1000)), b = x forward, y right, z down;
    imu_link is FLU. The IMU stamps are 1.24 s later (62 samples at 50 Hz)."""

    def rx(a):
        return np.array([[1, 0, 0], [0, math.cos(a), math.sin(a)], [0, -math.sin(a), math.cos(a)]])

    def ry(b):
        return np.array([[math.cos(b), 0, -math.sin(b)], [0, 1, 0], [math.sin(b), 0, math.cos(b)]])

    def rz(g):
        return np.array([[math.cos(g), math.sin(g), 0], [-math.sin(g), math.cos(g), 0], [0, 0, 1]])

    o2, o3 = 0.438057067391664, -0.01816728115647
    acc, gyro = np.array([-123.0, 45.0, 987.0]), np.array([1500.0, -700.0, 2500.0])
    fis_b = rz(math.pi) @ ry(o2) @ rx(o3) @ (0.97396 * 9.82171 * acc / 1000)
    ois_b = np.radians(rz(0) @ ry(o2) @ rx(-o3) @ (-gyro / 1000))
    sample = logs.MemsSample(logs.Stamp("t", 1, 2, 1, 1, T0, 0, 0, 0), tuple(acc), tuple(gyro))
    accel_t, gyro_t = mems_conversion.thesis_transforms()
    series = mems_conversion.imu_series(
        [sample], accel=accel_t, gyro=gyro_t, time_shift_s=mems_conversion.THESIS_LATENCY_S
    )
    frd = np.array([1.0, -1.0, -1.0])
    np.testing.assert_allclose(series.accel_m_s2[0] * frd, fis_b, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(series.rate_rad_s[0] * frd, ois_b, rtol=1e-14, atol=1e-14)
    assert series.utc_ns[0] - T0 == 1_240_000_000
    # 1000 mg reads 0.97396 * 9.82171 = 9.5659... m/s²; the gyro's matrix is a reflection
    z = mems_conversion.imu_series(
        [logs.MemsSample(sample.stamp, (0, 0, 1000), (0, 0, 0))], accel=accel_t
    )
    assert np.linalg.norm(z.accel_m_s2[0]) == pytest.approx(0.97396 * 9.82171, rel=1e-14)
    assert np.linalg.det(accel_t.matrix) == pytest.approx(1.0)
    assert np.linalg.det(gyro_t.matrix) == pytest.approx(-1.0)


# ---------------------------------------------------------------------------- import tool


def test_import_writes_the_documented_topics(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    code, bag = import_fixtures(tmp_path, "--reference", str(REFERENCE))
    out, err = capsys.readouterr()
    assert code == 0
    msgs = read(bag)
    assert {t: len(m) for t, m in msgs.items()} == {
        "/gnss/fix": 10,
        "/gnss/vel": 8,  # epoch 5 is bad, epoch 8 has no velocity
        "/imu/data_raw": 150,
        "/ground_truth/fix": 10,
        "/ground_truth/vel": 10,
    }
    # every bad line reported with file and line number, and counted in the summary
    for where in [f"{GNSS}:5:", f"{GNSS}:8:", f"{GNSS}:12:", f"{MEMS}:41:", f"{MEMS}:81:"]:
        assert where in err
    assert f"{MEMS}:121: column 14 (gyro_z) is missing" in err
    assert "bad lines: 6" in out and "/imu/data_raw" in out and "largest gaps" in out
    # the wrap: reported with its lines, undone
    assert f"gyro wrap: {MEMS}:90: gyro z 32533 -> -32469" in err
    assert f"{MEMS}:112:" in err and "2 jumps (x 0, y 0, z 2), undone" in out

    fixes = msgs["/gnss/fix"]
    status = [m.status.status for _, m in fixes]
    assert status == [0, 0, 0, 0, 0, -1, 1, 0, 0, 0]  # epoch 5 bad, epoch 6 SBAS
    assert {m.status.service for _, m in fixes} == {1}
    t, first = fixes[0]
    assert t == T0 and (first.header.stamp.sec, first.header.stamp.nanosec) == (T0 // 10**9, 0)
    assert first.header.frame_id == "gnss_link"
    assert (first.latitude, first.longitude, first.altitude) == (63.4195, 10.402, 50.0)
    np.testing.assert_allclose(first.position_covariance, np.diag([0.36, 0.64, 2.25]).ravel())
    assert first.position_covariance_type == 2
    assert fixes[3][1].position_covariance_type == 1 and fixes[3][1].position_covariance[0] == 36.0

    t, vel = msgs["/gnss/vel"][0]
    linear = vel.twist.twist.linear
    assert t == T0 and (linear.x, linear.y, linear.z) == (2.0, 1.0, 0.1)
    covariance = vel.twist.covariance.reshape(6, 6)
    np.testing.assert_allclose(np.diag(covariance), [0.43**2] * 3 + [1e6] * 3)
    assert [t for t, _ in msgs["/gnss/vel"]] == [T0 + k * 10**9 for k in (0, 1, 2, 3, 4, 6, 7, 9)]

    times = [t for t, _ in msgs["/imu/data_raw"]]
    assert times == [T0 + k * 20_000_000 for k in range(150)]
    imu = msgs["/imu/data_raw"][0][1]
    assert imu.header.frame_id == "imu_link" and imu.orientation_covariance[0] == -1.0
    accel = imu.linear_acceleration
    np.testing.assert_allclose([accel.x, accel.y, accel.z], [0.012 * G0, -0.007 * G0, G0])
    rate = imu.angular_velocity
    np.testing.assert_allclose([rate.x, rate.y], np.radians([0.010, -0.020]))
    np.testing.assert_allclose(
        np.diag(imu.angular_velocity_covariance.reshape(3, 3)),
        mems_conversion.GYRO_VARIANCE_RAD2_S2,
    )
    rate_z = np.array([m.angular_velocity.z for _, m in msgs["/imu/data_raw"]])
    assert rate_z.max() == pytest.approx(math.radians(40.0), rel=1e-4)  # above the 16-bit limit
    assert np.abs(np.diff(rate_z)).max() < math.radians(1.0)  # continuous: the wrap is undone

    truth = msgs["/ground_truth/fix"][2][1]
    assert truth.header.frame_id == "base_link" and truth.position_covariance[0] == pytest.approx(
        0.0004
    )


def _in_g(line: str) -> str:
    """A MEMS line with its accelerations (columns 9-11) from mg to g; others unchanged."""
    fields = line.split()
    try:
        fields[8:11] = [f"{float(v) / 1000:g}" for v in fields[8:11]]
    except ValueError:  # a comment or a deliberately bad line
        return line
    return " ".join(fields)


def test_import_options_units_mounting_wrap_storage(tmp_path: Path):
    in_g = tmp_path / "mems_g.txt"  # the MEMS fixture with its accelerations in g
    in_g.write_text("\n".join(_in_g(line) for line in MEMS.read_text().splitlines()))
    code, bag = import_fixtures(
        tmp_path, "--mems", str(in_g),
        "--accel-unit", "g", "--mounting", "0,0,90", "--keep-gyro-wrap", "--storage", "sqlite3",
    )  # fmt: skip
    assert code == 0 and next(bag.glob("*.db3"))
    msgs = read(bag)
    assert "/ground_truth/fix" not in msgs
    accel = msgs["/imu/data_raw"][0][1].linear_acceleration
    np.testing.assert_allclose([accel.x, accel.y, accel.z], [0.007 * G0, 0.012 * G0, 1.0 * G0])
    rate_z = np.array([m.angular_velocity.z for _, m in msgs["/imu/data_raw"]])
    assert rate_z.min() < -0.5  # the wrapped values were kept


def test_per_sensor_mountings_preset_and_time_shift(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    plain = read(import_fixtures(tmp_path / "plain")[1])["/imu/data_raw"]
    code, bag = import_fixtures(
        tmp_path / "split", "--accel-mounting", "0,0,90", "--gyro-mounting", "0,0,180",
        "--time-shift", "0.5",
    )  # fmt: skip
    assert code == 0
    split = read(bag)["/imu/data_raw"]
    assert split[0][0] - plain[0][0] == 500_000_000
    a, b = plain[0][1], split[0][1]
    f0, f1 = a.linear_acceleration, b.linear_acceleration
    np.testing.assert_allclose([f1.x, f1.y, f1.z], [-f0.y, f0.x, f0.z], atol=1e-12)
    w0, w1 = a.angular_velocity, b.angular_velocity
    np.testing.assert_allclose([w1.x, w1.y, w1.z], [-w0.x, -w0.y, w0.z], atol=1e-12)
    code, bag = import_fixtures(tmp_path / "thesis", "--preset", "thesis")
    assert code == 0 and "MEMS stamps shifted by +1.24 s" in capsys.readouterr().out
    assert read(bag)["/imu/data_raw"][0][0] - plain[0][0] == 1_240_000_000
    code, _ = import_fixtures(tmp_path / "both", "--preset", "thesis", "--mounting", "0,0,90")
    assert code == 2 and "not with --mounting" in capsys.readouterr().err


def test_equipment_filter_and_failures(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    assert import_fixtures(tmp_path, "--equipment", "9")[0] == 1  # nothing from receiver 9
    assert "no valid GNSS epoch or MEMS sample" in capsys.readouterr().err
    missing = main(
        ["import-qfree", "--gnss", "nope.txt", "--mems", str(MEMS), "-o", str(tmp_path / "b")]
    )
    assert missing == 2 and "nope.txt" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        import_fixtures(tmp_path, "--mounting", "1,2")


def _mems_line(time: str, accel_z: str = "1000", gyro_x: str = "10") -> str:
    return f"2 1 1 2013-08-26 {time} 1759 0 0 12 -7 {accel_z} {gyro_x} -20 0"


def test_implausible_values_and_time_faults_are_refused_listed_and_counted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    mems = tmp_path / "mems.txt"
    mems.write_text(
        "\n".join(
            [
                _mems_line("10:00:00.000"),
                _mems_line("10:00:00.020", accel_z="1e308"),  # beyond the ±8 g of the sensor
                _mems_line("10:00:00.040", gyro_x="-2500000"),  # beyond ±2000 deg/s
                _mems_line("10:00:00.060"),
                _mems_line("10:00:00.010"),  # back in time
                _mems_line("10:00:00.060"),  # a repeat
                _mems_line("10:00:00.080"),
            ]
        )
    )
    gnss = tmp_path / "gnss.txt"
    gnss.write_text(
        "\n".join(
            [
                gnss_line(equipment_id="2", time="10:00:00.000"),
                gnss_line(equipment_id="2", time="10:00:01.000", height_ellipsoid="1e308"),
                gnss_line(equipment_id="2", time="09:59:59.500"),
                gnss_line(equipment_id="2", time="10:00:02.000"),
            ]
        )
    )
    bag = tmp_path / "bag"
    assert main(["import-qfree", "--gnss", str(gnss), "--mems", str(mems), "-o", str(bag)]) == 0
    out, err = capsys.readouterr()
    assert f"implausible value: {mems}:2: accelerometer value 1e+308 mg beyond ±8 g" in err
    assert f"implausible value: {mems}:3: gyro value -2.5e+06 mdps beyond ±2000 deg/s" in err
    assert f"time order: {mems}:5: time goes back 0.05 s from the time of line 4" in err
    assert f"time order: {mems}:6: time repeats the time of line 4" in err
    assert f"implausible value: {gnss}:2: height 1e+308 m outside" in err
    assert f"time order: {gnss}:3: time goes back 0.5 s from the time of line 1" in err
    assert "refused: 3 lines with implausible values, 3 lines at or before the time" in out
    msgs = read(bag)
    imu_times = [t for t, _ in msgs["/imu/data_raw"]]
    assert imu_times == [T0, T0 + 60_000_000, T0 + 80_000_000]
    assert [t for t, _ in msgs["/gnss/fix"]] == [T0, T0 + 2_000_000_000]
    assert all(abs(m.linear_acceleration.z) < 80 for _, m in msgs["/imu/data_raw"])


@pytest.mark.parametrize(
    ("overrides", "reason"),
    [
        ({"vel_north": "600"}, "velocity component 600 m/s"),
        ({"std_east": "1e6"}, "position sigma 1e+06 m"),
        ({"std_east": "-1"}, "position sigma -1 m"),
        ({"height_ellipsoid": "-5000"}, "height -5000 m"),
    ],
)
def test_implausible_gnss_values_say_why(overrides: dict[str, str], reason: str):
    epoch = logs.parse_gnss_line(gnss_line(**overrides))
    assert reason in (checks.gnss_problem(epoch) or "")
    assert checks.gnss_problem(logs.parse_gnss_line(gnss_line())) is None
