"""One epoch's sentences -> the best fix, velocity and attitude it holds (no ROS).

Position: GGA, else GNS, else PASHR,PAT, else LLQ's grid position when ``llq_projection`` names
its projected CRS (``grid``; height taken as ellipsoidal), else RMC, else GLL. Fix type from GGA
quality (1 SPS, 2 DGPS, 3 PPS, 4 RTK fixed, 5 RTK float), else the best of GNS's per-system mode
letters (R, F, P, D, A), else LLQ quality (1 SPS, 2 RTK float, 3 RTK fixed), else the RMC/GLL
mode letter, else SPS for a PAT position. Quality 0, 6 (dead reckoning), 7 (manual) and 8
(simulator), status 'V', mode 'N' or fewer satellites than ``min_satellites`` (GGA, GNS, LLQ)
are NO_FIX: published as such, with NaN position and no covariance, never a made-up position.
A satellites-used count the receiver did not report, 2-D fixes and the altitude of RMC/GLL
epochs follow ``fix_rules``.

Altitude: height above the WGS-84 ellipsoid = GGA/GNS altitude (mean sea level) + geoid
separation; when the receiver leaves the separation empty, the EGM96 undulation of
``geoid.MODEL`` at the position (counted in ``geoid_altitudes``). PAT's altitude is taken as
ellipsoidal [external: Ashtech's PAT reports the WGS-84 solution; verify on the receiver].

Covariance, ENU [m^2]: GST, else LLQ, else the DOPs (``fix_covariance``).

Velocity: VTG, else RMC: speed and course over ground -> ENU (v_E, v_N, 0); the vertical is
not measured (notes §7.2: no down velocity), so its variance is ``UNKNOWN_VARIANCE``.

Attitude: PASHR,PAT, else PASHR,ATT (see ``attitude``), else HDT (heading only). A reset flag of
1 means "rough estimate or bad attitude" (notes §7.3): not published, counted.
"""

from __future__ import annotations

import datetime
import math
from dataclasses import dataclass, field
from typing import Any

import pynmea2

from gnss_driver import geoid
from gnss_driver.attitude import AttitudeConverter, Orientation
from gnss_driver.epoch import Epoch
from gnss_driver.fix_covariance import LLQ_HORIZONTAL_FRACTION, FixCovariance
from gnss_driver.fix_rules import HeldAltitude, gsa_mode, gsa_satellites, is_2d
from gnss_driver.fix_type import (
    GNS_MODE_RANK,
    LLQ_FIX,
    MODE_FIX,
    NAV_SAT_STATUS,
    VALID_FIX_TYPES,
    FixType,
    gga_fix_type,
    gns_fix_type,
)
from gnss_driver.grid import GridProjection
from gnss_driver.plausibility import KNOTS_TO_M_S, FieldReader
from gnss_driver.sentences import ASHRATT, ASHRPAT, LLQ, sentence_id, text
from gnss_ins_common.message_fields import UNKNOWN_VARIANCE, fill_navsatfix
from gnss_ins_common.navsat import (
    HEIGHT_UNKNOWN_VARIANCE_M2,
    SERVICE_COMPASS,
    SERVICE_GALILEO,
    SERVICE_GLONASS,
    SERVICE_GPS,
    CovarianceType,
    NavSatStatus,
)

#: sensor_msgs/NavSatStatus service bits per NMEA talker; GN (combined), proprietary and
#: unknown talkers name no system, and an epoch naming none is taken as GPS.
_TALKER_SERVICE = {
    "GP": SERVICE_GPS,
    "GL": SERVICE_GLONASS,
    "GB": SERVICE_COMPASS,
    "BD": SERVICE_COMPASS,
    "GA": SERVICE_GALILEO,
}
#: Service bits of the GNS mode letters by position: GPS, GLONASS, Galileo, BeiDou (NMEA 4.10).
_GNS_MODE_SERVICE = (SERVICE_GPS, SERVICE_GLONASS, SERVICE_GALILEO, SERVICE_COMPASS)


