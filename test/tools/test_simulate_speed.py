"""`gnss_ins simulate --speed`: the odometer on /vehicle/speed (docs/simulator.md), stamped at
the middle of each counting period, in base_link, reading the wheel's true speed scaled by the
scale error; without --speed the bag is what it was."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from gnss_ins_common.message_fields import UNKNOWN_VARIANCE
from ins_fusion.bags import topics as T  # noqa: N812
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.bags.typestore import jazzy_typestore
from ins_fusion.sim.drive import DEFAULT_START_NS, Simulation, SimulationConfig
from ins_fusion.sim.odometer_model import DMI
from ins_fusion.tools import cli

DURATION_S = 20.0
#: A right turn at 60 km/h: the wheel on the left rear hub reads faster than base_link.
ARGS = ["simulate", "--scenario=aalborg_turn", f"--duration={DURATION_S:g}", "--seed=4"]
SCALE = 0.03
TS = jazzy_typestore()


def _stamp(message: Any) -> int:
    return int(message.header.stamp.sec) * 1_000_000_000 + int(message.header.stamp.nanosec)


def _read(path) -> dict[str, list[tuple[int, Any]]]:
    out: dict[str, list[tuple[int, Any]]] = {}
    with BagReader(path) as reader:
        for msg in reader.messages():
            out.setdefault(msg.topic, []).append((msg.log_time_ns, bytes(msg.message)))
    return out


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, list]]:
    root = tmp_path_factory.mktemp("speed")
    speed_args = ["--speed", f"--speed-scale={SCALE}"]
    assert cli.main([*ARGS, *speed_args, f"--output={root / 'with'}"]) == 0
    assert cli.main([*ARGS, f"--output={root / 'without'}"]) == 0
    return {"with": _read(root / "with"), "without": _read(root / "without")}


def test_speed_topic_stamps_frame_and_covariance(bags):
    speed = bags["with"][T.VEHICLE_SPEED]
    rate = DMI.rate_hz
    assert len(speed) == DURATION_S * rate - 1  # none at 0: no period counted yet
    messages = [TS.deserialize_cdr(raw, T.VELOCITY_TYPE) for _, raw in speed]
    logs = np.array([log for log, _ in speed]) - DEFAULT_START_NS
    stamps = np.array([_stamp(m) for m in messages]) - DEFAULT_START_NS
    k = np.arange(1, len(speed) + 1)
    np.testing.assert_array_equal(logs, np.rint(k / rate * 1e9))  # end of the period
    np.testing.assert_array_equal(stamps, np.rint((k - 0.5) / rate * 1e9))  # its middle
    for m in messages:
        assert m.header.frame_id == T.SPEED_FRAME == "base_link"
        assert (m.twist.twist.linear.y, m.twist.twist.linear.z) == (0.0, 0.0)
        cov = np.asarray(m.twist.covariance).reshape(6, 6)
        assert cov[0, 0] == pytest.approx(DMI.reported_sigma_m_s**2)
        assert np.all(np.diag(cov)[1:] == UNKNOWN_VARIANCE)


def test_speed_is_the_wheels_true_speed_with_the_scale_error(bags):
    messages = [
        TS.deserialize_cdr(raw, T.VELOCITY_TYPE) for _, raw in bags["with"][T.VEHICLE_SPEED]
    ]
    mid_s = (np.array([_stamp(m) for m in messages]) - DEFAULT_START_NS) / 1e9
    measured = np.array([m.twist.twist.linear.x for m in messages])
    config = SimulationConfig(scenario="aalborg_turn", duration_s=DURATION_S)
    wheel, _ = Simulation(config).vehicle.odometer(mid_s)
    error = measured - (1.0 + SCALE) * wheel
    # Quantisation (step 0.04 m/s) and 0.01 m/s noise; the mean over a period is the speed at
    # its middle to (period² / 24) × jerk: far below both.
    assert np.max(np.abs(error)) < DMI.step_m_s + 5 * DMI.noise_sigma_m_s
    assert abs(np.mean(error)) < 0.005
    assert np.std(error) == pytest.approx(DMI.reported_sigma_m_s, rel=0.3)
    # The turn shows at the wheel: it reads more than base_link's speed (right turn, left hub).
    base_speed = np.hypot(*Simulation(config).vehicle.base_link(mid_s).vel_enu_m_s[:, :2].T)
    assert np.max(wheel - base_speed) > 0.1


def test_without_speed_nothing_changes_and_the_seed_reproduces(bags, tmp_path):
    with_speed = {t: v for t, v in bags["with"].items() if t != T.VEHICLE_SPEED}
    assert with_speed == bags["without"]
    again = tmp_path / "again"
    assert cli.main([*ARGS, "--speed", f"--speed-scale={SCALE}", f"--output={again}"]) == 0
    assert _read(again) == bags["with"]
    assert set(bags["without"]) == set(T.TOPICS)


def test_speed_options(tmp_path, capsys):
    assert cli.main([*ARGS, "--speed-scale=0.01", f"--output={tmp_path / 'a'}"]) == 2
    assert "need --speed" in capsys.readouterr().err
    assert cli.main(["simulate", "--live", "--speed"]) == 2
    assert "for bags" in capsys.readouterr().err
    assert cli.main([*ARGS, "--speed", "--speed-scale=-1", f"--output={tmp_path / 'b'}"]) == 2
    assert "scale_error > -1" in capsys.readouterr().err
    path = tmp_path / "fast"
    args = [*ARGS, "--duration=3", "--speed", "--speed-rate=50", "--speed-slip-threshold=2"]
    assert cli.main([*args, f"--output={path}"]) == 0
    assert "speed dmi at 50 Hz (scale +2.00%, slip above 2 m/s²)" in capsys.readouterr().out
    assert len(_read(path)[T.VEHICLE_SPEED]) == 3 * 50 - 1
    config = SimulationConfig(duration_s=1.0, odometer=dataclasses.replace(DMI, rate_hz=10.0))
    assert Simulation(config).topics[T.VEHICLE_SPEED] == T.VELOCITY_TYPE
