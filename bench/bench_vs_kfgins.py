"""`gnss_ins replay` against KF-GINS on the same bag: CPU seconds, alternating; prints numbers.

KF-GINS (i2Nav-WHU, GPLv3, https://github.com/i2Nav-WHU/KF-GINS) is a C++ (Eigen, -O3) loosely
coupled GNSS/INS EKF: 21 error states (position, velocity, attitude, gyro and accelerometer
biases and scale factors), covariance propagated at every IMU sample, GNSS position updates
only, and its navigation result, IMU errors and state σ written as text at every IMU sample. It
is built from its public source outside this repository (``--help`` and a missing binary print
how); nothing of it is copied here.

The bag (bench/speed_bag.py: 437 s test pattern, imu400cc at 200 Hz, GNSS fix + velocity at
5 Hz, truth at 50 Hz; ``--duration`` another length of the same drive, the pattern repeated;
or ``--bag``) is converted to KF-GINS's inputs: the IMU as angle and
velocity increments (rate and specific force times the sample interval, imu_link FLU turned
into KF-GINS's forward-right-down), the valid fixes with their σ (north, east, down), and its
YAML with the replay's own noise (config/ins_fusion.yaml: ARW, VRW, bias instabilities and
correlation time, turn-on biases as the initial bias σ; 1000 ppm for the scale factors the
replay does not estimate by default) and lever arm. KF-GINS has no alignment: it starts from
the truth at the first IMU stamp (moved from base_link to the IMU).

Timed: ``gnss_ins replay BAG --report FILE`` (the whole command: start-up, reading, fusion,
evaluation against the truth, report) and ``KF-GINS CONFIG`` (reading its text inputs, the
filter, writing its outputs), after one untimed run of each, in alternating order, CPU seconds
(user + system) of the child from resource.getrusage. Prints each run, the medians, their
ratio and each pair's (the two runs of a pair saw about the same load on a shared machine), and
both horizontal RMS errors against the truth (a check that both filters ran sensibly).

With a second, shorter bag of the same drive (``--short-bag``; by default, with the simulated
bag, the same simulation 150 s long, which has the same standstill and alignment in its first
64 s) both are timed on it too, and the difference of the medians over the difference of the
IMU samples gives each one's cost per IMU sample beyond its fixed start-up (imports, kernel
load): the ratio a long bag tends to. The difference of two medians is noisy on a shared
machine (±10 µs a sample between runs); a long bag (``--duration 1800``) measures the same
more firmly.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import shutil
import statistics
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pymap3d
import yaml
from scipy.spatial.transform import Rotation
from speed_bag import gnss_ins_command, simulated_bag

from ins_fusion.replay.inputs import ReplayInputs, load_bag
from ins_fusion.replay.metrics import map_enu

REPOSITORY = Path(__file__).resolve().parent.parent
PARAMETER_FILE = REPOSITORY / "config" / "ins_fusion.yaml"
BUILD_HELP = """\
KF-GINS binary not found: give --kfgins PATH or set KFGINS_BIN. To build it (GPLv3; keep it
outside this repository; cmake and a C++ compiler, ~3 min on 2 cores, its Eigen, yaml-cpp and
abseil come vendored in its ThirdParty/):
    git clone https://github.com/i2Nav-WHU/KF-GINS.git /tmp/kfgins
    cmake -S /tmp/kfgins -B /tmp/kfgins/build -DCMAKE_BUILD_TYPE=Release
    cmake --build /tmp/kfgins/build -j2 --target KF-GINS
    KFGINS_BIN=/tmp/kfgins/bin/KF-GINS python bench/bench_vs_kfgins.py"""
#: GPS time = Unix time - this + leap seconds (18 s since 2017) [s].
GPS_EPOCH_UNIX_S = 315964800.0
GPS_LEAP_S = 18.0
WEEK_S = 604800.0
#: KF-GINS scale-factor σ [ppm] (the replay has no scale-factor states by default).
SCALE_SIGMA_PPM = 1000.0
#: Standard gravity [m/s²]; 1 mg = 980.665 mGal.
G0 = 9.80665
#: FLU <-> FRD (imu_link and KF-GINS's IMU frame), ENU -> NED.
FLU_FRD = np.diag([1.0, -1.0, -1.0])
NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def node_parameters() -> dict[str, Any]:
    """The replay's default parameters (config/ins_fusion.yaml)."""
    text = PARAMETER_FILE.read_text(encoding="utf-8")
    return dict(yaml.safe_load(text)["ins_fusion_node"]["ros__parameters"])


