"""Vehicle and sensor simulator (no ROS): trajectories and sensor error models."""
