"""`gnss_ins simulate`: a simulated drive to a rosbag2 bag, or live on emulated serial devices.

Bag mode writes what imu400cc_node and gnss_node would publish on the drive, each message at its
receive time, plus the truth (ins_fusion/sim/drive.py lists topics, frames and stamps), then
prints the bag summary. The same seed gives the same messages.

``--live`` runs the drive in real time instead: the IMU400CC emulator and the GNSS emulators (the
position receiver, and the ADU5) on pseudo-terminals take their samples from the same truth and
error models, and the port paths are printed first, one line each (``imu: PATH``, ``gnss: PATH``,
``adu5: PATH``), for the real nodes to open. ``--truth-output BAG`` records the truth meanwhile,
stamped on the host clock from the start time the emulators use. Runs until the duration ends or
Ctrl-C / SIGTERM; with ``--hold`` it prints ``drive ended`` when the duration ends and keeps the
devices open (the vehicle parked where the drive ended, the receivers without a fix) until
Ctrl-C / SIGTERM, so that the nodes reading them can be stopped first (``gnss_ins demo``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import signal
import sys
import threading
import time
from datetime import datetime
from pathlib import Path

import numpy as np

from gnss_driver.emulator import EmulatorConfig as GnssEmulatorConfig
from gnss_driver.emulator import GnssEmulator, Truth
from gnss_driver.profiles import Receiver
from gnss_ins_common.types import FloatArray
from imu400cc_driver.emulator import EmulatorConfig, Imu400ccEmulator, SentPacket
from ins_fusion.bags.bag_io import STORAGES, BagError, BagWriter
from ins_fusion.runtime.progress import Progress
from ins_fusion.sim import imu_model, odometer_model, vibration
from ins_fusion.sim.drive import (
    DEFAULT_START_NS,
    POSITION_RECEIVERS,
    Simulation,
    SimulationConfig,
    SkyZoneSpec,
)
from ins_fusion.sim.gnss_model import GnssErrorModel
from ins_fusion.sim.receivers import emulator_truth, epoch_config
from ins_fusion.sim.scenarios import SCENARIOS
from ins_fusion.sim.vehicle import TruthCache
from ins_fusion.sim.vibration import Vibration

#: How often the live mode writes the truth that became due [s].
_LIVE_TICK_S = 0.1
#: Messages written between progress-bar updates.
_PROGRESS_EVERY = 2000


def _numbers(text: str, count: tuple[int, int], what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(":")]
    except ValueError:
        values = []
    if not count[0] <= len(values) <= count[1]:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return values


def _positive(text: str) -> float:
    value = _numbers(text, (1, 1), "a number")[0]
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def _outage(text: str) -> tuple[float, float]:
    start, duration = _numbers(text, (2, 2), "START:DURATION in seconds")
    return start, duration


def _sky_zone(text: str) -> SkyZoneSpec:
    values = _numbers(text, (2, 3), "T:RADIUS[:SATELLITES]")
    return SkyZoneSpec(values[0], values[1], int(values[2]) if len(values) == 3 else 0)


def _number(text: str) -> float:
    value = _numbers(text, (1, 1), "a number")[0]
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def _utc_ns(text: str) -> int:
    try:
        stamp = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an ISO 8601 UTC time, got {text!r}") from None
    if stamp.tzinfo is None:
        raise argparse.ArgumentTypeError(f"{text!r}: give the time zone, e.g. a final Z")
    return round(stamp.timestamp() * 1e9)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins simulate``."""
    parser.add_argument(
        "--scenario",
        choices=sorted(SCENARIOS),
        default="test_pattern",
        help="the drive (docs/simulator.md)",
    )
    parser.add_argument(
        "--imu", choices=sorted(imu_model.PROFILES), default="imu400cc", help="IMU error profile"
    )
    parser.add_argument(
        "--imu-rate", type=_positive, metavar="HZ", help="IMU output rate (default: the profile's)"
    )
    parser.add_argument("--duration", type=_positive, default=240.0, help="seconds to simulate")
    parser.add_argument("--seed", type=int, default=0, help="seed of every error model")
    parser.add_argument("-o", "--output", type=Path, help="bag directory to create")
    parser.add_argument(
        "--storage", choices=sorted(STORAGES), default="mcap", help="rosbag2 storage plugin"
    )
    parser.add_argument(
        "--gnss",
        choices=[*POSITION_RECEIVERS, "none"],
        default="leica_rtk",
        help="position receiver on /gnss/fix, /gnss/vel, /gnss/time_reference (printed as the "
        "Leica rover's VTG, GGA, LLQ)",
    )
    parser.add_argument(
        "--gnss-rate",
        type=_positive,
        metavar="HZ",
        help="position receiver's epoch rate (default: the profile's, 1 Hz)",
    )
    parser.add_argument(
        "--adu5",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="ADU5 attitude on /gnss/attitude",
    )
    parser.add_argument(
        "--outage",
        type=_outage,
        action="append",
        default=[],
        metavar="START:DURATION",
        help="scheduled GNSS outage [s] (repeatable)",
    )
    parser.add_argument(
        "--sky-zone",
        type=_sky_zone,
        action="append",
        default=[],
        metavar="T:RADIUS[:SATS]",
        help="only SATS (default 0) satellites visible within RADIUS m of where the vehicle is at "
        "route time T s (repeatable; the drive meets it again on every lap)",
    )
    parser.add_argument(
        "--band-limit",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="low-pass the IMU white noise with the sensor bandwidth (per-sample σ as measured)",
    )
    parser.add_argument(
        "--vibration",
        choices=sorted(vibration.PROFILES),
        default="car",
        help="engine/road vibration the IMU senses, growing with speed; default like a car on "
        "a road (docs/simulator.md)",
    )
    parser.add_argument(
        "--speed",
        action="store_true",
        help="an odometer (DMI on the left rear wheel) on /vehicle/speed (bags only)",
    )
    parser.add_argument(
        "--speed-rate", type=_positive, metavar="HZ", help="odometer output rate (default 20)"
    )
    parser.add_argument(
        "--speed-scale",
        type=_number,
        metavar="FRACTION",
        help="odometer scale error, measured/true - 1 (default 0.02)",
    )
    parser.add_argument(
        "--speed-slip-threshold",
        type=_number,
        metavar="M_S2",
        help="deceleration above which the wheels slip and the odometer under-reads (default 3)",
    )
    parser.add_argument(
        "--truth-rate", type=_positive, default=50.0, help="rate of /ground_truth/* [Hz]"
    )
    parser.add_argument(
        "--start",
        type=_utc_ns,
        default=DEFAULT_START_NS,
        help="UTC time of the bag's start, ISO 8601 (default 2024-06-01T10:00:00Z)",
    )
    parser.add_argument(
        "--live", action="store_true", help="emulated devices on pseudo-terminals in real time"
    )
    parser.add_argument("--truth-output", type=Path, help="live mode: bag of the truth topics")
    parser.add_argument(
        "--hold",
        action="store_true",
        help="live mode: at the end of the drive print 'drive ended' and keep the devices open"
        " until Ctrl-C/SIGTERM",
    )


