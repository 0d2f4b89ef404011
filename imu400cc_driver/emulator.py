"""An emulated Crossbow IMU400CC-100 on a pseudo-terminal.

It behaves like the device as far as the driver can tell (imu400cc-aalborg-notes.md §2): it powers
up in polled mode and silent, answers the single-character commands, streams 18-byte scaled-sensor
packets at 134 Hz after 'C' with the real down-counting 16-bit timer (~0.793 us/tick, optionally
drifting), sends one packet per 'G', switches to voltage mode on 'r', and takes its sample values
from a callable (so the simulator can drive it). Each packet is written when its last byte would
have left a 38400-baud wire (sample time + 4.6875 ms). Faults are injected on demand: corrupted
and dropped packets, garbage bytes, silence, a pulled cable (the device powers up again, in
polled mode, when it is plugged back), a power-cycle on a plugged cable, and noise on the line.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.pty_device import PtyEmulator
from gnss_ins_common.rates import IMU400CC_RATE_HZ
from imu400cc_driver.axes import DEFAULT_AXIS_SPEC, measurement_to_packet
from imu400cc_driver.device_clock import NOMINAL_TICK_S, PACKET_TRANSMISSION_S
from imu400cc_driver.protocol import (
    PACKET_LENGTH,
    Command,
    RawPacket,
    Scaling,
    encode_packet,
    encode_serial_number_reply,
    encode_version_reply,
)

#: (time since start [s]) -> (angular rate, specific force), both in imu_link FLU, SI units.
ImuSource = Callable[[float], tuple[np.ndarray, np.ndarray]]

#: Per-sample noise of the unit at rest, (7.14) in the notes §1.3 (rad/s and m/s^2).
_REST_GYRO_SIGMA = np.array([0.0041, 0.0040, 0.0048])
_REST_ACCEL_SIGMA = np.array([0.0029, 0.0038, 0.0036])
_STANDARD_GRAVITY = 9.80665
#: Interval between the bursts of ``line_noise`` [s].
_NOISE_PERIOD_S = 0.02


def resting_source(seed: int = 0, noise: bool = True) -> ImuSource:
    """A level unit at rest: (0, 0, +g) specific force and zero rate, plus (7.14) white noise."""
    rng = np.random.default_rng(seed)
    gravity = np.array([0.0, 0.0, _STANDARD_GRAVITY])

    def sample(_t: float) -> tuple[np.ndarray, np.ndarray]:
        if not noise:
            return np.zeros(3), gravity.copy()
        return rng.normal(0.0, _REST_GYRO_SIGMA), gravity + rng.normal(0.0, _REST_ACCEL_SIGMA)

    return sample


@dataclass(frozen=True)
class EmulatorConfig:
    """Device properties of the emulated unit."""

    rate_hz: float = IMU400CC_RATE_HZ
    tick_s: float = NOMINAL_TICK_S
    clock_drift_ppm: float = 0.0
    temperature_c: float = 25.0
    scaling: Scaling = field(default_factory=Scaling)
    axis_spec: tuple[str, str, str] = DEFAULT_AXIS_SPEC
    accel_sign: float = -1.0
    serial_number: int = 1040201
    version: str = "IMU400CC-100 v1.0 (gnss_ins emulator)"
    initial_timer: int = 41606
    #: Answer the commands the Aalborg report does not document ('R', 'c', 'r', 'v', 'S').
    answer_external_commands: bool = True


@dataclass(frozen=True)
class SentPacket:
    """What the emulator sent: timer field, true sample time and write time (wall clock, s)."""

    timer: int
    sample_wall_s: float
    written_wall_s: float


class Imu400ccEmulator(PtyEmulator):
    """A running emulated IMU400CC on a pty; ``path`` is what the driver opens."""

    thread_name = "imu400cc-emulator"

    def __init__(
        self,
        source: ImuSource | None = None,
        config: EmulatorConfig | None = None,
        *,
        link_path: str | None = None,
        on_packet: Callable[[SentPacket], None] | None = None,
    ) -> None:
        """``on_packet(SentPacket)`` is called after each packet is written."""
        super().__init__(link_path)
        self.config = config or EmulatorConfig()
        self._source = source or resting_source()
        self._axis_map = AxisMap.from_spec(list(self.config.axis_spec))
        self._on_packet = on_packet
        self._wall_minus_monotonic = time.time() - time.monotonic()
        self.commands: Counter[str] = Counter()
        self.packets_sent = 0
        self._corrupt_next = 0
        self._drop_next = 0
        self._silent_until = 0.0
        self._noise_bytes_per_s = 0.0
        self._noise_rng = np.random.default_rng(0)
        self._noise_due = 0.0
        self._power_up()

    @property
    def streaming(self) -> bool:
        """True in continuous mode."""
        return self._streaming

    # ---- faults -----------------------------------------------------------------------------
    def corrupt_packets(self, count: int = 1) -> None:
        """Flip one payload byte in each of the next ``count`` packets (bad checksum)."""
        with self._lock:
            self._corrupt_next += count

    def drop_packets(self, count: int = 1) -> None:
        """Do not send the next ``count`` packets (the timer keeps running)."""
        with self._lock:
            self._drop_next += count

    def send_garbage(self, data: bytes) -> None:
        """Write arbitrary bytes between packets right now."""
        self.pty.write(data)

    def go_silent(self, seconds: float) -> None:
        """Send nothing for ``seconds`` (a stalled stream; the device keeps sampling)."""
        with self._lock:
            self._silent_until = time.monotonic() + seconds

    def power_cycle(self) -> None:
        """The unit loses power and restarts on a plugged cable: polled mode, silent."""
        with self._lock:
            self._power_up()

    def line_noise(self, bytes_per_s: float, seed: int = 0) -> None:
        """Random bytes on the device-to-host line from now on (0 stops them), in bursts
        every 20 ms between packets."""
        with self._lock:
            self._noise_bytes_per_s = bytes_per_s
            self._noise_rng = np.random.default_rng(seed)
            self._noise_due = time.monotonic()

    def unplug(self) -> None:
        """Pull the cable: the port disappears and the device loses power."""
        self.pty.close_port()

    def plug(self) -> None:
        """Plug the cable back: a new pty on the same path, the device freshly powered up."""
        with self._lock:
            self._power_up()
        self.pty.reopen_port()

    # ---- device behaviour -------------------------------------------------------------------
    def _power_up(self) -> None:
        # Same convention as DeviceClock.drift_ppm: positive means the device clock runs slow.
        self._host_per_device = 1.0 + self.config.clock_drift_ppm * 1e-6
        self._streaming = False
        self._voltage_mode = False
        self._start_monotonic = time.monotonic()
        self._next_index = 0
        self._pending_polls: list[float] = []

    def _device_time(self, monotonic_s: float) -> float:
        """Device-oscillator time since power-up for a host monotonic time [s]."""
        return (monotonic_s - self._start_monotonic) / self._host_per_device

    def _host_time_of(self, device_time_s: float) -> float:
        return self._start_monotonic + device_time_s * self._host_per_device

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            deadline = now + (0.05 if self._noise_bytes_per_s <= 0 else _NOISE_PERIOD_S)
            if self._streaming:
                deadline = min(deadline, self._next_write_time())
            if self._pending_polls:
                deadline = min(deadline, self._pending_polls[0])
            for byte in self.pty.read(deadline - now):
                self._handle_command(chr(byte))
            self._emit_due()
            self._emit_noise(time.monotonic())

    def _emit_noise(self, now: float) -> None:
        with self._lock:
            if self._noise_bytes_per_s <= 0 or now < self._noise_due:
                return
            count = max(1, round(self._noise_bytes_per_s * _NOISE_PERIOD_S))
            noise = self._noise_rng.integers(0, 256, count, dtype=np.uint8).tobytes()
            self._noise_due = now + _NOISE_PERIOD_S
        self.pty.write(noise)

    def _next_write_time(self) -> float:
        sample_device_time = self._next_index / self.config.rate_hz
        return self._host_time_of(sample_device_time) + PACKET_TRANSMISSION_S

    def _next_due(self, now: float) -> float | None:
        """Device time [s] of the next sample whose packet is due by ``now`` (taken off the
        schedule), or None."""
        if self._pending_polls and self._pending_polls[0] <= now:
            return self._device_time(self._pending_polls.pop(0) - PACKET_TRANSMISSION_S)
        if self._streaming and self._next_write_time() <= now:
            self._next_index += 1
            return (self._next_index - 1) / self.config.rate_hz
        return None

    def _emit_due(self) -> None:
        """Write the due packets in one go, the clock read again after each one: a thread that
        woke late, or was preempted while it built them (a loaded machine), hands the host all
        it owes at once, as a UART's receive buffer would hold it, not stale packets first and
        the rest on later wake-ups."""
        sent: list[tuple[int, float]] = []  # (timer, device time [s]) of the packets written
        wire = bytearray()
        while (device_time_s := self._next_due(time.monotonic())) is not None:
            timer = (self.config.initial_timer - round(device_time_s / self.config.tick_s)) % 65536
            packet = encode_packet(self._sample_packet(device_time_s, timer))
            with self._lock:
                if self._drop_next > 0:
                    self._drop_next -= 1
                    continue
                if time.monotonic() < self._silent_until:
                    continue
                if self._corrupt_next > 0:
                    self._corrupt_next -= 1
                    packet = packet[:5] + bytes([packet[5] ^ 0x5A]) + packet[6:]
            wire += packet
            sent.append((timer, device_time_s))
        if not wire:
            return
        complete = sent[: self.pty.write(bytes(wire)) // PACKET_LENGTH]
        written = time.time()
        self.packets_sent += len(complete)
        if self._on_packet is not None:
            for timer, device_time_s in complete:
                sample = self._host_time_of(device_time_s) + self._wall_minus_monotonic
                self._on_packet(SentPacket(timer, sample, written))

    def _sample_packet(self, device_time_s: float, timer: int) -> RawPacket:
        rate, force = self._source(device_time_s)
        cfg = self.config
        packet = measurement_to_packet(
            np.asarray(rate, dtype=float),
            np.asarray(force, dtype=float),
            cfg.temperature_c,
            timer,
            cfg.scaling,
            self._axis_map,
            cfg.accel_sign,
        )
        if not self._voltage_mode:
            return packet
        # Voltage mode: 12-bit counts around mid-scale 2.5 V, +-2 V at full range (emulator only).
        volts = [2048 + round(c / 32768 * 1638) for c in (*packet.rates, *packet.accels)]
        return RawPacket(
            rates=(volts[0], volts[1], volts[2]),
            accels=(volts[3], volts[4], volts[5]),
            temperature=packet.temperature,
            timer=timer,
        )

    def _handle_command(self, char: str) -> None:
        self.commands[char] += 1
        try:
            command = Command(char)
        except ValueError:
            return  # the unit ignores unknown characters
        if command.unverified and not self.config.answer_external_commands:
            return
        if command.reply is not None:
            self.pty.write(command.reply)
        match command:
            case Command.CONTINUOUS if not self._streaming:
                self._streaming = True
                now_device = self._device_time(time.monotonic())
                self._next_index = int(now_device * self.config.rate_hz) + 1
            case Command.POLLED:
                self._streaming = False
            case Command.GET_PACKET:
                self._pending_polls.append(time.monotonic() + PACKET_TRANSMISSION_S)
            case Command.SCALED_MODE | Command.VOLTAGE_MODE:
                self._voltage_mode = command is Command.VOLTAGE_MODE
            case Command.VERSION:
                self.pty.write(encode_version_reply(self.config.version))
            case Command.SERIAL_NUMBER:
                self.pty.write(encode_serial_number_reply(self.config.serial_number))
