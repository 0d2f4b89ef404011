"""Running the system (no rclpy): the vehicle's node set and their command lines
(``vehicle_nodes``), the vehicle's recorder (``recorder``), child processes with their logs,
supervised and restarted (``processes``), a progress bar (``progress``), tasks on a Dask
cluster (``cluster``)."""
