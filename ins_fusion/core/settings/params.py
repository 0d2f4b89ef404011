"""Parameters of the fusion engine and ins_fusion_node: one table for the node and the tools.

``PARAMETERS`` is data (gnss_ins_common.params.Param): the node declares it, the replay tool
validates a YAML file against it, and
``ins_fusion.core.settings.config.FusionConfig.from_parameters`` turns the validated flat dict into
the engine's typed configuration. config/ins_fusion.yaml holds exactly these defaults (a test checks
it).

Defaults and their sources (docs/fusion.md explains the choices; references are to
shared/reference/: "Aalborg" imu400cc-aalborg-notes.md, "NTNU" gnss-ins-ntnu-notes.md, "Oslo"
mems-noise-oslo-notes.md):

- the IMU noise model: ins_fusion.core.settings.imu_noise_params;
- stop detector: 1 s window and var(a_x)+var(a_y) < 0.048 (m/s²)² (NTNU §7), speed 0.2 m/s
  (NTNU §7 ground-truth threshold); gyro variance, hysteresis and minimum duration are ours
  (NTNU §14 item 19 and D6 ask for them);
- course heading above 3 m/s (NTNU §8).
"""

from __future__ import annotations

from gnss_ins_common.params import Param
from ins_fusion.core.nav.calibration import CalibrationError, ImuCalibration
from ins_fusion.core.settings.imu_noise_params import IMU_NOISE_PARAMETERS, vector_param

#: ``tf_mode`` values: the frame of ins/odometry and of its transform; none = no /tf
#: (ins_fusion.adapters.tf_frames).
TF_MODES = ("map", "odom", "none")


def _calibration_file(path: str) -> str | None:
    """Why the calibration file cannot be used (unreadable or malformed), or None."""
    if not path:
        return None
    try:
        ImuCalibration.from_yaml(path)
    except CalibrationError as exc:
        return str(exc)
    return None


def _datum(values: list[float]) -> str | None:
    if not values:
        return None
    if len(values) != 3:
        return "needs [] or [latitude_deg, longitude_deg, height_m]"
    lat, lon, _ = values
    return None if abs(lat) <= 90.0 and abs(lon) <= 180.0 else "latitude/longitude out of range"