def seconds_of_week(t_unix_s: np.ndarray, week_start_s: float) -> np.ndarray:
    """GPS seconds of the week that starts at ``week_start_s`` (GPS seconds) [s]."""
    return np.asarray(t_unix_s - GPS_EPOCH_UNIX_S + GPS_LEAP_S - week_start_s)


def imu_pose(inputs: ReplayInputs, lever_arm_flu_m: list[float]) -> np.ndarray:
    """Truth of the IMU at the reference stamps: (m, 7) = t [s], lat [deg], lon [deg], h [m],
    then roll, pitch, yaw [deg] of FRD in NED (lever arm from base_link, no mounting)."""
    ref = inputs.reference
    if ref is None or ref.attitude is None:
        raise SystemExit(f"{inputs.bag}: needs /ground_truth/fix and /ground_truth/attitude")
    at = np.searchsorted(ref.attitude.t_s, ref.position.t_s).clip(0, len(ref.attitude.t_s) - 1)
    r_enu_flu = Rotation.from_quat(ref.attitude.values[at])
    lat, lon, h = ref.position.values.T
    arm = r_enu_flu.apply(lever_arm_flu_m)
    imu_lat, imu_lon, imu_h = pymap3d.enu2geodetic(arm[:, 0], arm[:, 1], arm[:, 2], lat, lon, h)
    r_ned_frd = Rotation.from_matrix(NED_ENU @ r_enu_flu.as_matrix() @ FLU_FRD)
    yaw, pitch, roll = r_ned_frd.as_euler("ZYX", degrees=True).T
    return np.column_stack([ref.position.t_s, imu_lat, imu_lon, imu_h, roll, pitch, yaw % 360.0])


def write_inputs(inputs: ReplayInputs, directory: Path) -> tuple[Path, int, float]:
    """KF-GINS's IMU, GNSS and YAML files in ``directory``; returns the YAML path, the IMU rate
    [Hz] and the GPS week start [GPS s] of its times."""
    params = node_parameters()
    noise = params["imu_noise"]
    t = inputs.imu.t_s
    rate = inputs.imu.rate_flu_rad_s @ FLU_FRD
    force = inputs.imu.force_flu_m_s2 @ FLU_FRD
    imu_rate_hz = round((len(t) - 1) / (t[-1] - t[0]))
    dt = np.diff(t, prepend=t[0] - 1.0 / imu_rate_hz)[:, None]
    week_start = math.floor((t[0] - GPS_EPOCH_UNIX_S + GPS_LEAP_S) / WEEK_S) * WEEK_S
    sow = seconds_of_week(t, week_start)
    if sow[-1] >= WEEK_S:
        raise SystemExit(f"{inputs.bag}: crosses a GPS week boundary, which KF-GINS cannot read")
    np.savetxt(
        directory / "imu.txt",
        np.column_stack([sow, rate * dt, force * dt]),
        fmt=["%.6f"] + ["%.12e"] * 6,
    )
    fixes = [m for _, role, m in inputs.measurements if role == "fix" and m.valid]
    enu_var = np.array([np.diag(m.cov_enu_m2) for m in fixes])
    gnss = np.column_stack(
        [
            seconds_of_week(np.array([m.t_s for m in fixes]), week_start),
            [(m.lat_deg, m.lon_deg, m.height_m) for m in fixes],
            np.sqrt(enu_var[:, [1, 0, 2]]),
        ]
    )
    np.savetxt(directory / "gnss.txt", gnss, fmt=["%.6f", "%.11f", "%.11f"] + ["%.4f"] * 4)
    imu_arm = np.asarray(params["imu_lever_arm"], dtype=np.float64)
    start = imu_pose(inputs, list(imu_arm))[0]
    ref = inputs.reference
    assert ref is not None and ref.velocity is not None
    vel_enu = ref.velocity.values[np.searchsorted(ref.velocity.t_s, t[0])]
    antenna_flu = np.asarray(params["gnss_lever_arm"], dtype=np.float64) - imu_arm
    turn_on_gyro_deg_h = noise["gyro_turn_on_bias"] * 3600.0
    turn_on_accel_mgal = noise["accel_turn_on_bias"] * G0 * 100.0
    config = {
        "imupath": str(directory / "imu.txt"),
        "gnsspath": str(directory / "gnss.txt"),
        "outputpath": str(directory),
        "imudatalen": 7,
        "imudatarate": imu_rate_hz,
        "starttime": float(sow[0]),
        "endtime": -1,
        "initpos": [float(v) for v in start[1:4]],
        "initvel": [float(v) for v in NED_ENU @ vel_enu],
        "initatt": [float(v) for v in start[4:7]],
        "initgyrbias": [0.0] * 3,
        "initaccbias": [0.0] * 3,
        "initgyrscale": [0.0] * 3,
        "initaccscale": [0.0] * 3,
        "initposstd": [0.1, 0.1, 0.1],
        "initvelstd": [0.05, 0.05, 0.05],
        "initattstd": [0.5, 0.5, 2.0],
        "initbgstd": [turn_on_gyro_deg_h] * 3,
        "initbastd": [turn_on_accel_mgal] * 3,
        "imunoise": {
            "arw": list(noise["gyro_arw"]),
            "vrw": list(noise["accel_vrw"]),
            "gbstd": list(noise["gyro_bias_instability"]),
            "abstd": [v * G0 * 100.0 for v in noise["accel_bias_instability"]],
            "gsstd": [SCALE_SIGMA_PPM] * 3,
            "asstd": [SCALE_SIGMA_PPM] * 3,
            "corrtime": noise["bias_correlation_time"] / 3600.0,
        },
        "antlever": [float(v) for v in FLU_FRD @ antenna_flu],
    }
    path = directory / "kf-gins.yaml"
    path.write_text(yaml.safe_dump(config, default_flow_style=None), encoding="utf-8")
    return path, imu_rate_hz, week_start


