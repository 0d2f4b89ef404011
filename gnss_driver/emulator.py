"""An emulated Leica GPS System 500 RTK rover or Thales/Ashtech ADU5 on a pseudo-terminal.

As far as the driver can tell it is the receiver (imu400cc-aalborg-notes.md §7.2, §7.3):

- ``leica``: one epoch per second at 9600 baud, in the report's order VTG, GGA, LLQ, then the
  optional GST, RMC, ZDA; RTK-fixed quality, the coordinate quality of the nominal 2 cm + 3 cm;
  commands are ignored (the rover is set up on its own keyboard). With ``rtk_from_corrections``
  the rover's solution follows the RTCM 3 corrections written to it (``emulated_rtk``): RTK
  fixed while valid frames arrived within ``rtk_hold_s``, RTK float for ``float_hold_s`` after
  that, then standalone (also from the start until the first frame), each with its position
  error, coordinate quality, GST sigmas and mode letters.
- ``adu5``: ``$PASHR,PAT`` (optionally also ``$PASHR,ATT``) five times a second; answers each
  ``$PASHS`` / ``$PASHQ`` line with ``$PASHR,ACK*3D`` or ``$PASHR,NAK*30`` and applies the
  offset angles (``3DF,OFS``), the output period (``NME,PER``) and PAT on/off (``NME,PAT``).
  The antenna frame may be mounted with an offset to the vehicle (``mount_offsets_deg``); the
  output removes the offsets it was told, as the receiver does.

Epochs fall on whole multiples of the period of UTC, taken as the host's ``time.time()``; each
sentence is written when its last byte would have left the wire: epoch + ``output_latency_s`` +
bytes so far x 10 / baud. Values come from a callable giving the true state at a UTC time, so a
simulator can drive it. Faults on demand: bad checksums, cut lines, garbage, fix loss, an outlier
jump, attitude resets, degraded attitude quality, silence and a pulled cable.
"""

from __future__ import annotations

import dataclasses
import datetime
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import pymap3d

from gnss_driver.attitude import brf_angles, brf_rotation
from gnss_driver.driver import BITS_PER_CHARACTER, GPS_UTC_LEAP_S
from gnss_driver.emulated_rtk import RoverCorrections
from gnss_driver.profiles import PROFILES, Receiver
from gnss_driver.reader import frame_sentence
from gnss_driver.utc import SECONDS_PER_WEEK
from gnss_ins_common.pty_device import PtyEmulator

_KNOTS_PER_M_S = 3600.0 / 1852.0
#: GPS time 0, 1980-01-06T00:00:00Z, in Unix seconds.
_GPS_EPOCH_UNIX_S = 315_964_800
ACK = frame_sentence("PASHR,ACK")
NAK = frame_sentence("PASHR,NAK")
#: GGA quality -> RMC mode letter (NMEA 2.3+; R, F: RTK fixed, float, NMEA 4.1).
_RMC_MODE = {1: "A", 2: "D", 4: "R", 5: "F"}


