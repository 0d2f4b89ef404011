"""The error-state filter: covariance algebra and state layout, the nominal state, the time
update, the late-measurement timeline, noise adaptation, the records it takes in, the counters."""
