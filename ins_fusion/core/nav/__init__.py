"""Navigation models: WGS-84 earth, rotations and frames, units, IMU calibration, strapdown
mechanization, static levelling."""