PARAMETERS: tuple[Param, ...] = (
    *IMU_NOISE_PARAMETERS,
    # Installation (REP-103: base_link FLU, angles of the sensor frame in base_link).
    vector_param(
        "imu_mounting_rpy_deg",
        [0.0, 0.0, 0.0],
        "roll, pitch, yaw of imu_link in base_link [deg]",
        -180.0,
        180.0,
    ),
    vector_param(
        "imu_lever_arm",
        [0.8, 0.0, 1.6],
        "origin of imu_link in base_link FLU [m] (the simulator's survey car)",
        -50.0,
        50.0,
    ),
    vector_param(
        "gnss_lever_arm",
        [0.0, 0.0, 1.75],
        "GNSS antenna phase centre in base_link FLU [m] (the simulator's survey car)",
        -50.0,
        50.0,
    ),
    vector_param(
        "attitude_mounting_rpy_deg",
        [0.0, 0.0, 0.0],
        "roll, pitch, yaw of the frame the attitude receiver reports, in base_link [deg]",
        -180.0,
        180.0,
    ),
    Param(
        "imu_range_rate",
        100.0,
        "measuring range of the gyros [deg/s] (IMU400CC-100: 100); a sample beyond 1.1 times it "
        "is corrupt: skipped and counted, never fed to the filter",
        1.0,
        1.0e5,
    ),
    Param(
        "imu_range_accel",
        2.0,
        "measuring range of the accelerometers [g] (IMU400CC-100: 2); a sample beyond 1.1 "
        "times it is corrupt: skipped and counted",
        0.1,
        1000.0,
    ),
    Param(
        "imu_time_offset",
        0.0,
        "how much later than the GNSS epochs the IMU samples are stamped [s]; subtracted from "
        "every IMU stamp (the residual is estimated, self_calibration.time_offset)",
        -1.0,
        1.0,
    ),
    Param(
        "self_calibration.time_offset",
        False,
        "estimate the residual IMU-GNSS time offset online (observable in turns and speed "
        "changes; reported in /diagnostics and by replay): a calibration run, then set "
        "imu_time_offset",
    ),
    Param(
        "self_calibration.time_offset_sigma",
        0.1,
        "initial sigma of the residual IMU time offset [s]",
        1.0e-4,
        1.0,
    ),
    Param(
        "self_calibration.mounting",
        True,
        "estimate the residual IMU-to-vehicle mounting (pitch, yaw) online from the NHC "
        "(needs use_nhc; observable in turns and speed changes)",
    ),
    Param(
        "self_calibration.mounting_sigma",
        3.0,
        "initial sigma of the residual mounting pitch and yaw [deg]",
        0.01,
        20.0,
    ),
    Param(
        "datum",
        [],
        "origin of the map frame [lat_deg, lon_deg, height_m]; empty = the first good fix",
        check=_datum,
        empty_list_of="float",
    ),
    Param(
        "calibration_file",
        "",
        "IMU calibration YAML applied before mechanization; empty = none",
        check=_calibration_file,
    ),
    # Measurements.
    Param("use_gnss_velocity", True, "use gnss/vel (horizontal only when vertical is unknown)"),
    Param("use_attitude", True, "use gnss/attitude (ADU5 roll, pitch, heading)"),
    Param("use_zupt", True, "zero-velocity updates while the stop detector reports a stop"),
    Param("use_zaru", True, "zero-angular-rate updates while the stop detector reports a stop"),
    Param("use_nhc", True, "non-holonomic constraint (no lateral/vertical base_link velocity)"),
    Param("use_course_heading", True, "GNSS course as heading during alignment"),
    Param(
        "gate_probability",
        0.999,
        "chi-square gate: probability of accepting a correct measurement",
        0.5,
        0.999999,
    ),
    Param(
        "gate_recovery_count",
        5,
        "after this many gated rejections in a row of one measurement, widen the covariance "
        "along what it observes until it fits, and apply it (0 = never)",
        0,
        1000,
    ),
    vector_param(
        "gnss_noise.white_sigma",
        [0.014, 0.014, 0.021],
        "largest white (epoch-to-epoch) part of the receiver's position sigma, E/N/U [m]; the "
        "rest is a time-correlated error (Gauss-Markov states)",
        0.0,
        100.0,
        axes=True,
    ),
    Param(
        "gnss_noise.white_fraction",
        0.05,
        "and at least this share of the receiver's position variance is white",
        0.0,
        1.0,
    ),
    Param(
        "gnss_noise.correlation_time",
        60.0,
        "correlation time of the time-correlated GNSS position error [s]; 0 = all white, no "
        "GNSS error states",
        0.0,
        3600.0,
    ),
    Param(
        "gnss_position_noise_scale",
        1.0,
        "factor on the receiver's position sigma (covers time-correlated receiver errors)",
        0.1,
        100.0,
    ),
    Param(
        "pseudo_measurement_rate",
        10.0,
        "rate of the ZUPT, ZARU and NHC pseudo-measurements [Hz]",
        0.1,
        200.0,
    ),
    Param("zupt_sigma", 0.02, "ZUPT noise sigma per axis [m/s]", 1e-4, 10.0),
    Param(
        "zaru_sigma",
        0.002,
        "ZARU noise sigma per axis on top of the gyro white noise [deg/s]",
        0.0,
        10.0,
    ),
    Param("nhc_sigma", 0.05, "NHC noise sigma, lateral and vertical [m/s]", 1e-4, 10.0),
    Param(
        "nhc_min_speed",
        0.5,
        "apply the NHC above this speed [m/s] (the stop detector handles standstill)",
        0.0,
        100.0,
    ),
    # Vehicle speed (odometer, DMI, CAN; docs/fusion.md "Vehicle speed").
    Param(
        "speed.use",
        False,
        "use vehicle/speed (forward speed of the measuring point, base_link x) with a speed "
        "scale state; gnss_ins replay turns it on when the bag holds the speed topic, unless"
        " --params or --set make it false",
    ),
    vector_param(
        "speed.lever_arm",
        [0.0, 0.0, 0.0],
        "measuring point of the speed in base_link FLU [m] (a single wheel's hub, or the "
        "centre of the wheels whose mean speed is measured)",
        -50.0,
        50.0,
    ),
    Param(
        "speed.sigma",
        0.05,
        "least noise sigma of one speed measurement [m/s]; a larger variance in the message "
        "is used instead",
        1e-4,
        10.0,
    ),
    Param(
        "speed.scale_sigma",
        2.0,
        "initial sigma of the speed's scale error (tyre radius, load, pressure) [%]; 0 = the "
        "speed is taken as exact, no scale state",
        0.0,
        50.0,
    ),
    Param(
        "speed.time_offset",
        0.0,
        "how much later than the GNSS epochs the speed readings are stamped [s]; subtracted "
        "from every speed stamp (a CAN bus logged with its receive times: their latency)",
        -1.0,
        1.0,
    ),
    Param(
        "speed.max_accel",
        1.5,
        "speed readings are not used while the IMU measures a forward acceleration or braking "
        "beyond this [m/s^2] (the tyres may slip)",
        0.1,
        100.0,
    ),
    # Stop detector (NTNU §7; hysteresis and minimum duration ours).
    Param("stop_detector.window", 1.0, "variance window [s]", 0.1, 10.0),
    Param(
        "stop_detector.accel_variance",
        0.048,
        "stop when var(a_x)+var(a_y) over the window is below [(m/s^2)^2]",
        0.0,
        100.0,
    ),
    Param(
        "stop_detector.gyro_variance",
        5.0e-4,
        "and var(w_x)+var(w_y)+var(w_z) is below [(rad/s)^2]",
        0.0,
        100.0,
    ),
    Param(
        "stop_detector.accel_change",
        0.05,
        "and the mean horizontal specific force of the last quarter window moved less than "
        "[m/s^2] (from the window mean, or during a stop from its start)",
        0.0,
        10.0,
    ),
    Param(
        "stop_detector.speed",
        0.2,
        "and the GNSS speed (when recent) and the estimated speed are below [m/s]",
        0.0,
        10.0,
    ),
    Param(
        "stop_detector.hysteresis",
        1.5,
        "a stop ends when a variance or speed exceeds this factor times its threshold",
        1.0,
        10.0,
    ),
    Param(
        "stop_detector.min_duration",
        0.5,
        "the stop conditions must hold this long before ZUPT/ZARU start [s]",
        0.0,
        60.0,
    ),
    # Alignment and state machine.
    Param(
        "alignment.duration",
        10.0,
        "standstill averaged for levelling and the gyro-bias seed [s]",
        1.0,
        600.0,
    ),
    Param(
        "alignment.course_speed",
        3.0,
        "GNSS speed above which the course gives the heading [m/s] (NTNU §8)",
        0.5,
        50.0,
    ),
    Param(
        "alignment.moving_tilt_sigma",
        3.0,
        "roll/pitch sigma when aligning in motion without a levelling standstill [deg]",
        0.1,
        45.0,
    ),
    Param(
        "degraded_after_s",
        5.0,
        "state 'degraded' after this long without a used GNSS position [s]",
        0.5,
        3600.0,
    ),
    Param(
        "covariance_interval",
        0.1,
        "propagate the covariance over this many seconds of IMU samples at a time (mean "
        "specific force; always up to each measurement); 0 = every sample [s]",
        0.0,
        0.2,
    ),
    Param(
        "history_s",
        3.0,
        "IMU history kept to apply late measurements at their stamps [s]",
        0.1,
        60.0,
    ),
    Param(
        "imu_gap_reset_s",
        1.0,
        "an IMU gap longer than this resets the filter [s] (shorter gaps are bridged)",
        0.05,
        60.0,
    ),
    # Output (ins_fusion_node).
    Param("output_rate", 50.0, "publish rate of ins/odometry, ins/fix, ins/imu [Hz]", 0.1, 1000.0),
    Param("map_frame", "map", "frame_id of ins/odometry (ENU tangent plane at the datum)"),
    Param("base_frame", "base_link", "child_frame_id of ins/odometry"),
    # TF (REP-105; ins_fusion/adapters/tf_frames.py).
    Param(
        "tf_mode",
        "map",
        "transform broadcast on /tf from ins/odometry: map = map_frame->base_frame, odom ="
        " odom_frame->base_frame (ins/odometry then in odom_frame), none = no /tf",
        choices=TF_MODES,
    ),
    Param("odom_frame", "odom", "world frame of ins/odometry and /tf when tf_mode is odom"),
    Param("imu_frame", "imu_link", "child of the static base_frame->IMU transform on /tf_static"),
    Param("gnss_frame", "gnss_link", "child of the static base_frame->antenna transform"),
    Param(
        "attitude_frame",
        "",
        "child of a static base_frame->attitude receiver transform (rotation only,"
        " attitude_mounting_rpy_deg); empty = none",
    ),
    Param("diagnostics_period", 1.0, "period of the /diagnostics status [s]", 0.1, 60.0),
    Param(
        "imu_timeout",
        0.5,
        "imu/data_raw silent this long: state no_imu, ERROR on /diagnostics at once"
        " (reported within 1.5 x this) [s]",
        0.05,
        10.0,
    ),
)
