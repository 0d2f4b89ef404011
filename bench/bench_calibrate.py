"""Calibration methods (ins_fusion.calibration_id): recovery accuracy and run time; prints
numbers, asserts nothing.

1. Per method, many seeds of the simulated procedure (IMU400CC unless said, band-limited noise,
   bias instability given to the estimator): for every written term the normalised error
   (estimate - truth)/σ — its RMS should be near 1 if the stated σ are honest, and 99.7 % of the
   components should be within 3σ — and the median σ in the file's units.
2. Run time: simulation and estimation per procedure, and ``gnss_ins calibrate six-position``
   end to end on a bag of the Aalborg procedure (6 × 120 s at 134 Hz): reading, estimation,
   report and figure.

``--docs-images DIR`` instead writes the figures of docs/calibration.md (docs/images).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ins_fusion.bags.imu import write_imu_bag
from ins_fusion.calibration_id import procedures, rotation, static
from ins_fusion.calibration_id.model import BiasInstability, Site
from ins_fusion.calibration_id.plot import plot_positions, plot_segments
from ins_fusion.calibration_id.result import CalibrationResult, Quantity
from ins_fusion.calibration_id.segments import DetectorSettings, Kind, detect
from ins_fusion.calibration_id.unknown_attitude import unknown_attitude
from ins_fusion.sim.imu_model import IMU400CC, STIM300, ImuErrorModel, ImuProfile
from ins_fusion.tools.cli import main as gnss_ins

SITE = Site.at(57.0, 50.0)
LEVEL = math.radians(0.05)
S4_PROFILE = dataclasses.replace(
    STIM300,
    accel=dataclasses.replace(
        STIM300.accel,
        misalignment_rad=((0.0, 0.0, 0.0), (1e-3, 0.0, 0.0), (-2e-3, 5e-4, 0.0)),
        misalignment_sigma_rad=0.0,
    ),
)
#: the same without the random walks (rate and acceleration) that the estimators do not model
S4_NO_WALK = dataclasses.replace(
    S4_PROFILE,
    gyro=dataclasses.replace(S4_PROFILE.gyro, random_walk=(0.0, 0.0, 0.0)),
    accel=dataclasses.replace(S4_PROFILE.accel, random_walk=(0.0, 0.0, 0.0)),
)
S3_PROFILE = dataclasses.replace(
    IMU400CC,
    accel=dataclasses.replace(
        IMU400CC.accel,
        misalignment_rad=((0.0, 2e-3, -1e-3), (1.5e-3, 0.0, 3e-3), (-2e-3, 1e-3, 0.0)),
    ),
)
RPY = [
    tuple(math.radians(a) for a in rpy)
    for rpy in [(r, 0.0, 20.0 * k) for k, r in enumerate(range(-180, 180, 45))]
    + [
        (0, 45, 10),
        (0, -45, 50),
        (90, 45, 90),
        (-90, -45, 130),
        (180, 45, 170),
        (45, -45, 210),
        (0, 89, 250),
        (0, -89, 290),
        (135, 45, 330),
        (-135, -45, 20),
    ]
]


def _instability(profile: ImuProfile) -> BiasInstability:
    return BiasInstability(
        profile.gyro.bias_instability,
        profile.accel.bias_instability,
        profile.gyro.bias_correlation_time_s[0],
        profile.accel.bias_correlation_time_s[0],
    )


def _truth(model: ImuErrorModel, profile: ImuProfile) -> dict[Quantity, np.ndarray]:
    return {
        Quantity.ACCEL_BIAS: model.accel.bias,
        Quantity.ACCEL_SCALE_POSITIVE: model.accel.scale_pos,
        Quantity.ACCEL_SCALE_NEGATIVE: model.accel.scale_neg,
        Quantity.ACCEL_MISALIGNMENT: model.accel.misalignment,
        Quantity.GYRO_BIAS: model.gyro.bias,
        Quantity.GYRO_SCALE_POSITIVE: model.gyro.scale_pos,
        Quantity.GYRO_SCALE_NEGATIVE: model.gyro.scale_neg,
        Quantity.GYRO_G_SENSITIVITY: np.array(profile.gyro_g_sensitivity),
    }


@dataclasses.dataclass
class Method:
    name: str
    profile: ImuProfile
    steps: Callable[[int], list[procedures.Step]]
    estimate: Callable[[list, object], CalibrationResult]
    #: the truth of a term as the method sees it (symmetric S2 averages S+ and S-)
    adjust: Callable[[Quantity, np.ndarray, ImuErrorModel], np.ndarray] = lambda q, v, m: v


def _symmetric(q: Quantity, value: np.ndarray, model: ImuErrorModel) -> np.ndarray:
    s_pos, s_neg = model.accel.scale_pos, model.accel.scale_neg
    if q is Quantity.ACCEL_BIAS:
        return value + SITE.gravity_m_s2 * (s_pos - s_neg) / 2
    if q in (Quantity.ACCEL_SCALE_POSITIVE, Quantity.ACCEL_SCALE_NEGATIVE):
        return (s_pos + s_neg) / 2
    return value


TURN_TABLE = procedures.turn_table(8.0 * math.pi, math.radians(15.0), 20.0)
METHODS = [
    Method(
        "six-position (S2), 6 x 120 s",
        IMU400CC,
        lambda seed: procedures.six_position(120.0, 6.0, level_sigma_rad=LEVEL, seed=seed),
        lambda rec, segs: static.six_position(
            segs, static.StaticOptions(SITE, LEVEL, _instability(IMU400CC))
        ),
    ),
    Method(
        "salychev (symmetric S2), 6 x 120 s",
        IMU400CC,
        lambda seed: procedures.six_position(
            120.0, 6.0, salychev=True, level_sigma_rad=LEVEL, seed=seed
        ),
        lambda rec, segs: static.six_position(
            segs,
            static.StaticOptions(SITE, LEVEL, _instability(IMU400CC), static.Scale.SYMMETRIC),
            salychev=True,
        ),
        _symmetric,
    ),
    Method(
        "known-attitude (S3), 18 x 40 s, misalignment",
        S3_PROFILE,
        lambda seed: procedures.multi_position(
            [
                procedures.tilted(
                    Rotation.from_euler("ZYX", [y, p, r]), LEVEL, np.random.default_rng(seed + k)
                )
                for k, (r, p, y) in enumerate(RPY)
            ],
            40.0,
            5.0,
        ),
        lambda rec, segs: static.known_attitude(
            segs, RPY, static.StaticOptions(SITE, LEVEL, _instability(S3_PROFILE))
        ),
    ),
    *(
        Method(
            f"unknown-attitude (S4), 26 x 30 s, {name}",
            profile,
            lambda seed: procedures.multi_position(procedures.positions_26(), 30.0, 4.0),
            lambda rec, segs, profile=profile: unknown_attitude(
                segs, static.StaticOptions(SITE, 0.0, _instability(profile))
            ),
        )
        for name, profile in (
            ("STIM300 without random walks", S4_NO_WALK),
            ("STIM300 (its random walks are not modelled)", S4_PROFILE),
        )
    ),
    Method(
        "rate-table (D1), 15 deg/s",
        IMU400CC,
        lambda seed: TURN_TABLE,
        lambda rec, segs: rotation.rate_table(
            segs, math.radians(15.0), 0.0, math.radians(0.5), _instability(IMU400CC)
        ),
    ),
    Method(
        "known-angle (D2), 4 turns at 15 deg/s",
        IMU400CC,
        lambda seed: TURN_TABLE,
        lambda rec, segs: rotation.known_angle(
            [rec],
            [s for s in segs if s.kind is Kind.STATIC],
            8.0 * math.pi,
            math.radians(0.1),
            math.radians(0.5),
            _instability(IMU400CC),
        ),
    ),
]


def bench_method(method: Method, seeds: int) -> None:
    z: dict[Quantity, list[np.ndarray]] = {}
    sigmas: dict[Quantity, list[np.ndarray]] = {}
    sim_s = est_s = 0.0
    for seed in range(seeds):
        start = time.perf_counter()
        record, model = procedures.simulate(method.steps(seed), method.profile, SITE, 500 + seed)
        segments = detect(record, 0, DetectorSettings())
        sim_s += time.perf_counter() - start
        start = time.perf_counter()
        result = method.estimate(record, segments)
        est_s += time.perf_counter() - start
        truth = _truth(model, method.profile)
        for e in result.estimates:
            if not e.written:
                continue
            known = ~np.isnan(e.value) & (e.sigma > 0.0)
            expected = method.adjust(e.quantity, truth[e.quantity], model)
            z.setdefault(e.quantity, []).append((e.value - expected)[known] / e.sigma[known])
            sigmas.setdefault(e.quantity, []).append(e.sigma[known] / e.quantity.unit)
    print(
        f"\n{method.name}: {seeds} seeds, simulation + detection {sim_s / seeds:.2f} s,"
        f" estimation {1e3 * est_s / seeds:.1f} ms per run"
    )
    print(f"  {'term':<26} {'RMS z':>6} {'max |z|':>8} {'|z|<3':>7} {'median σ':>10}  unit")
    for q, values in z.items():
        all_z = np.concatenate(values)
        sigma = np.median(np.concatenate(sigmas[q]))
        print(
            f"  {q.label:<26} {math.sqrt(np.mean(all_z**2)):6.2f} {np.max(np.abs(all_z)):8.2f}"
            f" {100 * np.mean(np.abs(all_z) < 3):6.1f}% {sigma:10.4g}  {q.unit_text}"
        )


def bench_cli(directory: Path) -> None:
    steps = procedures.six_position(120.0, 6.0, level_sigma_rad=LEVEL, seed=1)
    record, _ = procedures.simulate(steps, IMU400CC, SITE, 1, name="aalborg_six_position")
    bag = directory / "six"
    start = time.perf_counter()
    write_imu_bag(bag, record)
    written = time.perf_counter() - start
    args = [
        "calibrate",
        "six-position",
        str(bag),
        "--latitude",
        "57",
        "--level-sigma",
        "0.05",
        "-o",
        str(directory / "cal.yaml"),
        "--report",
        str(directory / "report.md"),
    ]
    for extra in ([], ["--plot", str(directory / "segments.png")]):
        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            gnss_ins([*args, *extra])
        elapsed = time.perf_counter() - start
        print(
            f"gnss_ins calibrate six-position, {len(record.t_s)} samples"
            f"{' with --plot' if extra else ''}: {elapsed:.2f} s"
        )
    print(f"(writing that bag: {written:.2f} s)")


def docs_images(directory: Path) -> None:
    """The figures of docs/calibration.md."""
    directory.mkdir(parents=True, exist_ok=True)
    plot_positions(directory / "calibration_positions.png")
    steps = procedures.six_position(60.0, 8.0, level_sigma_rad=LEVEL, seed=1)
    record, _ = procedures.simulate(steps, IMU400CC, SITE, 1, name="six")
    segments = detect(record, 0, DetectorSettings())
    result = static.six_position(segments, static.StaticOptions(SITE, LEVEL))
    plot_segments(
        [record],
        result.segments,
        result.labels,
        directory / "calibration_six_position.png",
        "six-position record (simulated IMU400CC): static segments found",
    )
    record, _ = procedures.simulate(TURN_TABLE, IMU400CC, SITE, 2, name="turn_table")
    segments = detect(record, 0, DetectorSettings())
    result = rotation.rate_table(segments, math.radians(15.0), 0.0, 0.0, BiasInstability())
    plot_segments(
        [record],
        result.segments,
        result.labels,
        directory / "calibration_turn_table.png",
        "turn-table record (simulated IMU400CC): bias before each turn, steady turns",
    )
    print(f"figures written to {directory}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=12, help="runs per method (S4: half)")
    parser.add_argument(
        "--docs-images", type=Path, metavar="DIR", help="only write the figures of the docs"
    )
    args = parser.parse_args()
    if args.docs_images is not None:
        docs_images(args.docs_images)
        return
    for method in METHODS:
        seeds = max(2, args.seeds // 2) if "S4" in method.name else args.seeds
        bench_method(method, seeds)
    print()
    with tempfile.TemporaryDirectory() as directory:
        bench_cli(Path(directory))


if __name__ == "__main__":
    main()
