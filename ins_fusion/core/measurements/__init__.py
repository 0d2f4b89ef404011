"""The measurements: models, noise, handlers and the compiled update of each kind (GNSS position
and velocity, attitude, course heading, ZUPT/ZARU with the stop detector, NHC)."""
