"""A drive scripted as segments (stand, accelerate, turn, climb, stop at a light, roundabout,
U-turn) and built into a ``Trajectory`` (sim.trajectory): each segment sets knots of the three
smooth channels, the speed along the path, the yaw rate and the path pitch.
"""

from __future__ import annotations

import math

import numpy as np

from ins_fusion.sim.trajectory import GeodeticStart, SmoothChannel, Trajectory


class _ChannelBuilder:
    """Knots of one channel, appended in time order."""

    def __init__(self, value: float) -> None:
        self.t: list[float] = [0.0]
        self.y: list[float] = [value]

    @property
    def value(self) -> float:
        return self.y[-1]

    def hold_until(self, t_s: float) -> None:
        if t_s > self.t[-1]:
            self.t.append(t_s)
            self.y.append(self.y[-1])

    def ramp(self, t_start_s: float, duration_s: float, value: float) -> None:
        self.hold_until(t_start_s)
        self.t.append(t_start_s + duration_s)
        self.y.append(value)

    def build(self, end_s: float) -> SmoothChannel:
        self.hold_until(end_s)
        if len(self.t) == 1:
            self.t.append(self.t[0] + 1.0)
            self.y.append(self.y[0])
        return SmoothChannel(np.array(self.t), np.array(self.y))


class Route:
    """Builder of a drive from segments; each segment method advances the route clock.

    Turn angles are positive to the left (REP-103, counter-clockwise seen from above).
    """

    def __init__(self, start: GeodeticStart, speed_m_s: float = 0.0) -> None:
        self.start = start
        self.t_s = 0.0
        self._speed = _ChannelBuilder(speed_m_s)
        self._yaw_rate = _ChannelBuilder(0.0)
        self._pitch = _ChannelBuilder(0.0)

    @property
    def speed_m_s(self) -> float:
        """Speed at the end of the route so far [m/s]."""
        return self._speed.value

    def stand(self, duration_s: float) -> Route:
        """Stand still (or keep the current speed and heading) for duration_s."""
        self.t_s += duration_s
        return self

    cruise = stand

    def accelerate(self, speed_m_s: float, duration_s: float) -> Route:
        """Change speed smoothly to speed_m_s over duration_s (also for braking)."""
        self._speed.ramp(self.t_s, duration_s, speed_m_s)
        self.t_s += duration_s
        return self

    def turn(
        self,
        angle_deg: float,
        radius_m: float | None = None,
        rate_deg_s: float | None = None,
        ramp_s: float = 1.5,
    ) -> Route:
        """Turn by angle_deg (left positive) at constant speed, with the yaw rate set by a path
        radius (rate = speed/radius) or given directly; the rate ramps in and out over ramp_s
        (shortened for small angles so the turn angle is always exact)."""
        if (radius_m is None) == (rate_deg_s is None):
            raise ValueError("give exactly one of radius_m and rate_deg_s")
        if radius_m is not None:
            if self.speed_m_s <= 0.0:
                raise ValueError("a turn by radius needs a moving vehicle")
            rate = self.speed_m_s / radius_m
        else:
            rate = math.radians(abs(rate_deg_s or 0.0))
        angle = math.radians(angle_deg)
        total_s = abs(angle) / rate
        ramp = min(ramp_s, total_s)
        hold = total_s - ramp
        yaw_rate = -math.copysign(rate, angle)  # NED yaw: left turn = negative rate
        self._yaw_rate.ramp(self.t_s, ramp, yaw_rate)
        self._yaw_rate.ramp(self.t_s + ramp + hold, ramp, 0.0)
        self.t_s += total_s + ramp
        return self

    def climb(self, pitch_deg: float, duration_s: float, ramp_s: float = 3.0) -> Route:
        """Drive over a slope: path pitch ramps to pitch_deg, holds, ramps back to level; the
        whole segment lasts duration_s (>= 2 ramp_s)."""
        if duration_s < 2.0 * ramp_s:
            raise ValueError("a climb needs duration_s >= 2 * ramp_s")
        self._pitch.ramp(self.t_s, ramp_s, math.radians(pitch_deg))
        self._pitch.ramp(self.t_s + duration_s - ramp_s, ramp_s, 0.0)
        self.t_s += duration_s
        return self

    def stop_at_light(self, brake_s: float, wait_s: float, pull_away_s: float) -> Route:
        """Brake to a stop, wait, and pull away to the speed before the stop."""
        speed = self.speed_m_s
        return self.accelerate(0.0, brake_s).stand(wait_s).accelerate(speed, pull_away_s)

    def roundabout(
        self, radius_m: float, exit_angle_deg: float, deflection_deg: float = 45.0
    ) -> Route:
        """Right-hand-traffic roundabout at the current speed: deflect right to enter, circulate
        counter-clockwise, deflect right to leave; the net heading change is exit_angle_deg."""
        return (
            self.turn(-deflection_deg, radius_m=radius_m)
            .turn(exit_angle_deg + 2.0 * deflection_deg, radius_m=radius_m)
            .turn(-deflection_deg, radius_m=radius_m)
        )

    def u_turn(self, radius_m: float, left: bool = True) -> Route:
        """Half-circle turn of the given radius at the current speed."""
        return self.turn(180.0 if left else -180.0, radius_m=radius_m)

    def build(
        self, roll_per_lateral_accel_deg_per_m_s2: float = 0.5, duration_s: float | None = None
    ) -> Trajectory:
        """Trajectory of the route over duration_s (default: the route's own length): a longer
        one holds the final speed and heading, a shorter one is the start of the route.

        roll_per_lateral_accel: suspension roll gradient (body rolls out of the turn); typical
        cars 3-6 deg/g (assumption, not from the references).
        """
        end = self.t_s if duration_s is None else duration_s
        if end <= 0.0:
            raise ValueError("a trajectory needs a positive duration")
        return Trajectory(
            self.start,
            end,
            self._speed.build(end),
            self._yaw_rate.build(end),
            self._pitch.build(end),
            math.radians(roll_per_lateral_accel_deg_per_m_s2),
        )
