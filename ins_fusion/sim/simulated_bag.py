"""A simulated drive written as a rosbag2 bag: what imu400cc_node and gnss_node would publish,
each message at its receive time, and the truth (ins_fusion/sim/drive.py lists topics, frames and
stamps); ``gnss_ins simulate``'s bag mode, and the drives of tests and benchmarks."""

from __future__ import annotations

from pathlib import Path

from ins_fusion.bags.bag_io import BagWriter
from ins_fusion.runtime.progress import Progress
from ins_fusion.sim.drive import Simulation, SimulationConfig

#: Messages written between progress-bar updates.
_PROGRESS_EVERY = 2000


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
