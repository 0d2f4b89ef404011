"""Re-processing many bags (``gnss_ins batch``): one replay task per bag on a Dask cluster
(``task``), results kept atomically in one folder per bag so that a rerun resumes (``store``),
and the fleet summary: table, CSV, Parquet and overview figure (``summary``, ``overview``). No
rclpy."""
