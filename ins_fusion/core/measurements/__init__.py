"""The measurements, one module per kind with its model, its handler and its compiled update
(gnss_position with its noise split gnss_noise, gnss_velocity, attitude, stationary: ZUPT/ZARU,
nhc, vehicle_speed); what their models share (common); the gated update with its recovery and
the books (gate); the heading from the course or an attitude (heading); the stop detector
(stop_detector); which records the compiled updates take (fused)."""
