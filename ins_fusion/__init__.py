"""GNSS-aided INS: strapdown mechanization, error-state Kalman filter, simulator and tools."""
