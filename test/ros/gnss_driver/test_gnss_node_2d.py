"""gnss_node (rclpy) reading receivers that leave the satellite count out or fall back to 2-D
fixes, over a pseudo-terminal: the sentences of test_gnss_fix_rules.py (NMEA 0183, Garmin GPS
18x / Furuno GN-87 style: GGA with ``00`` satellites, GSA per constellation) written to the
real node, which publishes them as fixes on gnss/fix."""

from __future__ import annotations

import math

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import NavSatFix, NavSatStatus
from support.nmea_sentences import ALT, GSA_GLONASS, GSA_GPS, gga, rmc
from support.pacing import pause
from support.ros_harness import Collector, diagnostic_values, overrides, spinning, wait_for

from gnss_driver.node import GnssNode
from gnss_driver.reader import frame_sentence
from gnss_ins_common.navsat import HEIGHT_UNKNOWN_VARIANCE_M2
from gnss_ins_common.pty_device import PtyDevice

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def test_fixes_with_00_satellites_2d_fixes_and_held_altitudes_are_published():
    epochs = [
        [gga(second, 1, "00"), GSA_GPS.format(3), GSA_GLONASS.format(3), rmc(second)]
        for second in range(10, 14)
    ]
    epochs += [[gga(second, 1, "03"), rmc(second)] for second in (14, 15)]  # 2-D
    epochs += [[gga(16)], [rmc(17)]]  # 3-D, then RMC only: held altitude
    collector = Collector({"gnss/fix": NavSatFix, "/diagnostics": DiagnosticArray})
    with PtyDevice() as device:
        node = GnssNode(
            parameter_overrides=overrides(
                port=device.path,
                receiver="generic",
                baud=115200,
                epoch_idle_timeout=0.1,
                diagnostics_period=0.2,
            )
        )
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: node.port_open, 10.0)
                for bodies in epochs:
                    device.write(b"".join(frame_sentence(b) for b in bodies))
                    pause(0.25)  # one epoch, ended by the idle time-out (0.1 s)
                assert wait_for(lambda: collector.count("gnss/fix") >= len(epochs), 5.0)
                assert collector.more("/diagnostics", 1, 5.0)  # a report after the last epoch
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    fixes = collector.get("gnss/fix")
    assert len(fixes) == len(epochs)
    for fix in fixes:
        assert fix.status.status == NavSatStatus.STATUS_FIX
        assert math.isfinite(fix.latitude) and fix.position_covariance[0] > 0.0
    for fix in fixes[:4]:  # 00 satellites: the count from the GSAs, a 3-D fix
        assert fix.altitude == pytest.approx(ALT)
        assert fix.position_covariance[8] < HEIGHT_UNKNOWN_VARIANCE_M2
    for fix in fixes[4:6]:  # 3 satellites: 2-D
        assert math.isnan(fix.altitude)
        assert fix.position_covariance[8] == HEIGHT_UNKNOWN_VARIANCE_M2
    held = fixes[7]
    assert held.altitude == pytest.approx(ALT)
    assert held.position_covariance[8] == pytest.approx(fixes[6].position_covariance[8] + 4.0)
    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert int(values["satellites_unreported"]) == 4 and int(values["fixes_2d"]) == 2
    assert int(values["held_altitudes"]) == 1 and int(values["too_few_satellites"]) == 0
