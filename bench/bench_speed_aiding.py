"""Vehicle speed aiding: GNSS outages with and without the speed, on the real car
drive with its CAN speed and on simulated IMU400CC drives with a survey DMI.

    .venv/bin/python bench/bench_speed_aiding.py            (about 4 min; simulates into a
                                                              temporary directory)
    .venv/bin/python bench/bench_speed_aiding.py --keep DIR  (keeps the simulated bags)

1. Real: test/fixtures/comma2k19/comma2k19_ex1_seg40_speed (a RAV4's CAN speed, the mean of
   its four wheel speeds, on /vehicle/speed), parameters 'defaults' (config/ins_fusion.yaml: the
   IMU400CC's noise, the survey car's lever arms) and 'datasheet' (the fixture's
   ins_fusion_phone.yaml); outages of 15 s (three) and 30 s (two runs of one). Per outage the
   largest horizontal error against the reference and the 3σ the filter gave at the outage's end.
2. Simulated: `gnss_ins simulate --speed` drives (test pattern, 900 s, IMU400CC, Leica RTK, ADU5,
   the DMI on the left rear wheel: 2 % scale error, 500 pulses/m, 20 Hz) replayed with the
   defaults and `speed.lever_arm` = the DMI's hub (0, 0.8, 0.33) m as a user measures it; five 60 s
   outages. The scale estimate after 300 s and at the end, each outage's largest horizontal
   error as a share of the distance driven in it, and the error of the path's length through
   the outage (what the speed measures; the rest of the position error is the heading's).
3. Slip: the same drive with the wheels slipping from 1 m/s² of braking (the simulator's default
   is 3 m/s²): readings the slip spoils (more than 3σ below the same drive's reading without
   slip), how many speed readings are rejected (``speed.max_accel``) or gated, and the trajectory
   against the same drive without slip.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gnss_ins_common.params import load_yaml, validate_all
from gnss_ins_common.types import FloatArray
from ins_fusion.core.settings.config import NODE_NAME
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import ReplayInputs, load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.topics import DEFAULT_REFERENCE, TopicMap

REPO = Path(__file__).resolve().parents[1]
FIXTURE = REPO / "test" / "fixtures" / "comma2k19"
REAL_BAG = FIXTURE / "comma2k19_ex1_seg40_speed"
REAL_OUTAGES = {
    "15 s": [(Outage(5.0, 15.0), Outage(25.0, 15.0), Outage(43.0, 15.0))],
    "30 s": [(Outage(5.0, 30.0),), (Outage(28.0, 30.0),)],
}
SIM_SEEDS = (1, 2, 3)
SIM_DURATION_S = 900
SIM_OUTAGES = tuple(Outage(start, 60.0) for start in (300.0, 420.0, 540.0, 660.0, 780.0))
#: The DMI's hub in base_link FLU [m] (sim.scenarios' survey car), as a user measures it.
DMI_LEVER_ARM = [0.0, 0.8, 0.33]
SCALE_ERROR = 0.02
SLIP_THRESHOLD_M_S2 = 1.0


def first_seconds(inputs: ReplayInputs, seconds: float) -> ReplayInputs:
    """The inputs of the first ``seconds`` of IMU samples."""
    n = int(np.searchsorted(inputs.imu.t_s, inputs.t0_s + seconds))
    imu = inputs.imu
    cut = type(imu)(imu.t_s[:n], imu.rate_flu_rad_s[:n], imu.force_flu_m_s2[:n])
    kept = [m for m in inputs.measurements if m[0] < n]
    return dataclasses.replace(inputs, imu=cut, measurements=kept)


def _f(value: Any, digits: int = 2) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _nees(nees: dict[str, Any]) -> str:
    """The position NEES mean and the share of epochs inside 3σ."""
    return f"{_f(nees['position_mean'])} ({100.0 * nees['position_within_3sigma_fraction']:.0f} %)"


def _rms(values: Sequence[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values)) if values else math.nan


def outage_rows(report: dict[str, Any]) -> list[tuple[float, float]]:
    """(largest horizontal error, 3σ at the end) [m] of each outage."""
    return [
        (o["horizontal_error_max_m"], 3.0 * o["horizontal_sigma_end_m"]) for o in report["outages"]
    ]


def real_drive() -> None:
    inputs = load_bag(REAL_BAG, TopicMap(), DEFAULT_REFERENCE, reference_required=True)
    plain = inputs.without_speed()
    speeds = len(inputs.measurements) - len(plain.measurements)
    print(f"## Real drive {REAL_BAG.name}: {speeds} CAN speed readings, {inputs.duration_s:.0f} s")
    print()
    print(
        "| parameters | outages | speed | largest error per outage m (3σ at its end) | RMS m"
        " | ratio | NEES (in 3σ) | speed scale % |"
    )
    print("|---|---|---|---|---|---|---|---|")
    sets = {
        "defaults": validate_all(PARAMETERS, {}),
        "datasheet": load_yaml(FIXTURE / "ins_fusion_phone.yaml", NODE_NAME, PARAMETERS),
    }
    for name, params in sets.items():
        for label, runs in REAL_OUTAGES.items():
            rms = {}
            for aided, data in (("no", plain), ("yes", inputs)):
                rows: list[tuple[float, float]] = []
                nees, inside, scale = [], [], ""
                for outages in runs:
                    report = replay(data, params, outages, DEFAULT_REFERENCE).report
                    rows += outage_rows(report)
                    nees.append(report["nees"]["position_mean"])
                    inside.append(report["nees"]["position_within_3sigma_fraction"])
                    cal = report["self_calibration"]
                    if "speed_scale_error_pct" in cal:
                        scale = (
                            f"{cal['speed_scale_error_pct']:.2f} ± "
                            f"{3.0 * cal['speed_scale_sigma_pct']:.2f} (3σ)"
                        )
                rms[aided] = _rms([e for e, _ in rows])
                ratio = f"{rms['no'] / rms['yes']:.1f}x" if aided == "yes" else ""
                print(
                    f"| {name} | {label} | {aided} | "
                    + ", ".join(f"{_f(e)} ({_f(s)})" for e, s in rows)
                    + f" | {_f(rms[aided])} | {ratio} | {_f(float(np.mean(nees)))}"
                    f" ({100.0 * float(np.mean(inside)):.0f} %) | {scale or '-'} |"
                )
                sys.stdout.flush()
    print()


def simulate(directory: Path, seed: int, slip_threshold_m_s2: float | None = None) -> Path:
    """A `gnss_ins simulate --speed` drive in ``directory`` (made once)."""
    name = f"speed_s{seed}" + ("" if slip_threshold_m_s2 is None else "_slip")
    path = directory / name
    if not path.exists():
        command = [
            str(Path(sys.executable).with_name("gnss_ins")),
            "simulate",
            f"--duration={SIM_DURATION_S}",
            f"--seed={seed}",
            "--speed",
            f"--speed-scale={SCALE_ERROR}",
            f"--output={path}",
        ]
        if slip_threshold_m_s2 is not None:
            command.append(f"--speed-slip-threshold={slip_threshold_m_s2}")
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return path


def distance_m(inputs: ReplayInputs, outage: Outage) -> float:
    """Distance driven in an outage [m], from the reference velocity."""
    assert inputs.reference is not None and inputs.reference.velocity is not None
    velocity = inputs.reference.velocity
    return path_length_m(velocity.t_s, velocity.values, inputs.t0_s, outage)


def path_length_m(t_s: FloatArray, vel_enu: FloatArray, t0_s: float, outage: Outage) -> float:
    """Length of the horizontal path [m] driven in an outage by velocities at stamps t_s."""
    t = t_s - t0_s
    inside = (t >= outage.start_s) & (t <= outage.end_s)
    return float(np.trapezoid(np.hypot(*vel_enu[inside, :2].T), t[inside]))


def simulated_drives(directory: Path) -> None:
    params = validate_all(PARAMETERS, {"speed.lever_arm": DMI_LEVER_ARM})
    print(
        f"## Simulated drives: IMU400CC, DMI {100 * SCALE_ERROR:.0f} % scale, "
        f"{len(SIM_OUTAGES)} outages of 60 s"
    )
    print()
    print(
        "| seed | speed | scale at 300 s % (3σ) | scale at the end % (3σ) | largest error per"
        " outage, % of the distance | worst % | path length error, worst % |"
        " horiz RMS m | NEES (in 3σ) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for seed in SIM_SEEDS:
        inputs = load_bag(simulate(directory, seed), TopicMap(), DEFAULT_REFERENCE)
        for aided, data in (("no", inputs.without_speed()), ("yes", inputs)):
            result = replay(data, params, SIM_OUTAGES, DEFAULT_REFERENCE)
            report = result.report
            assert result.evaluation is not None
            distances = [distance_m(inputs, outage) for outage in SIM_OUTAGES]
            shares = [
                100.0 * o["horizontal_error_max_m"] / d
                for o, d in zip(report["outages"], distances, strict=True)
            ]
            track = result.run.track
            lengths = [
                100.0 * abs(path_length_m(track.t_s, track.vel_enu_m_s, inputs.t0_s, o) - d) / d
                for o, d in zip(SIM_OUTAGES, distances, strict=True)
            ]
            scales = []
            if aided == "yes":
                early = replay(first_seconds(data, 300.0), params, (), DEFAULT_REFERENCE).report
                for cal in (early["self_calibration"], report["self_calibration"]):
                    scales.append(
                        f"{cal['speed_scale_error_pct']:.3f} "
                        f"({3.0 * cal['speed_scale_sigma_pct']:.3f})"
                    )
            nees = report["nees"]
            print(
                f"| {seed} | {aided} | {scales[0] if scales else '-'} |"
                f" {scales[1] if scales else '-'} | "
                + ", ".join(f"{s:.2f}" for s in shares)
                + f" | {max(shares):.2f} | {max(lengths):.3f}"
                f" | {_f(report['position_error_m']['horizontal_rms'], 3)}"
                f" | {_nees(nees)} |"
            )
            sys.stdout.flush()
    print()


def _speeds(inputs: ReplayInputs) -> tuple[FloatArray, FloatArray]:
    """Stamps [s] and values [m/s] of the speed readings."""
    speeds = [m for _, role, m in inputs.measurements if role == "speed"]
    return np.array([m.t_s for m in speeds]), np.array([m.speed_m_s for m in speeds])


def spoiled_stamps(slipping: ReplayInputs, clean: ReplayInputs) -> FloatArray:
    """Stamps of the readings the slip spoils: more than 3σ below the same drive's reading
    without slip (same seed: same noise, same counter)."""
    t, slipped = _speeds(slipping)
    t_clean, clean_speed = _speeds(clean)
    assert np.array_equal(t, t_clean)
    sigma = math.sqrt(max(m.variance_m2_s2 for _, r, m in clean.measurements if r == "speed"))
    return t[slipped < clean_speed - 3.0 * sigma]


def slip(directory: Path) -> None:
    params = validate_all(PARAMETERS, {"speed.lever_arm": DMI_LEVER_ARM})
    seed = SIM_SEEDS[0]
    print(f"## Slip from {SLIP_THRESHOLD_M_S2} m/s² of braking (seed {seed})")
    print()
    print(
        "| drive | readings spoilt | speed readings rejected (gated) | horiz RMS m"
        " | largest outage error m | NEES (in 3σ) |"
    )
    print("|---|---|---|---|---|---|")
    clean = load_bag(simulate(directory, seed), TopicMap(), DEFAULT_REFERENCE)
    slipping = load_bag(simulate(directory, seed, SLIP_THRESHOLD_M_S2), TopicMap())
    spoiled = len(spoiled_stamps(slipping, clean))
    for label, inputs, spoilt in (("no slip", clean, 0), ("slip", slipping, spoiled)):
        report = replay(inputs, params, SIM_OUTAGES, DEFAULT_REFERENCE).report
        worst = max(e for e, _ in outage_rows(report))
        speed = report["measurements"]["vehicle_speed"]
        nees = report["nees"]
        print(
            f"| {label} | {spoilt} |"
            f" {speed['rejected']} ({speed['gated']}) |"
            f" {_f(report['position_error_m']['horizontal_rms'], 3)} | {_f(worst)} |"
            f" {_nees(nees)} |"
        )
    print()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", type=Path, help="simulate into (and reuse) this directory")
    parser.add_argument("--only", choices=("real", "sim", "slip"), help="one part only")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as scratch:
        directory = args.keep or Path(scratch)
        directory.mkdir(parents=True, exist_ok=True)
        if args.only in (None, "real"):
            real_drive()
        if args.only in (None, "sim"):
            simulated_drives(directory)
        if args.only in (None, "slip"):
            slip(directory)
    return 0


if __name__ == "__main__":
    sys.exit(main())
