"""sensor_msgs/NavSatStatus and NavSatFix constants (ROS 2 common_interfaces), defined once for the
code that fills or reads those messages without rclpy: the GNSS driver, the fusion node's
adapters, the simulator and the importers. Fields take them as ``int(...)``.
"""

from __future__ import annotations

from enum import IntEnum


class NavSatStatus(IntEnum):
    """sensor_msgs/NavSatStatus ``status`` values; below FIX no position."""

    UNKNOWN = -2
    NO_FIX = -1
    FIX = 0
    SBAS_FIX = 1
    GBAS_FIX = 2


#: sensor_msgs/NavSatStatus ``service`` bits.
SERVICE_GPS, SERVICE_GLONASS, SERVICE_COMPASS, SERVICE_GALILEO = 1, 2, 4, 8


class CovarianceType(IntEnum):
    """sensor_msgs/NavSatFix ``position_covariance_type`` values."""

    UNKNOWN = 0
    APPROXIMATED = 1
    DIAGONAL_KNOWN = 2
    KNOWN = 3
