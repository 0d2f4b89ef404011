"""NTRIP client: network-RTK corrections (RTCM 3 over HTTP) for the rover, without ROS."""
