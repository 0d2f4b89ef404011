"""Pure fusion core (no ROS): earth model, strapdown mechanization, error-state filter."""