@dataclass(frozen=True)
class Truth:
    """True state of the vehicle: antenna position (degrees, metres above the WGS-84 ellipsoid),
    velocity in ENU [m/s] and attitude as ADU5 angles of the vehicle [deg]."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    vel_enu_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    heading_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0


#: UTC [s since 1970] -> the true state at that time.
TruthSource = Callable[[float], Truth]

#: Aalborg, about where the report's test drives ran: 57.0° N, 9.97° E, 50 m.
AALBORG_LLH = (57.0148, 9.9865, 50.0)


def constant_velocity(
    vel_enu_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0),
    origin_llh: tuple[float, float, float] = AALBORG_LLH,
    start_utc_s: float | None = None,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
) -> TruthSource:
    """A vehicle moving straight at a constant ENU velocity from ``origin_llh`` at
    ``start_utc_s`` (default: when first asked), heading along its velocity (north at rest)."""
    east, north, _ = vel_enu_m_s
    heading = math.degrees(math.atan2(east, north)) % 360.0 if east or north else 0.0
    start: list[float] = [] if start_utc_s is None else [start_utc_s]

    def truth(utc_s: float) -> Truth:
        if not start:
            start.append(utc_s)
        dt = utc_s - start[0]
        lat, lon, alt = pymap3d.enu2geodetic(
            vel_enu_m_s[0] * dt, vel_enu_m_s[1] * dt, vel_enu_m_s[2] * dt, *origin_llh
        )
        return Truth(float(lat), float(lon), float(alt), vel_enu_m_s, heading, pitch_deg, roll_deg)

    return truth


@dataclass(frozen=True)
class EmulatorConfig:
    """What the emulated receiver sends. ``None`` rate/baud: the profile's."""

    receiver: Receiver = Receiver.LEICA
    rate_hz: float | None = None
    baud: int | None = None
    output_latency_s: float = 0.02
    #: Geoid height above the ellipsoid for GGA (about 40 m around Aalborg) [m].
    geoid_separation_m: float = 40.0
    #: Optional Leica sentences after VTG, GGA, LLQ: any of "GST", "RMC", "ZDA".
    leica_extra: tuple[str, ...] = ()
    fix_quality: int = 4
    hdop: float = 0.8
    satellites: int = 12
    #: LLQ coordinate quality: the nominal 2 cm horizontal + 3 cm vertical (notes §7.2) [m].
    coordinate_quality_m: float = 0.05
    #: GST sigmas (latitude, longitude, altitude) [m].
    gst_sigmas_m: tuple[float, float, float] = (0.014, 0.014, 0.03)
    adu5_att: bool = False
    mrms_m: float = 0.002
    brms_m: float = 0.010
    #: True attitude of the antenna frame relative to the vehicle (heading, pitch, roll) [deg].
    mount_offsets_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: Offsets stored in the receiver at power-up (changed by $PASHS,3DF,OFS) [deg].
    receiver_offsets_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gps_utc_leap_s: int = GPS_UTC_LEAP_S
    #: False: the ADU5 records commands but never answers or applies them.
    answer_commands: bool = True
    #: Leica: the solution follows the RTCM 3 frames written to the port (module docstring).
    rtk_from_corrections: bool = False
    #: RTK fixed while the last valid frame arrived at most this long ago [s].
    rtk_hold_s: float = 2.0
    #: Then RTK float for this long, then standalone [s].
    float_hold_s: float = 10.0
    #: Seed of the float and standalone position errors.
    seed: int = 0


@dataclass
class _Faults:
    corrupt: int = 0
    cut: int = 0
    no_fix_epochs: int = 0
    jump_epochs: int = 0
    jump_north_m: float = 0.0
    attitude_resets: int = 0
    degraded_epochs: int = 0
    silent_until: float = 0.0


@dataclass
class _Adu5State:
    offsets_deg: tuple[float, float, float]
    period_s: float
    pat_on: bool = True
    commands: list[str] = field(default_factory=list)


def _time_of_day(utc_s: float) -> str:
    t = datetime.datetime.fromtimestamp(round(utc_s, 2), datetime.UTC)
    return f"{t:%H%M%S}.{t.microsecond // 10000:02d}"


def _angle(value_deg: float, degree_digits: int, decimals: int, signs: str) -> str:
    """``ddmm.mmmm,N``-style field pair; ``signs`` = positive and negative hemisphere letters."""
    minutes_total = round(abs(value_deg) * 60.0, decimals)
    degrees, minutes = divmod(minutes_total, 60.0)
    width = 3 + decimals
    hemisphere = signs[0] if value_deg >= 0.0 else signs[1]
    return f"{int(degrees):0{degree_digits}d}{minutes:0{width}.{decimals}f},{hemisphere}"


def _lat_lon(truth: Truth, decimals: int) -> str:
    return f"{_angle(truth.lat_deg, 2, decimals, 'NS')},{_angle(truth.lon_deg, 3, decimals, 'EW')}"


def _course_speed(vel_enu_m_s: tuple[float, float, float]) -> tuple[float, float]:
    """(course over ground [deg from north], speed [m/s])."""
    east, north, _ = vel_enu_m_s
    return math.degrees(math.atan2(east, north)) % 360.0, math.hypot(east, north)


