"""Simulated GNSS epochs as the receivers send them and as gnss_node decodes them (no ROS).

An epoch of the error model (sim.gnss_model) is printed with the GNSS emulators' own sentence
writers (gnss_driver.emulator: the Leica rover's VTG, GGA, LLQ and GST; the ADU5's PASHR,PAT)
and read back with the GNSS driver core's reader and solver configured as gnss_node's defaults,
so the fix, velocity and attitude and their covariances are what gnss_node publishes for it, NMEA
rounding included. The live mode hands the same inputs (``emulator_truth``, ``epoch_config``) to
the emulators on pseudo-terminals.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_driver.attitude import R_BRF_FLU, AttitudeConfig, AttitudeConverter, brf_angles
from gnss_driver.emulator import EmulatorConfig, Truth, adu5_sentences, leica_sentences
from gnss_driver.epoch import Epoch
from gnss_driver.profiles import CAR_OFFSETS_DEG, Receiver
from gnss_driver.reader import NmeaReader, frame_sentence
from gnss_driver.solution import EpochSolution, EpochSolver, SolutionConfig
from ins_fusion.sim.gnss_model import GnssEpoch, GnssFix

#: The state printed for an epoch without a fix (the sentences leave the fields empty).
_NO_FIX_TRUTH = Truth(math.nan, math.nan, math.nan)


def emulator_config(receiver: Receiver) -> EmulatorConfig:
    """The emulated receiver of a simulation. The ADU5 antenna frame is mounted with the
    report car's offsets (Aalborg notes §7.3), which gnss_node uploads with $PASHS,3DF,OFS, so
    its PAT angles are those of base_link. The Leica adds GST after its LLQ: the LLQ's
    coordinate quality is one sum σ_h + σ_v, which gnss_node splits by an assumed ratio
    (``llq_horizontal_fraction``) that need not be the error model's (RTK fixed: 2.8 cm
    horizontal for 3.0 cm vertical, read back as 1.6 cm per horizontal axis instead of 2.0 and
    3.5 cm vertical); GST's σ per axis, which gnss_node takes first, is the model's own."""
    if receiver is Receiver.ADU5:
        return EmulatorConfig(receiver=receiver, mount_offsets_deg=CAR_OFFSETS_DEG)
    return EmulatorConfig(receiver=receiver, leica_extra=("GST",))


def emulator_truth(fix: GnssFix | None) -> Truth:
    """The measured state of a fix in the emulators' terms: antenna position [deg, m above the
    ellipsoid], ENU velocity [m/s] (0 up when the receiver has no vertical velocity) and the ADU5
    angles (heading, pitch, roll [deg]) of the measured base_link attitude."""
    if fix is None:
        return _NO_FIX_TRUTH
    heading = pitch = roll = 0.0
    if fix.quat_enu_flu is not None:
        r_enu_brf = Rotation.from_quat(fix.quat_enu_flu) * R_BRF_FLU.inv()
        heading, pitch, roll = brf_angles(r_enu_brf)
    east, north, up = (float(v) for v in np.nan_to_num(fix.vel_enu_m_s))
    return Truth(
        math.degrees(fix.lat_rad),
        math.degrees(fix.lon_rad),
        fix.height_m,
        (east, north, up),
        heading,
        pitch,
        roll,
    )


def epoch_config(base: EmulatorConfig, epoch: GnssEpoch) -> EmulatorConfig:
    """``base`` with what the receiver reports for this epoch: GGA quality, satellites, HDOP, the
    LLQ coordinate quality CQ = σ_h + σ_v (Aalborg notes §7.2, (7.1)) and the GST σ."""
    fix = epoch.fix
    if fix is None:
        return dataclasses.replace(base, satellites=epoch.satellites)
    sigma_e, sigma_n, sigma_u = (float(s) for s in fix.position_sigma_enu_m)
    return dataclasses.replace(
        base,
        fix_quality=int(fix.fix_type),
        satellites=fix.satellites,
        hdop=fix.hdop,
        coordinate_quality_m=math.hypot(sigma_e, sigma_n) + sigma_u,
        gst_sigmas_m=(sigma_n, sigma_e, sigma_u),
    )


class ReceiverModel:
    """One simulated receiver: its sentences for an epoch and gnss_node's reading of them."""

    def __init__(self, receiver: Receiver) -> None:
        self.receiver = receiver
        self.config = emulator_config(receiver)
        self._reader = NmeaReader()
        self._solver = EpochSolver(SolutionConfig(), AttitudeConverter(AttitudeConfig()))

    def sentences(self, utc_s: float, epoch: GnssEpoch) -> list[bytes]:
        """The framed NMEA sentences of an epoch at UTC time utc_s [s since 1970]."""
        config = epoch_config(self.config, epoch)
        truth, has_fix = emulator_truth(epoch.fix), epoch.fix is not None
        if self.receiver is Receiver.ADU5:
            mrms = config.mrms_m
            bodies = adu5_sentences(utc_s, truth, config, CAR_OFFSETS_DEG, 0, mrms, has_fix)
        else:
            bodies = leica_sentences(utc_s, truth, config, has_fix)
        return [frame_sentence(body) for body in bodies]

    def decode(self, sentences: list[bytes]) -> EpochSolution:
        """gnss_node's fix, velocity and attitude of one epoch's sentences."""
        epoch = Epoch(None)
        for read in self._reader.feed(b"".join(sentences)):
            epoch.add(read.sentence, read.wire_bytes, 0.0)
        return self._solver.solve(epoch)

    def solve(self, utc_s: float, epoch: GnssEpoch) -> EpochSolution:
        """What gnss_node makes of the epoch."""
        return self.decode(self.sentences(utc_s, epoch))
