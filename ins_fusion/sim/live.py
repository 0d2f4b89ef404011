"""A simulated drive played live on emulated serial devices, in real time (no ROS).

``gnss_ins simulate --live`` and ``gnss_ins emulate`` run it: the IMU400CC emulator and the GNSS
emulators (the position receiver and the ADU5) on pseudo-terminals take their samples from one
``Simulation``'s truth and error models, so every device reports the same drive. The port paths
are printed first, one line each (``imu: PATH``, ``gnss: PATH``, ``adu5: PATH``), for the real
nodes to open; ``LiveOptions`` chooses the devices, their stable link paths, a truth bag recorded
meanwhile (stamped on the host clock from the start time the emulators use) and what happens at
the end of the drive: the run ends, or with ``hold`` it prints ``drive ended`` and keeps the
devices open (the vehicle parked where the drive ended, the receivers without a fix) until
Ctrl-C / SIGTERM, so that the nodes reading them can be stopped first.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import signal
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gnss_driver.emulator import EmulatorConfig as GnssEmulatorConfig
from gnss_driver.emulator import GnssEmulator, Truth
from gnss_driver.profiles import Receiver
from gnss_ins_common.types import FloatArray
from imu400cc_driver.emulator import EmulatorConfig, Imu400ccEmulator, SentPacket
from ins_fusion.bags.bag_io import BagWriter
from ins_fusion.runtime.progress import Progress
from ins_fusion.sim.drive import Simulation, SimulationConfig
from ins_fusion.sim.gnss_model import GnssErrorModel
from ins_fusion.sim.receivers import emulator_truth, epoch_config
from ins_fusion.sim.vehicle import TruthCache
from ins_fusion.sim.vibration import Vibration

#: How often the live mode writes the truth that became due [s].
_LIVE_TICK_S = 0.1
#: The emulated devices, as the port lines name them: the IMU400CC, the position receiver
#: (the Leica rover's sentences) and the ADU5.
DEVICES = ("imu", "gnss", "adu5")


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


@dataclass(frozen=True)
class LiveOptions:
    """How a drive is played: the ``devices`` (of DEVICES) emulated, each at its ``links`` path
    if given (else a temporary one), the truth bag (None: none) and its storage plugin, ``hold``
    the devices open after the drive, and a progress bar on a terminal."""

    devices: frozenset[str] = frozenset(DEVICES)
    links: Mapping[str, str] = field(default_factory=dict)
    truth_output: Path | None = None
    storage: str = "mcap"
    hold: bool = False
    progress: bool = True


def run_live(config: SimulationConfig, options: LiveOptions) -> int:
    """Run the emulators in real time until the duration ends (with ``options.hold``: until a
    stop signal after it) or a stop signal."""
    start_s = time.time()
    simulation = Simulation(dataclasses.replace(config, start_ns=round(start_s * 1e9)))
    with contextlib.ExitStack() as stack:
        ports: list[tuple[str, str]] = []
        imu = None
        if "imu" in options.devices:
            temperature = float(simulation.imu_model.temperature_c(np.array([0.0]))[0])
            imu_source = LiveImu(simulation, start_s, time.time() - start_s)
            imu = stack.enter_context(
                Imu400ccEmulator(
                    imu_source,
                    EmulatorConfig(temperature_c=temperature),
                    link_path=options.links.get("imu"),
                    on_packet=imu_source.on_packet,
                )
            )
            ports.append(("imu", imu.path))
        gnss_devices: list[GnssEmulator] = []
        for receiver, model in simulation.receivers:
            name = "adu5" if receiver.receiver is Receiver.ADU5 else "gnss"
            if name not in options.devices:
                continue
            source = LiveGnss(model, receiver.config, start_s, config.duration_s)
            source.device = device = GnssEmulator(
                source, receiver.config, link_path=options.links.get(name)
            )
            stack.enter_context(device)
            gnss_devices.append(device)
            ports.append((name, device.path))
        writer = None
        if (truth_output := options.truth_output) is not None:
            writer = stack.enter_context(BagWriter(truth_output, storage=options.storage))
            ports.append(("truth", str(truth_output)))
        for name, path in ports:
            print(f"{name}: {path}", flush=True)
        progress = stack.enter_context(Progress("live", total=config.duration_s, unit="s"))
        progress.enabled = progress.enabled and options.progress
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
        if options.hold and not done.is_set():
            print("drive ended", flush=True)
            done.wait()
    sent = [] if imu is None else [f"imu {imu.packets_sent} packets"]
    sent += [f"{d.config.receiver.value} {d.epochs_sent} epochs" for d in gnss_devices]
    print(f"sent: {', '.join(sent)}", flush=True)
    if writer is not None:
        print(writer.summary.format(f"truth bag {truth_output} ({options.storage})"))
    return 0
