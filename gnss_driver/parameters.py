"""The gnss_node's parameters: name, default, description and valid values, and the driver
core's configuration from them (no ROS).

``gnss_driver.node`` declares them (with the lifecycle's ``autostart``); ``gnss_ins redecode``
reads them from a parameter file; docs/parameters.md lists them and docs/gnss.md describes them.
"""

from __future__ import annotations

from typing import Any

from gnss_driver.attitude import (
    ANGLE_CONVENTIONS,
    DEFAULT_ANGLE_CONVENTION,
    DEFAULT_SIGMA_RPY_DEG,
    AttitudeConfig,
)
from gnss_driver.commands import command_error
from gnss_driver.driver import GPS_UTC_LEAP_S, DriverConfig
from gnss_driver.grid import projection_error
from gnss_driver.profiles import CAR_OFFSETS_DEG, CAR_VECTORS_M, Adu5Setup, Receiver
from gnss_driver.solution import SolutionConfig, UereTable
from gnss_ins_common.params import Param, needs_values, serial_link_params


def _commands_error(commands: list[str]) -> str | None:
    for command in commands:
        problem = command_error(command)
        if problem:
            return f"{command!r}: {problem}"
    return None


_UERE = UereTable()
DRIVER_PARAMETERS = (
    *serial_link_params(
        "receiver", 9600, "serial baud rate, 8N1 (Leica 9600, notes §7.2)", 3.0, 0.2
    ),
    Param(
        "receiver",
        "leica",
        "receiver profile: leica (GGA/VTG/LLQ), adu5 (PASHR PAT/ATT), generic (any NMEA 0183)",
        choices=tuple(r.value for r in Receiver),
    ),
    Param("frame_id", "gnss_link", "frame_id of the published messages (the antenna)"),
    Param(
        "setup_commands",
        [],
        "commands sent after each (re)open, CR LF appended; empty: the profile's defaults",
        check=_commands_error,
    ),
    Param("setup_answer_timeout", 0.5, "wait for each command's ACK/NAK [s]", 0.0, 10.0),
    Param("allow_missing_checksum", False, "accept sentences without *hh (still counted)"),
    Param("uere_sps", _UERE.sps, "UERE of an SPS fix [m], x HDOP/VDOP", 0.001, 100.0),
    Param("uere_dgps", _UERE.dgps, "UERE of a DGPS fix [m]", 0.001, 100.0),
    Param("uere_rtk_float", _UERE.rtk_float, "UERE of an RTK float fix [m]", 0.001, 100.0),
    Param("uere_rtk_fixed", _UERE.rtk_fixed, "UERE of an RTK fixed fix [m]", 0.001, 100.0),
    Param(
        "velocity_sigma",
        SolutionConfig().velocity_sigma_m_s,
        "1-sigma of each horizontal velocity component [m/s] (notes (7.15))",
        0.001,
        100.0,
    ),
    Param(
        "llq_horizontal_fraction",
        SolutionConfig().llq_horizontal_fraction,
        "horizontal share f of Leica LLQ's coordinate quality CQ = sigma_h + sigma_v: sigma_h ="
        " f CQ, sigma_v = (1 - f) CQ (the report gives only the sum; 0.4 = 2 cm of 2 + 3 cm)",
        0.01,
        0.99,
    ),
    Param(
        "attitude_sigma_rpy",
        list(DEFAULT_SIGMA_RPY_DEG),
        "1-sigma of roll, pitch, yaw at nominal PAT quality [deg] (notes §7.3)",
        0.001,
        180.0,
        check=needs_values(3, "roll, pitch, yaw"),
    ),
    Param(
        "adu5_angle_convention",
        DEFAULT_ANGLE_CONVENTION,
        "how ADU5 heading, pitch, roll compose: heading_pitch_roll (vehicle Euler angles, pitch ="
        " elevation of V12) or report_fixed_axes (Aalborg report 7.5: fixed axes, order"
        " heading, pitch, roll); docs/gnss.md",
        choices=ANGLE_CONVENTIONS,
    ),
    Param(
        "min_satellites",
        SolutionConfig().min_satellites,
        "a position from fewer satellites used is published as no fix (3-D needs 4; a 2-D fix"
        " needs one fewer; a count the receiver does not report is not checked)",
        0,
        12,
    ),
    Param(
        "allow_2d_fix",
        SolutionConfig().allow_2d_fix,
        "publish 2-D fixes (GSA mode 2, 3 satellites, RMC/GLL without a recent altitude) as fixes"
        " with altitude NaN and vertical variance 1e6 (height unknown); false: no fix",
    ),
    Param(
        "llq_projection",
        "",
        "projected CRS of Leica LLQ grid positions (e.g. EPSG:25832, ETRS89 / UTM 32N); empty:"
        " LLQ gives accuracy only, no position",
        check=projection_error,
    ),
    Param("attitude_mrms_limit", 0.005, "MRMS above this scales the sigmas up [m]", 1e-4, 1.0),
    Param("attitude_brms_limit", 0.04, "BRMS above this scales the sigmas up [m]", 1e-4, 10.0),
    Param(
        "adu5_vectors",
        [v for vector in CAR_VECTORS_M for v in vector],
        "ADU5 antenna vectors V12, V13, V14 as x right, y forward, z up [m] ($PASHS,3DF,Vxx)",
        -200.0,
        200.0,
        check=needs_values(9, "3 vectors x, y, z"),
    ),
    Param(
        "adu5_offsets",
        list(CAR_OFFSETS_DEG),
        "ADU5 offset angles heading, pitch, roll of the antenna frame on the vehicle [deg]",
        -180.0,
        360.0,
        check=needs_values(3, "heading, pitch, roll"),
    ),
    Param(
        "adu5_offsets_in_receiver",
        True,
        "true: send the offsets with $PASHS,3DF,OFS; false: send zeros, the driver removes them",
    ),
    Param("adu5_elevation_mask", 15, "ADU5 elevation mask [deg] (notes §7.3)", 0, 90),
    Param("adu5_period", 0.2, "ADU5 NMEA output period [s] (0.2 s = 5 Hz)", 0.2, 999.0),
    Param("adu5_port", "A", "ADU5 port this node is connected to", choices=("A", "B")),
    Param("latency", 0.0, "fixed delay from the epoch's UTC time to its first byte [s]", 0.0, 2.0),
    Param(
        "use_gnss_time",
        False,
        "true: stamp each epoch with its UTC time (host clock disciplined to UTC by NTP/PTP/PPS);"
        " false: with the UTC mapped onto the host clock by the arrival envelope",
    ),
    Param(
        "gnss_time_offset_warn",
        0.25,
        "with use_gnss_time, warn when host - UTC (receiver output delay + host clock error)"
        " exceeds this [s]",
        0.001,
        10.0,
    ),
    Param("gps_utc_leap_seconds", GPS_UTC_LEAP_S, "GPS - UTC for PASHR,ATT times [s]", 0, 100),
    Param(
        "epoch_idle_timeout",
        0.5,
        "a quiet line for this long ends an epoch [s]; below the gap between epochs",
        0.01,
        5.0,
    ),
    Param(
        "corrections_input",
        True,
        "write the RTCM 3 frames of the rtcm topic (rtcm_msgs/Message, e.g. from an NTRIP"
        " client) to the receiver: network RTK; false: no rtcm subscription",
    ),
    Param(
        "corrections_max_age",
        3.0,
        "a correction frame older than this when its turn to be written comes is dropped [s]",
        0.5,
        30.0,
    ),
    Param(
        "nmea_output",
        True,
        "publish every line read from the receiver on nmea (nmea_msgs/Sentence), rejected ones"
        " included, and the port's (re)opens on port_events",
    ),
)


