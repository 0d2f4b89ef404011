"""Running the system (no rclpy): the vehicle's node set and their command lines
(``vehicle_nodes``), child processes with their logs (``processes``), a progress bar
(``progress``)."""
