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


#: A NavSatFix vertical variance at or above this [m²] ((1 km)², the drivers' "not measured"
#: variance, message_fields.UNKNOWN_VARIANCE), or a NaN altitude, marks the height as unknown: a
#: 2-D fix, whose horizontal position alone is measured. The GNSS driver publishes 2-D fixes
#: with a NaN altitude and this vertical variance; the fusion uses only their horizontal part.
HEIGHT_UNKNOWN_VARIANCE_M2 = 1.0e6