@dataclass(frozen=True)
class UereTable:
    """User equivalent range error per fix type [m], 1 sigma, multiplied by the DOPs.

    Defaults: RTK fixed 0.02 m (2 cm horizontal at HDOP ~1, notes §7.2 [KMS 2003]); RTK float
    0.5 m, DGPS 1.0 m [external: typical]; SPS 6.0 m (the (6 m)² fallback of
    gnss-ins-ntnu-notes.md D8 / Table 4.9 at HDOP ~1). PPS uses the SPS value.
    """

    sps: float = 6.0
    dgps: float = 1.0
    rtk_float: float = 0.5
    rtk_fixed: float = 0.02

    def for_fix(self, fix_type: FixType) -> float:
        """UERE [m] of a valid fix type."""
        if fix_type is FixType.RTK_FIXED:
            return self.rtk_fixed
        if fix_type is FixType.RTK_FLOAT:
            return self.rtk_float
        return self.dgps if fix_type is FixType.DGPS else self.sps


@dataclass(frozen=True)
class SolutionConfig:
    """Accuracy model of a receiver."""

    uere: UereTable = UereTable()
    #: 1-sigma of each horizontal velocity component [m/s] (R of (7.15), notes §10).
    velocity_sigma_m_s: float = 0.05
    #: Horizontal share f of the LLQ coordinate quality: σ_h = f·CQ, σ_v = (1 - f)·CQ.
    llq_horizontal_fraction: float = LLQ_HORIZONTAL_FRACTION
    #: Fewer satellites used than this make a fix NO_FIX (a 3-D fix needs 4).
    min_satellites: int = 4
    #: Projected CRS of LLQ's grid position (e.g. "EPSG:25832"); "" = LLQ gives no position.
    llq_projection: str = ""
    #: Publish 2-D fixes (height unknown, ``fix_rules``); False: they are NO_FIX.
    allow_2d_fix: bool = True


@dataclass(frozen=True, slots=True)
class GnssFix:
    """A position fix. ``lat_deg``/``lon_deg`` north/east positive, ``alt_m`` above the WGS-84
    ellipsoid (NaN when unknown); all NaN with ``NO_FIX``. ``cov_enu_m2``: row-major 3x3.
    ``satellites``: used, None when not reported; ``two_d``: the height is unknown (altitude
    NaN, vertical variance ``HEIGHT_UNKNOWN_VARIANCE_M2``)."""

    fix_type: FixType
    lat_deg: float
    lon_deg: float
    alt_m: float
    cov_enu_m2: tuple[float, ...]
    cov_type: CovarianceType
    accuracy_source: str
    position_source: str
    satellites: int | None
    service: int
    two_d: bool = False

    @property
    def status(self) -> NavSatStatus:
        """NavSatStatus status of the fix type."""
        return NAV_SAT_STATUS.get(self.fix_type, NavSatStatus.NO_FIX)


@dataclass(frozen=True, slots=True)
class GnssVelocity:
    """Velocity over ground in ENU [m/s] with its row-major 3x3 covariance [m^2/s^2]."""

    vel_enu_m_s: tuple[float, float, float]
    cov_enu: tuple[float, ...]
    source: str


@dataclass(frozen=True, slots=True)
class GnssAttitude:
    """Vehicle orientation from the ADU5 (or a heading sentence) and where it came from."""

    orientation: Orientation
    source: str


@dataclass(slots=True)
class SolutionStats:
    """Counters since start-up."""

    no_fix: int = 0
    too_few_satellites: int = 0
    #: Valid fixes whose satellites-used count the receiver did not report (0 or empty).
    satellites_unreported: int = 0
    #: 2-D fixes: published (``allow_2d_fix``) or made NO_FIX.
    fixes_2d: int = 0
    rejected_2d: int = 0
    #: RMC/GLL fixes given the altitude of a recent 3-D fix.
    held_altitudes: int = 0
    #: Altitudes completed with the geoid model (GGA/GNS without a geoid separation).
    geoid_altitudes: int = 0
    fixes: dict[str, int] = field(default_factory=dict)
    attitudes: int = 0
    attitude_resets: int = 0
    attitude_degraded: int = 0


@dataclass(frozen=True, slots=True)
class EpochSolution:
    """What one epoch yields; ``date`` is its own UTC date if it had RMC / ZDA / LLQ."""

    fix: GnssFix | None
    velocity: GnssVelocity | None
    attitude: GnssAttitude | None
    date: datetime.date | None


