"""Laboratory calibration of an IMU from recorded bags (no ROS): ``gnss_ins calibrate``.

The methods of the Aalborg report (shared/reference/imu400cc-aalborg-notes.md §4, "notes" below)
estimate, from the IMU records of bags (ins_fusion.bags.imu), the deterministic errors of the
observation model (2.1)/(2.2) that ins_fusion.core.nav.calibration corrects, each with its own
observation equations and an uncertainty propagated from the noise of the data (§4.4):

| module | what |
|---|---|
| ``segments`` | static and steady-rotation segments: automatic detection or given windows |
| ``model`` | site (gravity, earth rate) and bias instability of the observations |
| ``lsq`` | weighted least squares with correlated observations |
| ``static`` | six-position S2, Salychev, known attitude S3, unknown attitude S4 |
| ``rotation`` | rate table D1, known rotation angle D2 |
| ``axes`` | the axis/sign mapping of a unit from a six-position record |
| ``result`` | estimates with σ, the calibration YAML the fusion node reads |
| ``report``, ``plot`` | the markdown report and the figure of the segments used |
| ``procedures`` | simulated laboratory procedures (tests, benchmark, documentation) |
| ``command`` | the steps of ``gnss_ins calibrate`` |

Frames and units: imu_link FLU (REP-103/REP-145: a level unit at rest reads (0, 0, +g)), SI
inside; user units (deg/s, mg, %, mrad) only in the file, the report and the command line.
"""
