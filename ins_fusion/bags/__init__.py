"""Bags (no rclpy): rosbag2 reading, writing and recovery (``bag_io``, ``recover``), empty
rosbags messages to fill (``messages``), the topic names and types of the nodes (``topics``) and
the IMU samples of a bag as arrays (``imu``)."""