def _adu5_offsets(p: dict[str, Any]) -> tuple[float, float, float]:
    offsets = p["adu5_offsets"]
    return (offsets[0], offsets[1], offsets[2])


def adu5_setup(p: dict[str, Any]) -> Adu5Setup:
    """The ADU5's set-up from the validated parameters (its default set-up commands)."""
    vectors = p["adu5_vectors"]
    in_receiver = p["adu5_offsets_in_receiver"]
    return Adu5Setup(
        vectors_m=tuple((vectors[i], vectors[i + 1], vectors[i + 2]) for i in (0, 3, 6)),
        offsets_deg=_adu5_offsets(p) if in_receiver else (0.0, 0.0, 0.0),
        elevation_mask_deg=p["adu5_elevation_mask"],
        period_s=p["adu5_period"],
        port=p["adu5_port"],
    )


def driver_config(p: dict[str, Any]) -> DriverConfig:
    """The driver core's configuration from the validated parameters."""
    sigma = p["attitude_sigma_rpy"]
    in_receiver = p["adu5_offsets_in_receiver"]
    return DriverConfig(
        baud=p["baud"],
        allow_missing_checksum=p["allow_missing_checksum"],
        latency_s=p["latency"],
        use_gnss_time=p["use_gnss_time"],
        epoch_idle_s=p["epoch_idle_timeout"],
        gps_utc_leap_s=p["gps_utc_leap_seconds"],
        solution=SolutionConfig(
            UereTable(p["uere_sps"], p["uere_dgps"], p["uere_rtk_float"], p["uere_rtk_fixed"]),
            p["velocity_sigma"],
            p["llq_horizontal_fraction"],
            p["min_satellites"],
            p["llq_projection"],
            p["allow_2d_fix"],
        ),
        attitude=AttitudeConfig(
            sigma_rpy_deg=(sigma[0], sigma[1], sigma[2]),
            offsets_deg=(0.0, 0.0, 0.0) if in_receiver else _adu5_offsets(p),
            mrms_limit_m=p["attitude_mrms_limit"],
            brms_limit_m=p["attitude_brms_limit"],
            convention=p["adu5_angle_convention"],
        ),
    )