def timed(command: list[str], cwd: Path) -> tuple[float, float]:
    """Run ``command`` to the end; CPU seconds (user + system) of the child and wall seconds."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def kfgins_horizontal_rms(
    directory: Path, inputs: ReplayInputs, week_start: float, lever_arm: list[float]
) -> float:
    """Horizontal RMS [m] of KF-GINS's IMU position against the truth of the IMU, at the truth
    stamps it covers (its navigation result is interpolated linearly in ENU)."""
    nav = np.loadtxt(directory / "KF_GINS_Navresult.nav")
    truth = imu_pose(inputs, lever_arm)
    truth_sow = seconds_of_week(truth[:, 0], week_start)
    keep = (truth_sow >= nav[0, 1]) & (truth_sow <= nav[-1, 1])
    datum = (float(truth[0, 1]), float(truth[0, 2]), float(truth[0, 3]))
    nav_enu = map_enu(nav[:, 2:5], datum)
    truth_enu = map_enu(truth[keep, 1:4], datum)
    at = truth_sow[keep]
    error = [np.interp(at, nav[:, 1], nav_enu[:, i]) - truth_enu[:, i] for i in (0, 1)]
    return float(np.sqrt(np.mean(np.hypot(*error) ** 2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kfgins", type=Path, help="KF-GINS binary (default $KFGINS_BIN)")
    parser.add_argument("--bag", type=Path, help="bag to replay (default: bench/speed_bag.py)")
    parser.add_argument("--pairs", type=int, default=3, help="timed pairs (default 3)")
    parser.add_argument("--workdir", type=Path, help="keep the bag and files here")
    parser.add_argument(
        "--duration",
        type=int,
        default=437,
        help="length of the simulated bag [s] (default 437; e.g. 1800: the fixed start-up"
        " weighs less)",
    )
    parser.add_argument(
        "--short-bag",
        type=Path,
        help="a shorter bag of the same drive for the cost per sample (default with the"
        " simulated bag: the same simulation 150 s long; none with --bag)",
    )
    args = parser.parse_args()
    binary = args.kfgins or (Path(os.environ["KFGINS_BIN"]) if "KFGINS_BIN" in os.environ else None)
    if binary is None or not binary.is_file():
        print(BUILD_HELP if binary is None else f"{binary}: no such file\n{BUILD_HELP}")
        print("skipped: no KF-GINS binary")
        return
    with tempfile.TemporaryDirectory(prefix="vs_kfgins_") as temporary:
        workdir = args.workdir or Path(temporary)
        workdir.mkdir(parents=True, exist_ok=True)
        bag = args.bag or simulated_bag(workdir, args.duration)
        short = args.short_bag or (None if args.bag else simulated_bag(workdir, 150))
        long_run = run(binary.resolve(), bag, workdir, args.pairs)
        if short is not None:
            print()
            short_run = run(binary.resolve(), short, workdir, args.pairs)
            marginal(long_run, short_run)


def marginal(long_run: Timed, short_run: Timed) -> None:
    """Cost per IMU sample beyond the fixed start-up of each, from two bags of one drive."""
    samples = long_run.samples - short_run.samples
    per_sample = {
        name: (long_run.medians[name] - short_run.medians[name]) / samples
        for name in long_run.medians
    }
    for name, value in per_sample.items():
        fixed = short_run.medians[name] - value * short_run.samples
        print(f"{name:<16} {value * 1e6:6.1f} µs per IMU sample beyond {fixed:5.2f} s fixed")
    print(f"ratio per IMU sample: {per_sample['gnss_ins replay'] / per_sample['KF-GINS']:.2f}")


class Timed(NamedTuple):
    """Median CPU seconds per command and the bag's IMU samples."""

    medians: dict[str, float]
    samples: int