_NAN = math.nan
_NO_FIX_COV = (0.0,) * 9


class EpochSolver:
    """Turns epochs into ``EpochSolution``; keeps the latest GSA DOPs across epochs."""

    def __init__(self, config: SolutionConfig, attitude: AttitudeConverter) -> None:
        """``attitude`` converts ADU5 angles."""
        self.config = config
        self.attitude = attitude
        self.stats = SolutionStats()
        self.fields = FieldReader()
        self._grid = GridProjection(config.llq_projection) if config.llq_projection else None
        self._covariance = FixCovariance(self.fields, config.llq_horizontal_fraction)
        self._held: HeldAltitude | None = None

    def note_gsa(self, gsa: pynmea2.GSA) -> None:
        """Remember the DOPs of a GSA sentence (GSA is timeless and may repeat per epoch)."""
        self._covariance.note_gsa(gsa)

    def solve(self, epoch: Epoch) -> EpochSolution:
        """Everything ``epoch`` tells (see the module docstring)."""
        fix = self._fix(epoch)
        if fix is not None:
            name = fix.fix_type.name
            self.stats.fixes[name] = self.stats.fixes.get(name, 0) + 1
            if fix.fix_type is FixType.NO_FIX:
                self.stats.no_fix += 1
        return EpochSolution(fix, self._velocity(epoch), self._attitude(epoch), self._date(epoch))

    # ---- position ---------------------------------------------------------------------------
    def _fix(self, epoch: Epoch) -> GnssFix | None:
        gga: pynmea2.GGA | pynmea2.GNS | None = epoch.get(pynmea2.GGA)
        if gga is None:
            gga = epoch.get(pynmea2.GNS)
        pat = epoch.get(ASHRPAT)
        rmc = epoch.get(pynmea2.RMC)
        gll = epoch.get(pynmea2.GLL)
        mode = self._mode_fix_type(rmc) if rmc is not None else None
        if mode is None and gll is not None:
            mode = self._mode_fix_type(gll)
        if isinstance(gga, pynmea2.GGA):
            quality = self.fields.integer(gga, "gps_qual", required=True)
            fix_type = gga_fix_type(quality) if quality is not None else FixType.NO_FIX
            source: pynmea2.NMEASentence = gga
        elif gga is not None:
            fix_type, source = gns_fix_type(text(gga, "mode_indicator")), gga
        elif pat is not None:
            fix_type, source = (FixType.SPS if mode is None else mode), pat
        elif (llq := epoch.get(LLQ)) is not None and self._grid is not None:
            quality = self.fields.integer(llq, "gps_qual", required=True)
            fix_type = FixType.NO_FIX if quality is None else LLQ_FIX.get(quality, FixType.NO_FIX)
            source = llq
            gga = None
        elif rmc is not None or gll is not None:
            source = rmc if rmc is not None else gll
            fix_type = FixType.NO_FIX if mode is None else mode
        else:
            return None
        name = sentence_id(source)
        service = _service(epoch)
        if fix_type not in VALID_FIX_TYPES:
            return _no_fix(name, service)
        sats = self._satellites(epoch, gga, source)
        heightless = source is rmc or source is gll  # no height field
        held = self._held_altitude(epoch) if heightless else None
        two_d = is_2d(gsa_mode(epoch.gsa), sats) or (heightless and held is None)
        if not self._enough_satellites(sats, two_d):
            return _no_fix(name, service)
        if isinstance(source, LLQ):
            position = self._grid_position(source)
        else:
            position = self.fields.position(source)
        if position is None:
            return _no_fix(name, service)
        alt = self._altitude(source, *position)
        uere = self.config.uere.for_fix(fix_type)
        cov, cov_type, accuracy = self._covariance.covariance(epoch, gga, uere)
        if two_d:
            alt, cov = _NAN, (*cov[:8], HEIGHT_UNKNOWN_VARIANCE_M2)
        elif held is not None:
            self.stats.held_altitudes += 1
            alt, cov = held[0], (*cov[:8], held[1])
        elif math.isfinite(alt) and epoch.time_of_day_ms is not None:
            self._held = HeldAltitude(epoch.time_of_day_ms, alt, cov[8])
        return GnssFix(
            fix_type, *position, alt, cov, cov_type, accuracy, name, sats, service, two_d
        )

    def _satellites(
        self,
        epoch: Epoch,
        gga: pynmea2.GGA | pynmea2.GNS | None,
        source: pynmea2.NMEASentence,
    ) -> int | None:
        """Satellites used by a valid fix: from GGA/GNS or LLQ; 0 or empty is "not reported",
        then from the epoch's GNS, else its GSAs, else None (``fix_rules``)."""
        counted = gga if gga is not None else source if isinstance(source, LLQ) else None
        sats = self.fields.integer(counted, "num_sats") if counted is not None else None
        if sats or counted is None:
            return sats
        self.stats.satellites_unreported += 1
        gns = epoch.get(pynmea2.GNS) if isinstance(gga, pynmea2.GGA) else None
        from_gns = self.fields.integer(gns, "num_sats") if gns is not None else None
        return from_gns or gsa_satellites(epoch.gsa)

    def _enough_satellites(self, sats: int | None, two_d: bool) -> bool:
        """``min_satellites`` on a reported count (``min_satellites - 1`` for a 2-D fix, which
        needs ``allow_2d_fix``); the counters."""
        if two_d:
            self.stats.fixes_2d += 1
            if not self.config.allow_2d_fix:
                self.stats.rejected_2d += 1
                return False
        needed = self.config.min_satellites - (1 if two_d else 0)
        if sats is not None and sats < needed:
            self.stats.too_few_satellites += 1
            return False
        return True

    def _held_altitude(self, epoch: Epoch) -> tuple[float, float] | None:
        """(altitude [m], vertical variance [m²]) of the last 3-D fix for an RMC/GLL epoch."""
        if self._held is None or epoch.time_of_day_ms is None:
            return None
        return self._held.at(epoch.time_of_day_ms)

    def _mode_fix_type(self, sentence: pynmea2.NMEASentence) -> FixType | None:
        """Fix type from RMC/GLL status and mode letter; None when neither says anything."""
        status = text(sentence, "status")
        if status == "V":
            return FixType.NO_FIX
        mode = text(sentence, "mode_indicator" if isinstance(sentence, pynmea2.RMC) else "faa_mode")
        if mode is not None:
            return MODE_FIX.get(mode[0], FixType.NO_FIX)
        return FixType.SPS if status == "A" else None

    def _grid_position(self, llq: LLQ) -> tuple[float, float] | None:
        """LLQ's grid easting and northing [m] through ``llq_projection``."""
        easting = self.fields.number(llq, "easting", required=True)
        northing = self.fields.number(llq, "northing", required=True)
        if easting is None or northing is None or self._grid is None:
            return None
        if {text(llq, "easting_unit"), text(llq, "northing_unit")} - {"M", None}:
            self.fields.reject(llq, "easting_unit")  # only metres
            return None
        position = self._grid.to_lat_lon(easting, northing)
        if position is None:
            self.fields.reject(llq, "easting")
        return position

    def _altitude(self, source: pynmea2.NMEASentence, lat_deg: float, lon_deg: float) -> float:
        if isinstance(source, ASHRPAT | LLQ):
            name = "height" if isinstance(source, LLQ) else "altitude"
            alt = self.fields.number(source, name, required=True)
            return _NAN if alt is None else alt
        if not isinstance(source, pynmea2.GGA | pynmea2.GNS):
            return _NAN
        msl = self.fields.number(source, "altitude", required=True)
        if msl is None:
            return _NAN
        separation = self.fields.number(source, "geo_sep")
        if separation is None:
            self.stats.geoid_altitudes += 1
            separation = geoid.undulation_m(lat_deg, lon_deg)
        return msl + separation

    # ---- velocity ---------------------------------------------------------------------------
    def _velocity(self, epoch: Epoch) -> GnssVelocity | None:
        vtg = epoch.get(pynmea2.VTG)
        rmc = epoch.get(pynmea2.RMC)
        if vtg is not None and text(vtg, "faa_mode") != "N":
            kmph = self.fields.number(vtg, "spd_over_grnd_kmph")
            knots = self.fields.number(vtg, "spd_over_grnd_kts")
            speed = kmph / 3.6 if kmph is not None else _scaled(knots, KNOTS_TO_M_S)
            return self._enu_velocity(speed, self.fields.number(vtg, "true_track"), "VTG")
        if rmc is not None and self._mode_fix_type(rmc) in VALID_FIX_TYPES:
            knots = self.fields.number(rmc, "spd_over_grnd")
            course = self.fields.number(rmc, "true_course")
            return self._enu_velocity(_scaled(knots, KNOTS_TO_M_S), course, "RMC")
        return None

    def _enu_velocity(
        self, speed: float | None, course_deg: float | None, source: str
    ) -> GnssVelocity | None:
        if speed is None or (course_deg is None and speed != 0.0):
            self.fields.empty_fields += 1
            return None
        course = math.radians(course_deg or 0.0)
        vel = (speed * math.sin(course), speed * math.cos(course), 0.0)
        var = self.config.velocity_sigma_m_s**2
        cov = (var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, UNKNOWN_VARIANCE)
        return GnssVelocity(vel, cov, source)

    # ---- attitude ---------------------------------------------------------------------------
    def _attitude(self, epoch: Epoch) -> GnssAttitude | None:
        sentence: ASHRPAT | ASHRATT | None = epoch.get(ASHRPAT) or epoch.get(ASHRATT)
        if sentence is None:
            hdt = epoch.get(pynmea2.HDT)
            heading = None if hdt is None else self.fields.number(hdt, "heading", required=True)
            if heading is None:
                return None
            self.stats.attitudes += 1
            return GnssAttitude(self.attitude.convert_heading(heading), "HDT")
        reset_flag = self.fields.integer(sentence, "reset_flag", required=True)
        if reset_flag is None:
            return None
        if reset_flag != 0:
            self.stats.attitude_resets += 1
            return None
        angles = [
            self.fields.number(sentence, n, required=True) for n in ("heading", "pitch", "roll")
        ]
        if None in angles:
            return None
        heading, pitch, roll = (float(a or 0.0) for a in angles)
        mrms = self.fields.number(sentence, "mrms")
        brms = self.fields.number(sentence, "brms")
        orientation = self.attitude.convert(heading, pitch, roll, mrms, brms)
        self.stats.attitudes += 1
        if orientation.scale > 1.0:
            self.stats.attitude_degraded += 1
        return GnssAttitude(orientation, sentence_id(sentence))

    # ---- date -------------------------------------------------------------------------------
    def _date(self, epoch: Epoch) -> datetime.date | None:
        for cls in (pynmea2.ZDA, pynmea2.RMC, LLQ):
            sentence = epoch.get(cls)
            found = self.fields.date(sentence) if sentence is not None else None
            if found is not None:
                return found
        return None