def leica_sentences(utc_s: float, truth: Truth, cfg: EmulatorConfig, fix: bool) -> list[str]:
    """Bodies (no ``$``, no checksum) of one Leica epoch."""
    tod = _time_of_day(utc_s)
    date = datetime.datetime.fromtimestamp(utc_s, datetime.UTC)
    course, speed = _course_speed(truth.vel_enu_m_s)
    if not fix:
        return [
            "GPVTG,,T,,M,,N,,K,N",
            f"GPGGA,{tod},,,,,0,{cfg.satellites:02d},99.9,,,,,,",
            f"GPLLQ,{tod},{date:%m%d%y},,M,,M,0,{cfg.satellites:02d},,,M",
        ]
    mode = "D" if cfg.fix_quality > 1 else "A"
    rmc_mode = _RMC_MODE.get(cfg.fix_quality, mode)
    llq_quality = {4: 3, 5: 2}.get(cfg.fix_quality, 1)
    msl = truth.alt_m - cfg.geoid_separation_m
    differential = "1.0,0001" if cfg.fix_quality > 1 else ","  # correction age [s], station
    bodies = [
        f"GPVTG,{course:05.1f},T,,M,{speed * _KNOTS_PER_M_S:06.2f},N,{speed * 3.6:06.2f},K,{mode}",
        f"GPGGA,{tod},{_lat_lon(truth, 7)},{cfg.fix_quality},{cfg.satellites:02d},"
        f"{cfg.hdop:.1f},{msl:.3f},M,{cfg.geoid_separation_m:.3f},M,{differential}",
        f"GPLLQ,{tod},{date:%m%d%y},,M,,M,{llq_quality},{cfg.satellites:02d},"
        f"{cfg.coordinate_quality_m:.3f},{truth.alt_m:.3f},M",
    ]
    s_lat, s_lon, s_alt = cfg.gst_sigmas_m
    extra = {
        "GST": f"GPGST,{tod},0.010,{s_lat:.3f},{s_lon:.3f},0.0,{s_lat:.3f},{s_lon:.3f},{s_alt:.3f}",
        "RMC": f"GPRMC,{tod},A,{_lat_lon(truth, 7)},{speed * _KNOTS_PER_M_S:.2f},{course:.1f},"
        f"{date:%d%m%y},,,{rmc_mode}",
        "ZDA": f"GPZDA,{tod},{date:%d},{date:%m},{date:%Y},00,00",
    }
    return bodies + [extra[name] for name in cfg.leica_extra]


def adu5_sentences(
    utc_s: float,
    truth: Truth,
    cfg: EmulatorConfig,
    offsets_deg: tuple[float, float, float],
    reset_flag: int,
    mrms_m: float,
    fix: bool = True,
) -> list[str]:
    """Bodies of one ADU5 epoch; the angles are the antenna frame's minus ``offsets_deg``.
    Without a fix the position fields are empty and the reset flag is 1."""
    tod = _time_of_day(utc_s)
    if not fix:
        return [f"PASHR,PAT,{tod},,,,,,,,,,,1"]
    r_enu_antenna = brf_rotation(truth.heading_deg, truth.pitch_deg, truth.roll_deg) * (
        brf_rotation(*cfg.mount_offsets_deg)
    )
    heading, pitch, roll = brf_angles(r_enu_antenna * brf_rotation(*offsets_deg).inv())
    attitude = (
        f"{heading:07.3f},{pitch:+06.2f},{roll:+06.2f},{mrms_m:.4f},{cfg.brms_m:.4f},{reset_flag}"
    )
    bodies = [f"PASHR,PAT,{tod},{_lat_lon(truth, 4)},{truth.alt_m:+09.2f},{attitude}"]
    if cfg.adu5_att:
        tow = (utc_s - _GPS_EPOCH_UNIX_S + cfg.gps_utc_leap_s) % SECONDS_PER_WEEK
        bodies.append(f"PASHR,ATT,{tow:.1f},{attitude}")
    return bodies


_ADU5_COMMAND = re.compile(
    r"\$PASHS,(RST|ELM,\d{1,2}|3DF,V1[234],[-+.\d]+,[-+.\d]+,[-+.\d]+"
    r"|3DF,OFS,([-+.\d]+),([-+.\d]+),([-+.\d]+)|NME,PER,([.\d]+)|NME,PAT,[AB],(ON|OFF))"
)


def _shifted(truth: Truth, east_m: float, north_m: float, up_m: float) -> Truth:
    """``truth`` with its position moved by ENU metres."""
    lat, lon, alt = pymap3d.enu2geodetic(
        east_m, north_m, up_m, truth.lat_deg, truth.lon_deg, truth.alt_m
    )
    return dataclasses.replace(truth, lat_deg=float(lat), lon_deg=float(lon), alt_m=float(alt))


