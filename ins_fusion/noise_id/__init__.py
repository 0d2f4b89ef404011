"""IMU noise identification from static records (``gnss_ins allan``; no ROS).

- ``allan``: overlapping Allan deviation per series (allantools), the power-law noise type and the
  equivalent degrees of freedom of every point, confidence intervals.
- ``terms``: the IEEE 952 noise terms fitted to a curve (quantisation, white noise, Gauss-Markov
  or flicker bias instability, random walk) with their confidence intervals, and the classic
  flat-minimum read-off.
- ``record``: the sample clock of a static IMU record (ins_fusion.bags.imu.ImuRecord: sample
  times, rates, specific forces) and the checks that refuse irregular, non-finite, constant or
  moving records.
- ``whittle``: white noise, Gauss-Markov bias and random walk fitted to the samples by the
  debiased Whittle likelihood of their block means, with Fisher-information errors.
- ``likelihood``: the Allan fit's terms with the bias and random walk of the Whittle fit.
- ``analysis``: every gyro and accelerometer axis of a record, the user-facing units, the length
  a record needs and what a report lacks for the requested terms.
- ``provisional``: a bias instability the record is too short to pin, written all the same
  (IEEE 952 floor and a Gauss-Markov σ fitted at the longest time the record shows), flagged.
- ``output``: the summary table and the ROS parameter file of ins_fusion_node (imu_noise.*).
- ``plot``: the log-log figure with the data and the fitted lines.
- ``synthetic``: static records of a simulated IMU (ins_fusion.sim) and their bags, for the
  tests, the benchmark and trying the tool.

References are to shared/reference/: "Oslo" mems-noise-oslo-notes.md, "Aalborg"
imu400cc-aalborg-notes.md.
"""