def run(binary: Path, bag: Path, workdir: Path, pairs: int) -> Timed:
    inputs = load_bag(bag)
    kf_dir = workdir / "kfgins"
    shutil.rmtree(kf_dir, ignore_errors=True)
    kf_dir.mkdir()
    config, imu_rate_hz, week_start = write_inputs(inputs, kf_dir)
    samples = len(inputs.imu)
    print(
        f"bag {bag}: {samples} IMU samples at {imu_rate_hz} Hz, {inputs.duration_s:.1f} s,"
        f" {sum(r == 'fix' for _, r, _ in inputs.measurements)} fixes"
    )
    report = workdir / "replay.json"
    commands = {
        "gnss_ins replay": [*gnss_ins_command(), "replay", str(bag), f"--report={report}"],
        "KF-GINS": [str(binary), str(config)],
    }
    for command in commands.values():  # untimed: file cache, .pyc
        timed(command, kf_dir)
    cpu: dict[str, list[float]] = {name: [] for name in commands}
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    for pair in range(pairs):
        order = list(commands) if pair % 2 == 0 else list(commands)[::-1]
        for name in order:
            seconds, wall = timed(commands[name], kf_dir)
            cpu[name].append(seconds)
            print(f"  pair {pair + 1}  {name:<16} CPU {seconds:6.2f} s  wall {wall:6.2f} s")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    medians = {name: statistics.median(values) for name, values in cpu.items()}
    for name, value in medians.items():
        print(f"{name:<16} median CPU {value:6.2f} s = {value / samples * 1e6:6.1f} µs per sample")
    ratio = medians["gnss_ins replay"] / medians["KF-GINS"]
    pair_ratios = [a / b for a, b in zip(cpu["gnss_ins replay"], cpu["KF-GINS"], strict=True)]
    print(
        f"ratio replay / KF-GINS: {ratio:.2f} (per pair: "
        f"{' '.join(f'{r:.2f}' for r in pair_ratios)}, median {statistics.median(pair_ratios):.2f})"
    )
    replay_rms = json.loads(report.read_text())["position_error_m"]["horizontal_rms"]
    if replay_rms is None:  # never navigating: no evaluation
        raise SystemExit(f"{bag}: the replay did not navigate (see {report})")
    kf_rms = kfgins_horizontal_rms(kf_dir, inputs, week_start, node_parameters()["imu_lever_arm"])
    print(
        f"horizontal RMS against the truth: replay {replay_rms:.3f} m (base_link),"
        f" KF-GINS {kf_rms:.3f} m (IMU, position updates only)"
    )
    return Timed(medians, samples)


if __name__ == "__main__":
    main()