def _scaled(value: float | None, factor: float) -> float | None:
    return None if value is None else value * factor


def _service(epoch: Epoch) -> int:
    """NavSatStatus service bits of the talkers in the epoch (GPS when none names a system)."""
    bits = 0
    for sentence in epoch.sentences:
        bits |= _TALKER_SERVICE.get(getattr(sentence, "talker", ""), 0)
        if isinstance(sentence, pynmea2.GNS):
            modes = text(sentence, "mode_indicator") or ""
            for letter, bit in zip(modes, _GNS_MODE_SERVICE, strict=False):
                bits |= bit if letter in GNS_MODE_RANK else 0
    return bits or SERVICE_GPS


def _no_fix(source: str, service: int) -> GnssFix:
    return GnssFix(
        FixType.NO_FIX,
        _NAN,
        _NAN,
        _NAN,
        _NO_FIX_COV,
        CovarianceType.UNKNOWN,
        "none",
        source,
        None,
        service,
    )


def fill_gnss_fix(msg: Any, time_ns: int, frame_id: str, fix: GnssFix) -> Any:
    """gnss/fix (sensor_msgs/NavSatFix) from a fix: status from its fix type, NaN when none."""
    return fill_navsatfix(
        msg,
        time_ns,
        frame_id,
        int(fix.status),
        fix.service,
        fix.lat_deg,
        fix.lon_deg,
        fix.alt_m,
        fix.cov_enu_m2,
        int(fix.cov_type),
    )
