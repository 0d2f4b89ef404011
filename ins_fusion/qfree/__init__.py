"""Q-Free OBU text logs (no ROS) for ``gnss_ins import-qfree``: ``logs`` parses the 35-column GNSS
and 14-column MEMS layouts and converts units and axes, ``checks`` refuses implausible or
out-of-order records."""