def run(args: argparse.Namespace) -> int:
    """Write the bag or run live; 2 on a usage, configuration or bag error."""
    if args.live == (args.output is not None):
        print("gnss_ins simulate: error: give either --output BAG or --live", file=sys.stderr)
        return 2
    if args.truth_output is not None and not args.live:
        print(
            "gnss_ins simulate: error: --truth-output is for --live (a bag holds the truth anyway)",
            file=sys.stderr,
        )
        return 2
    if args.hold and not args.live:
        print("gnss_ins simulate: error: --hold is for --live", file=sys.stderr)
        return 2
    if args.live and (args.imu_rate is not None or args.gnss_rate is not None):
        print(
            "gnss_ins simulate: error: --imu-rate and --gnss-rate are for bags; the emulators"
            " run at their devices' rates",
            file=sys.stderr,
        )
        return 2
    speed_options = (args.speed_rate, args.speed_scale, args.speed_slip_threshold)
    if not args.speed and any(v is not None for v in speed_options):
        print("gnss_ins simulate: error: the --speed-* options need --speed", file=sys.stderr)
        return 2
    if args.live and args.speed:
        print("gnss_ins simulate: error: --speed is for bags (no odometer device)", file=sys.stderr)
        return 2
    try:
        odometer = _odometer(args) if args.speed else None
    except ValueError as exc:
        print(f"gnss_ins simulate: error: {exc}", file=sys.stderr)
        return 2
    config = SimulationConfig(
        scenario=args.scenario,
        duration_s=args.duration,
        imu=args.imu,
        band_limited=args.band_limit,
        gnss=None if args.gnss == "none" else args.gnss,
        adu5=args.adu5,
        outages=tuple(args.outage),
        sky_zones=tuple(args.sky_zone),
        truth_rate_hz=args.truth_rate,
        seed=args.seed,
        start_ns=args.start,
        vibration=args.vibration,
        imu_rate_hz=args.imu_rate,
        gnss_rate_hz=args.gnss_rate,
        odometer=odometer,
    )
    try:
        if args.live:
            return run_live(config, args.truth_output, args.storage, args.hold)
        write_bag(config, args.output, args.storage)
    except (BagError, ValueError) as exc:
        print(f"gnss_ins simulate: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _odometer(args: argparse.Namespace) -> odometer_model.OdometerProfile:
    """The DMI profile with the rate, scale error and slip threshold given (ValueError if
    invalid)."""
    changes = {
        "rate_hz": args.speed_rate,
        "scale_error": args.speed_scale,
        "slip_threshold_m_s2": args.speed_slip_threshold,
    }
    given = {name: value for name, value in changes.items() if value is not None}
    return dataclasses.replace(odometer_model.DMI, **given)


def write_bag(config: SimulationConfig, path: Path, storage: str = "mcap") -> None:
    """Simulate and write the bag at ``path``; print its summary."""
    simulation = Simulation(config)
    with (
        BagWriter(path, storage=storage) as writer,
        Progress("simulate", total=config.duration_s, unit="s") as progress,
    ):
        for topic, msgtype in simulation.topics.items():
            writer.add_topic(topic, msgtype)
        for count, event in enumerate(simulation.stream()):
            writer.write(event.topic, event.log_ns, event.message)
            if count % _PROGRESS_EVERY == 0:
                progress.update((event.log_ns - config.start_ns) / 1e9)
        progress.update(config.duration_s)
    title = (
        f"bag {path} ({storage}): {config.scenario}, {config.duration_s:g} s, imu {config.imu},"
        f" gnss {config.gnss or 'none'}, adu5 {'on' if config.adu5 else 'off'}, seed {config.seed}"
    )
    if config.vibration != "none":
        title += f", vibration {config.vibration}"
    rates = (("imu", config.imu_rate_hz), ("gnss", config.gnss_rate_hz))
    title += "".join(f", {name} at {hz:g} Hz" for name, hz in rates if hz is not None)
    if (dmi := config.odometer) is not None:
        title += (
            f", speed {dmi.name} at {dmi.rate_hz:g} Hz (scale {dmi.scale_error:+.2%},"
            f" slip above {dmi.slip_threshold_m_s2:g} m/s²)"
        )
    print(writer.summary.format(title))


# --------------------------------------------------------------------------------------------
# Live mode
# --------------------------------------------------------------------------------------------


class LiveImu:
    """Source of the IMU400CC emulator: truth plus the IMU error model at simulation time
    t = device time + offset, with the offset (start of the device clock on the host clock
    minus the simulation start) measured on the first packet the emulator sends. The vibration
    (if any) runs on the device's own sample grid at the emulator's rate, its amplitude
    following the speed at t."""

    def __init__(self, simulation: Simulation, start_s: float, offset_s: float) -> None:
        """``start_s``: host time of simulation time 0 [s]; ``offset_s``: first guess."""
        self._model = simulation.imu_model
        duration = simulation.config.duration_s
        vehicle = simulation.vehicle
        rate_hz = EmulatorConfig().rate_hz
        self._vibration = Vibration(
            simulation.vibration_profile, rate_hz, simulation.vibration_seed
        )

        def truths(t: FloatArray) -> list[tuple[FloatArray, FloatArray, float]]:
            # Times clipped to the drive: the vehicle holds its final state after it.
            truth = vehicle.imu(np.clip(t, 0.0, duration))
            speed = np.linalg.norm(truth.vel_ned_m_s, axis=1).tolist()
            return list(
                zip(truth.rate_flu_rad_s, truth.specific_force_flu_m_s2, speed, strict=True)
            )

        self._truth = TruthCache(
            truths,
            lambda t: truths(np.array([t]))[0],
            ahead=np.arange(round(rate_hz)) / rate_hz,  # one second of streamed samples
        )
        self._start_s = start_s
        self.offset_s = offset_s
        self._measured = False
        self._first_device_s = math.nan

    def __call__(self, device_s: float) -> tuple[FloatArray, FloatArray]:
        if math.isnan(self._first_device_s):
            self._first_device_s = device_s
        t = device_s + self.offset_s
        rate, force, speed = self._truth(t)
        if not self._vibration.profile.silent:
            vibration_rate, vibration_force = self._vibration.sample(np.array([device_s]), speed)
            rate, force = rate + vibration_rate[0], force + vibration_force[0]
        measured_rate, measured_force = self._model.apply(np.array([t]), rate[None], force[None])
        return measured_rate[0], measured_force[0]

    def on_packet(self, packet: SentPacket) -> None:
        """Emulator callback (its thread, once the packets of its samples were written). The
        first is the first sample's: a late emulator thread asks for several samples before it
        writes them, so the offset is measured against the first sample's device time."""
        if not self._measured:
            self.offset_s = packet.sample_wall_s - self._start_s - self._first_device_s
            self._measured = True


class LiveGnss:
    """Source of a GNSS emulator: the receiver error model's epoch at UTC time u, i.e. at
    simulation time u - start. Sets the emulator's per-epoch fix quality, satellites, HDOP and
    accuracy, and reports a lost fix (the emulators take no fix quality from their source)."""

    def __init__(
        self,
        model: GnssErrorModel,
        base_config: GnssEmulatorConfig,
        start_s: float,
        duration_s: float,
    ) -> None:
        """``base_config``: the emulator's configuration, changed per epoch."""
        self._model = model
        self._base_config = base_config
        self._start_s = start_s
        self._duration_s = duration_s
        self.device: GnssEmulator | None = None

    def __call__(self, utc_s: float) -> Truth:
        device = self.device
        assert device is not None
        t = utc_s - self._start_s
        half_period = 0.5 / self._model.profile.rate_hz
        epoch = None
        if t < self._duration_s:
            epoch = next(iter(self._model.epochs(t - half_period, t + half_period)), None)
        if epoch is None or epoch.fix is None:
            device.lose_fix(1)
            return emulator_truth(None)
        device.config = epoch_config(self._base_config, epoch)
        return emulator_truth(epoch.fix)


def run_live(
    config: SimulationConfig, truth_output: Path | None, storage: str = "mcap", hold: bool = False
) -> int:
    """Run the emulators in real time until the duration ends (with ``hold``: until a stop
    signal after it) or a stop signal."""
    start_s = time.time()
    simulation = Simulation(dataclasses.replace(config, start_ns=round(start_s * 1e9)))
    temperature = float(simulation.imu_model.temperature_c(np.array([0.0]))[0])
    imu_source = LiveImu(simulation, start_s, time.time() - start_s)
    with contextlib.ExitStack() as stack:
        imu = stack.enter_context(
            Imu400ccEmulator(
                imu_source,
                EmulatorConfig(temperature_c=temperature),
                on_packet=imu_source.on_packet,
            )
        )
        ports = [("imu", imu.path)]
        gnss_devices: list[GnssEmulator] = []
        for receiver, model in simulation.receivers:
            source = LiveGnss(model, receiver.config, start_s, config.duration_s)
            source.device = device = GnssEmulator(source, receiver.config)
            stack.enter_context(device)
            gnss_devices.append(device)
            ports.append(("adu5" if receiver.receiver is Receiver.ADU5 else "gnss", device.path))
        writer = None
        if truth_output is not None:
            writer = stack.enter_context(BagWriter(truth_output, storage=storage))
            ports.append(("truth", str(truth_output)))
        for name, path in ports:
            print(f"{name}: {path}", flush=True)
        progress = stack.enter_context(Progress("live", total=config.duration_s, unit="s"))
        # Ctrl-C and SIGTERM end the run (also when started in the background, where the shell
        # leaves SIGINT ignored).
        done = threading.Event()
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda *_: done.set())
        written_s = 0.0
        while not done.wait(_LIVE_TICK_S):
            now_s = min(time.time() - start_s, config.duration_s)
            if writer is not None:
                for event in simulation.truth_events(written_s, now_s):
                    writer.write(event.topic, event.log_ns, event.message)
            written_s = now_s
            progress.update(now_s)
            if now_s >= config.duration_s:
                break
        if hold and not done.is_set():
            print("drive ended", flush=True)
            done.wait()
    sent = [f"imu {imu.packets_sent} packets"]
    sent += [f"{d.config.receiver.value} {d.epochs_sent} epochs" for d in gnss_devices]
    print(f"sent: {', '.join(sent)}", flush=True)
    if writer is not None:
        print(writer.summary.format(f"truth bag {truth_output} ({storage})"))
    return 0