class GnssEmulator(PtyEmulator):
    """A running emulated receiver on a pty; ``path`` is what the driver opens."""

    thread_name = "gnss-emulator"

    def __init__(
        self,
        source: TruthSource | None = None,
        config: EmulatorConfig | None = None,
        *,
        link_path: str | None = None,
        on_epoch: Callable[[float, Truth], None] | None = None,
    ) -> None:
        """``on_epoch(utc_s, truth)`` is called after each epoch's last sentence was written."""
        super().__init__(link_path)
        self.config = config or EmulatorConfig()
        profile = PROFILES[self.config.receiver]
        self.baud = self.config.baud or profile.baud
        self._source = source or constant_velocity()
        self._on_epoch = on_epoch
        self.epochs_sent = 0
        self._faults = _Faults()
        self._degraded_mrms_m = self.config.mrms_m
        self._adu5 = _Adu5State(
            offsets_deg=self.config.receiver_offsets_deg,
            period_s=1.0 / (self.config.rate_hz or profile.rate_hz),
        )
        self._line = bytearray()
        cfg = self.config
        self._rtk = (
            RoverCorrections(cfg.rtk_hold_s, cfg.float_hold_s, cfg.seed)
            if cfg.rtk_from_corrections
            else None
        )

    @property
    def rtcm_received(self) -> bytes:
        """With ``rtk_from_corrections``: the whole valid RTCM 3 frames received, in order."""
        return b"" if self._rtk is None else self._rtk.received

    @property
    def rtcm_frames(self) -> int:
        """With ``rtk_from_corrections``: valid RTCM 3 frames received."""
        return 0 if self._rtk is None else self._rtk.frames

    @property
    def commands(self) -> list[str]:
        """Command lines received so far."""
        with self._lock:
            return list(self._adu5.commands)

    @property
    def offsets_deg(self) -> tuple[float, float, float]:
        """The offset angles the receiver currently removes (heading, pitch, roll) [deg]."""
        return self._adu5.offsets_deg

    # ---- faults -----------------------------------------------------------------------------
    def corrupt_checksums(self, count: int = 1) -> None:
        """Send the next ``count`` sentences with a wrong checksum."""
        with self._lock:
            self._faults.corrupt += count

    def cut_lines(self, count: int = 1) -> None:
        """Send only the first half of each of the next ``count`` sentences, without CR LF."""
        with self._lock:
            self._faults.cut += count

    def send_garbage(self, data: bytes) -> None:
        """Write arbitrary bytes right now."""
        self.pty.write(data)

    def lose_fix(self, epochs: int) -> None:
        """No position for ``epochs`` epochs (empty fields, quality 0, PAT reset flag 1)."""
        with self._lock:
            self._faults.no_fix_epochs += epochs

    def jump(self, epochs: int, north_m: float) -> None:
        """Report positions ``north_m`` north of the truth for ``epochs`` epochs (an outlier)."""
        with self._lock:
            self._faults.jump_epochs, self._faults.jump_north_m = epochs, north_m

    def reset_attitude(self, epochs: int) -> None:
        """ADU5: set the PAT reset flag for ``epochs`` epochs."""
        with self._lock:
            self._faults.attitude_resets += epochs

    def degrade_attitude(self, epochs: int, mrms_m: float = 0.012) -> None:
        """ADU5: report MRMS ``mrms_m`` (above the 5 mm limit) for ``epochs`` epochs."""
        with self._lock:
            self._faults.degraded_epochs = epochs
            self._degraded_mrms_m = mrms_m

    def go_silent(self, seconds: float) -> None:
        """Send nothing for ``seconds`` (the receiver keeps running)."""
        with self._lock:
            self._faults.silent_until = time.time() + seconds

    def unplug(self) -> None:
        """Pull the cable: the port disappears."""
        self.pty.close_port()

    def plug(self) -> None:
        """Plug the cable back: a new pty on the same path."""
        if self._rtk is not None:
            self._rtk.reset()
        self.pty.reopen_port()

    # ---- receiver behaviour -----------------------------------------------------------------
    def _period_s(self) -> float:
        return self._adu5.period_s

    def _run(self) -> None:
        epoch = math.ceil(time.time() / self._period_s()) * self._period_s()
        while not self._stop.is_set():
            utc_s = epoch
            start = utc_s + self.config.output_latency_s
            self._serve_until(start)
            truth = self._source(utc_s)
            pieces = self._epoch_bytes(utc_s, truth)
            wire = 0
            for data in pieces:
                wire += len(data)
                self._serve_until(start + wire * BITS_PER_CHARACTER / self.baud)
                if self._stop.is_set():
                    return
                self._write(data)
            if pieces and self._on_epoch is not None:
                self._on_epoch(utc_s, truth)
            period = self._period_s()
            epoch = max(epoch + period, math.floor(time.time() / period) * period)
            epoch = round(epoch / period) * period

    def _serve_until(self, due: float) -> None:
        """Answer commands (and take corrections) until host time ``due``."""
        while (remaining := due - time.time()) > 0 and not self._stop.is_set():
            if not self.pty.is_open:
                time.sleep(min(remaining, 0.05))
                continue
            data = self.pty.read(min(remaining, 0.05))
            if self._rtk is not None and data:
                data = self._rtk.take(data, time.time())
            for byte in data:
                if byte in (0x0D, 0x0A):
                    if self._line:
                        self._command(self._line.decode("ascii", "replace"))
                    self._line.clear()
                elif len(self._line) < 200:
                    self._line.append(byte)

    def _solution(self, truth: Truth) -> tuple[EmulatorConfig, Truth]:
        """With ``rtk_from_corrections``: the configuration of the solution the corrections allow
        now and the position with its error."""
        cfg = self.config
        if self._rtk is None:
            return cfg, truth
        kind, error_enu_m = self._rtk.solution(time.time(), self._period_s())
        if kind is None:
            return cfg, truth
        scale = kind.coordinate_quality_m / cfg.coordinate_quality_m
        s_lat, s_lon, s_alt = cfg.gst_sigmas_m
        solution = dataclasses.replace(
            cfg,
            fix_quality=kind.quality,
            coordinate_quality_m=kind.coordinate_quality_m,
            gst_sigmas_m=(s_lat * scale, s_lon * scale, s_alt * scale),
        )
        return solution, _shifted(truth, *error_enu_m)

    def _command(self, line: str) -> None:
        with self._lock:
            self._adu5.commands.append(line)
        if self.config.receiver is not Receiver.ADU5 or not self.config.answer_commands:
            return
        match = _ADU5_COMMAND.fullmatch(line)
        if match is None:
            self.pty.write(NAK)
            return
        if match.group(2) is not None:
            h, p, r = (float(match.group(i)) for i in (2, 3, 4))
            self._adu5.offsets_deg = (h, p, r)
        if match.group(5) is not None:
            period = float(match.group(5))
            if period <= 0.0:
                self.pty.write(NAK)
                return
            self._adu5.period_s = max(0.2, period)  # fastest 5 Hz (notes §7.3)
        if match.group(6) is not None:
            self._adu5.pat_on = match.group(6) == "ON"
        self.pty.write(ACK)

    def _epoch_bytes(self, utc_s: float, truth: Truth) -> list[bytes]:
        with self._lock:
            faults = self._faults
            fix = faults.no_fix_epochs == 0
            faults.no_fix_epochs = max(0, faults.no_fix_epochs - 1)
            if faults.jump_epochs > 0:
                faults.jump_epochs -= 1
                truth = _shifted(truth, 0.0, faults.jump_north_m, 0.0)
            reset = 1 if faults.attitude_resets > 0 else 0
            faults.attitude_resets = max(0, faults.attitude_resets - 1)
            mrms = self.config.mrms_m
            if faults.degraded_epochs > 0:
                faults.degraded_epochs -= 1
                mrms = self._degraded_mrms_m
        if self.config.receiver is Receiver.ADU5:
            if not self._adu5.pat_on:
                return []
            offsets = self._adu5.offsets_deg
            bodies = adu5_sentences(utc_s, truth, self.config, offsets, reset, mrms, fix)
        else:
            config, truth = self._solution(truth)
            bodies = leica_sentences(utc_s, truth, config, fix)
        return [self._damaged(frame_sentence(body)) for body in bodies]

    def _damaged(self, sentence: bytes) -> bytes:
        with self._lock:
            faults = self._faults
            if faults.corrupt > 0:
                faults.corrupt -= 1
                checksum = int(sentence[-4:-2], 16) ^ 0x5A
                return sentence[:-4] + b"%02X\r\n" % checksum
            if faults.cut > 0:
                faults.cut -= 1
                return sentence[: len(sentence) // 2]
        return sentence

    def _write(self, data: bytes) -> None:
        with self._lock:
            silent = time.time() < self._faults.silent_until
        if silent or self.pty.write(data) < len(data):
            return
        if data.startswith((b"$GPGGA", b"$PASHR,PAT")) and data.endswith(b"\n"):
            self.epochs_sent += 1
