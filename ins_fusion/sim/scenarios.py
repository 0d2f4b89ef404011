"""Named drives for tests, benchmarks and ``gnss_ins simulate --scenario NAME``.

All start near the Aalborg test site (Aalborg notes §8.1, in
shared/reference/imu400cc-aalborg-notes.md; φ = 57°, h = 40 m as in §5.3). Every scenario
accepts a duration: a drive shorter than the requested duration is extended at its final state
(all end standing still except the two constructed Aalborg runs, which end cruising).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ins_fusion.sim.route import Route
from ins_fusion.sim.trajectory import GeodeticStart, Mounting, Trajectory
from ins_fusion.sim.vehicle import VehicleSetup

#: Near the taxi rank north of Fibigerstræde 11, Aalborg Øst (approximate), heading north.
AALBORG_START = GeodeticStart(math.radians(57.0150), math.radians(9.9870), 40.0, 0.0)

#: A survey car (assumption; the Aalborg report never measured its lever arms, §7.4): IMU on the
#: roof frame 0.8 m ahead of base_link (rear axle centre on the ground) and 1.6 m up, the GNSS
#: antenna above the rear axle at 1.75 m, the odometer (DMI) on the left rear wheel's hub (1.6 m
#: track, 0.33 m tyre radius).
SURVEY_CAR = VehicleSetup(
    imu=Mounting(lever_arm_flu_m=(0.8, 0.0, 1.6)),
    gnss_antenna_flu_m=(0.0, 0.0, 1.75),
    odometer_flu_m=(0.0, 0.8, 0.33),
)

_KMH = 1.0 / 3.6


def _urban_drive(route: Route) -> Route:
    """180 s of urban driving from standstill back to standstill: turns, a roundabout, a slope
    and a red light (after the Aalborg route of §8.1: taxi rank, roundabout, Langagervej to the
    lights at Humlebakken)."""
    end = route.t_s + 180.0
    route.accelerate(30 * _KMH, 8.0).cruise(10.0).turn(-90.0, radius_m=20.0)
    route.accelerate(50 * _KMH, 8.0).cruise(8.0).accelerate(25 * _KMH, 5.0)
    route.roundabout(radius_m=15.0, exit_angle_deg=90.0)
    route.accelerate(50 * _KMH, 6.0).climb(3.0, 20.0)
    route.stop_at_light(brake_s=9.0, wait_s=15.0, pull_away_s=10.0)
    route.accelerate(20 * _KMH, 5.0).turn(90.0, radius_m=15.0).accelerate(40 * _KMH, 6.0)
    brake_s = 8.0
    cruise_s = end - brake_s - route.t_s
    if cruise_s <= 0.0:
        raise RuntimeError("the urban drive segments exceed 180 s")
    route.cruise(cruise_s).accelerate(0.0, brake_s)
    return route


def seed_test_pattern(
    duration_s: float | None = None, start: GeodeticStart = AALBORG_START
) -> Trajectory:
    """The test pattern of the reference drives (Aalborg notes §8.1): 60 s standstill, then 180 s
    of urban driving; repeated 180 s drives fill a longer duration (600 s = 60 + 3 × 180), and a
    duration that ends within a drive ends the pattern there (150 s = standstill + 90 s drive)."""
    total = 240.0 if duration_s is None else duration_s
    route = Route(start).stand(60.0)
    while route.t_s < total - 1e-9:
        _urban_drive(route)
    return route.build(duration_s=total)


def figure_eight(
    duration_s: float = 600.0,
    speed_m_s: float = 10.0,
    radius_m: float = 40.0,
    start: GeodeticStart = AALBORG_START,
) -> Trajectory:
    """10 s standstill, accelerate, then figure-eights (a left and a right full circle) at
    constant speed until the time left only allows braking to a stop."""
    route = Route(start).stand(10.0).accelerate(speed_m_s, 10.0)
    brake_s = 8.0
    lap_s = 2.0 * (2.0 * math.pi * radius_m / speed_m_s + 1.5)
    while route.t_s + lap_s + brake_s <= duration_s:
        route.turn(360.0, radius_m=radius_m).turn(-360.0, radius_m=radius_m)
    route.cruise(max(0.0, duration_s - brake_s - route.t_s)).accelerate(0.0, brake_s)
    return route.build(duration_s=max(duration_s, route.t_s))


def aalborg_straight(duration_s: float = 180.0, start: GeodeticStart = AALBORG_START) -> Trajectory:
    """Constructed straight run of the Aalborg sensitivity study (§3.4, Fig. 2-1): 20 km/h,
    accelerate to 60 km/h in 10 s (mean 1.1133 m/s²), cruise."""
    route = Route(start, speed_m_s=20 * _KMH).accelerate(60 * _KMH, 10.0)
    return route.build(duration_s=duration_s)


def aalborg_turn(duration_s: float = 180.0, start: GeodeticStart = AALBORG_START) -> Trajectory:
    """Constructed turn of the Aalborg sensitivity study (§3.4, Fig. 2-1): 60 km/h, a 90° turn
    at 9 °/s (about 10 s), then straight."""
    route = Route(start, speed_m_s=60 * _KMH).turn(-90.0, rate_deg_s=9.0)
    return route.build(duration_s=duration_s)


SCENARIOS: dict[str, Callable[[float], Trajectory]] = {
    "test_pattern": seed_test_pattern,
    "figure_eight": figure_eight,
    "aalborg_straight": aalborg_straight,
    "aalborg_turn": aalborg_turn,
}
