"""Map a sensor's own clock onto the host clock by the lower envelope of the receive delays.

A sensor stamps its samples on its own time axis (IMU device time, GNSS UTC); the host only knows
when the bytes arrived. Each pair (sensor time ``s``, host time ``h``, the arrival already minus
the serial transmission time) satisfies ``h = offset + (1 + skew) * s + delay`` with ``delay >= 0``
(ARCHITECTURE.md, "The shared clock"). The delays of ``d = h - s`` against ``s`` are
therefore bounded below by the line ``offset + skew * s``: the mapping is the lower convex hull of
the points in a sliding window, and of its supporting lines the one that minimises the mean
distance of the points above it, i.e. the hull edge spanning the mean sensor time (Moon, Skelly &
Towsley, "Estimation and removal of clock skew from network delay measurements", INFOCOM 1999).
Unlike the newest hull edge, that line does not swing with each new low point. docs/timing.md
explains the method for users.

Why the hull is written here: scipy.spatial.ConvexHull (Qhull) is batch-only, so every sample
would cost O(n log n) for the ~8000 points of a 60 s IMU window; no installed library keeps a
sliding-window hull. The window is a queue of two monotone chains (Andrew 1979): new points are
pushed on the back chain; the front chain holds the older points pushed from newest to oldest
over mirrored sensor times, logging what each push removed, so that dropping the oldest point is
undoing the front chain's last push. The line is then the lower bridge between the two chains (a
short walk) or an edge of one of them (a bisection).

The next front chain is built a few points per update while the current one still serves (a
de-amortised two-stack queue: rebuilding all ~8000 points at once took 7-33 ms of the serial
reader's time once a minute): when the back holds as many points as the front, the whole window
is taken as a snapshot and pushed into a new front chain, ``REBUILD_STEPS`` points per update,
while new points go on both the current back chain and a fresh one; when the new front is done it
replaces the front and the fresh chain the back. Each point is pushed about three times and
undone once: O(1) per sample, in the worst case too.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Collection
from itertools import chain
from operator import itemgetter
from typing import NamedTuple

#: A point (sensor time, delay) relative to the first point since the last reset [s].
_Point = tuple[float, float]

_x = itemgetter(0)
_y = itemgetter(1)


def _cross(o: _Point, a: _Point, b: _Point) -> float:
    """z of (a - o) x (b - o): positive when b lies above the line o -> a (for o left of a)."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _mirror(p: _Point) -> _Point:
    return (-p[0], p[1])


class _LowerChain:
    """Lower convex hull of points pushed in increasing x (Andrew's monotone chain)."""

    def __init__(self) -> None:
        self.vertices: list[_Point] = []

    def push(self, p: _Point) -> tuple[_Point, ...]:
        """Append ``p`` and return the vertices it hid, newest first (for ``undo``)."""
        v = self.vertices
        hidden: list[_Point] = []
        while len(v) >= 2 and _cross(v[-2], v[-1], p) <= 0.0:
            hidden.append(v.pop())
        v.append(p)
        return tuple(hidden)  # usually the shared empty tuple: nothing to allocate or collect

    def undo(self, hidden: tuple[_Point, ...]) -> None:
        """Revert the last ``push``, given what it returned."""
        self.vertices.pop()
        self.vertices.extend(reversed(hidden))


def _edge_at(chain: list[_Point], x: float, lo: int) -> tuple[_Point, _Point]:
    """The edge of ``chain[lo:]`` (at least two vertices, ascending x) spanning ``x``, or the
    nearest end edge when ``x`` lies outside."""
    k = bisect.bisect_right(chain, x, lo + 1, len(chain) - 1, key=_x)
    return chain[k - 1], chain[k]


def _bridge(front: list[_Point], back: list[_Point]) -> tuple[int, int]:
    """Indices (i, j) of the lower common tangent of the mirrored front chain and the back chain.

    The front chain's points all lie left of the back chain's. The walk starts from the facing
    ends and only moves outwards, so it stops after at most len(front) + len(back) steps (a few in
    practice: it only crosses the vertices near the join).
    """
    i = j = 0
    u, v = _mirror(front[0]), back[0]
    while True:
        if i + 1 < len(front) and _cross(u, v, _mirror(front[i + 1])) < 0.0:
            i += 1
            u = _mirror(front[i])
        elif j + 1 < len(back) and _cross(u, v, back[j + 1]) < 0.0:
            j += 1
            v = back[j]
        else:
            return i, j


class _Moments:
    """Count, means and co-moments of the window's points (Welford's update; removal reverses
    it), for the mean sensor time and the delay statistics without cancellation."""

    def __init__(self) -> None:
        self.n = 0
        self.mean_x = self.mean_y = self.cxx = self.cxy = self.cyy = 0.0

    def add(self, p: _Point) -> None:
        self.n += 1
        dx, dy = p[0] - self.mean_x, p[1] - self.mean_y
        self.mean_x += dx / self.n
        self.mean_y += dy / self.n
        self.cxx += dx * (p[0] - self.mean_x)
        self.cxy += dx * (p[1] - self.mean_y)
        self.cyy += dy * (p[1] - self.mean_y)

    def remove(self, p: _Point) -> None:
        self.n -= 1
        if self.n == 0:
            self.mean_x = self.mean_y = self.cxx = self.cxy = self.cyy = 0.0
            return
        dx, dy = p[0] - self.mean_x, p[1] - self.mean_y
        self.mean_x -= dx / self.n
        self.mean_y -= dy / self.n
        self.cxx -= dx * (p[0] - self.mean_x)
        self.cxy -= dx * (p[1] - self.mean_y)
        self.cyy -= dy * (p[1] - self.mean_y)

    def merged(self, other: _Moments) -> _Moments:
        """The moments of both point sets together (Chan, Golub & LeVeque's pairwise update)."""
        both = _Moments()
        both.n = self.n + other.n
        if both.n == 0:
            return both
        dx, dy = other.mean_x - self.mean_x, other.mean_y - self.mean_y
        share, weight = other.n / both.n, self.n * other.n / both.n
        both.mean_x = self.mean_x + dx * share
        both.mean_y = self.mean_y + dy * share
        both.cxx = self.cxx + other.cxx + dx * dx * weight
        both.cxy = self.cxy + other.cxy + dx * dy * weight
        both.cyy = self.cyy + other.cyy + dy * dy * weight
        return both

    def residuals(self, p: _Point, slope: float) -> tuple[float, float]:
        """Mean and RMS of y above the line through ``p`` with ``slope``."""
        mean = self.mean_y - p[1] - slope * (self.mean_x - p[0])
        variance = (self.cyy - 2.0 * slope * self.cxy + slope * slope * self.cxx) / self.n
        return mean, math.sqrt(max(mean * mean + variance, 0.0))


#: Points pushed into the next front chain per update while it is being built: it is started
#: when the back holds at least as many points as the front (half the window), and at one expiry
#: per update it is done after a fifth of the window's updates, well before the front runs out.
REBUILD_STEPS = 4


class _FrontRebuild:
    """The next front chain, built from a snapshot of the window a few points per update, and
    the fresh back chain of the points that arrive meanwhile."""

    def __init__(self, window: Collection[_Point], first: int) -> None:
        """``window``: every point of the window, oldest first; ``first``: how many points had
        left the window before the oldest of them."""
        self.snapshot = list(window)
        self.first = first
        self.todo = len(self.snapshot)  # snapshot[:todo] not pushed yet (pushed newest first)
        self.front = _LowerChain()
        self.front_hidden: deque[tuple[_Point, ...]] = deque()
        self.front_moments = _Moments()
        self.back = _LowerChain()
        self.back_moments = _Moments()

    def add(self, p: _Point) -> None:
        """A point newer than the snapshot."""
        self.back.push(p)
        self.back_moments.add(p)

    def step(self, count: int, expired: int) -> bool:
        """Push up to ``count`` more snapshot points, none of the ``expired`` oldest; True when
        every snapshot point still in the window is pushed."""
        for _ in range(max(min(count, self.todo - expired), 0)):
            self.todo -= 1
            p = self.snapshot[self.todo]
            self.front_hidden.appendleft(self.front.push(_mirror(p)))
            self.front_moments.add(p)
        return self.todo <= expired

    def finish(self, expired: int) -> None:
        """Push the rest and take back the pushes of points that have left the window since
        (the oldest were pushed last, so they are undone in the order pushes are undone)."""
        self.step(self.todo, expired)
        for p in self.snapshot[self.todo : expired]:
            self.front.undo(self.front_hidden.popleft())
            self.front_moments.remove(p)


class _Fit(NamedTuple):
    """The current mapping, replaced as a whole on each update (so readers on other threads see
    a consistent one): the line ``delay = delay_s + skew * (sensor - sensor_s)``."""

    sensor_s: float
    delay_s: float
    skew: float
    jitter_s: float
    mean_delay_s: float


class EnvelopeClockSync:
    """Online sensor-time -> host-time mapping ``host = offset + (1 + skew) * sensor``.

    Feed ``update(sensor_time_s, host_time_s)`` with the host time already corrected by the
    transmission time of the bytes up to the stamped point; map with ``to_host``. Sensor time must
    increase: a repeated sensor time is ignored (the first pair is kept), a backwards step or a
    forward jump over ``max_jump_s`` restarts the mapping (counted in ``resets``). Until
    ``ready`` the mapping is offset only (skew 0, through the lowest delay): a skew fitted over a
    few points is noise, and packets read in one chunk even give a slope of -1. One thread
    updates; the properties may be read from any thread.
    """

    def __init__(
        self,
        window_s: float = 60.0,
        min_points: int = 10,
        max_jump_s: float = 10.0,
        max_skew: float = math.inf,
    ):
        """``window_s``: span of the sliding window [s], long enough to average the jitter, short
        enough to follow oscillator drift. ``min_points``: points needed before ``ready``.
        ``max_jump_s``: largest accepted forward step of sensor time [s]. ``max_skew``: largest
        plausible ``|skew|``; a steeper hull (delays that shrink or grow for a while, e.g. a
        backlog draining) gives the supporting line of that slope instead."""
        if window_s <= 0.0 or max_jump_s <= 0.0 or min_points < 1 or not max_skew > 0.0:
            raise ValueError("window_s, max_jump_s and max_skew must be > 0, min_points >= 1")
        self.window_s = window_s
        self.min_points = min_points
        self.max_jump_s = max_jump_s
        self.max_skew = max_skew
        self._resets = 0
        self._clear()

    def _clear(self) -> None:
        self._origin: _Point = (0.0, 0.0)  # absolute (sensor, delay) of the first point [s]
        self._window: deque[_Point] = deque()  # every point in the window, oldest first
        self._front = _LowerChain()  # over mirrored points: the oldest part of the window
        self._front_hidden: deque[tuple[_Point, ...]] = deque()  # per front point, its push log
        self._back = _LowerChain()  # the newest part of the window
        self._moments = _Moments()
        self._expired = 0  # points that have left the window since the last reset
        self._rebuild: _FrontRebuild | None = None  # the next front chain, while it is built
        self._last_sensor_s = -math.inf
        self._fit: _Fit | None = None

    # ---- feeding ---------------------------------------------------------------------------
    def update(self, sensor_time_s: float, host_time_s: float) -> None:
        """Add one pair: sensor time [s] and host time [s] of the same instant plus its delay."""
        if not (math.isfinite(sensor_time_s) and math.isfinite(host_time_s)):
            raise ValueError(f"non-finite pair ({sensor_time_s}, {host_time_s})")
        step = sensor_time_s - self._last_sensor_s
        if step == 0.0:
            return
        if self._window and (step < 0.0 or step > self.max_jump_s):
            self.reset()
        if not self._window:
            self._origin = (sensor_time_s, host_time_s - sensor_time_s)
        self._last_sensor_s = sensor_time_s
        p = (sensor_time_s - self._origin[0], host_time_s - sensor_time_s - self._origin[1])
        self._expire_before(p[0] - self.window_s)
        self._window.append(p)
        self._back.push(p)
        self._moments.add(p)
        self._build_front(p)
        self._fit = self._compute_fit()

    def reset(self) -> None:
        """Forget every point (e.g. after a reconnect); counted in ``resets``."""
        self._resets += 1
        self._clear()

    def _expire_before(self, x_min: float) -> None:
        while self._window and self._window[0][0] < x_min:
            if not self._front_hidden:  # only after an irregular stretch: the rebuild was late
                self._replace_front()
            self._front.undo(self._front_hidden.popleft())
            self._moments.remove(self._window.popleft())
            self._expired += 1

    def _build_front(self, p: _Point) -> None:
        """After ``p`` joined the window: the next front chain a few points further, started
        when the back holds as many points as the front, and put in place when done."""
        rebuild = self._rebuild
        if rebuild is not None:
            rebuild.add(p)
        elif len(self._window) >= 2 * len(self._front_hidden):
            rebuild = self._rebuild = _FrontRebuild(self._window, self._expired)
        else:
            return
        if rebuild.step(REBUILD_STEPS, self._expired - rebuild.first):
            self._replace_front()

    def _replace_front(self) -> None:
        """Put the next front chain in place (the whole window's when none is being built),
        finished now if it is not yet; the moments start again from the two chains' own sums,
        so that rounding cannot build up over hours."""
        rebuild = self._rebuild or _FrontRebuild(self._window, self._expired)
        rebuild.finish(self._expired - rebuild.first)
        self._front, self._front_hidden = rebuild.front, rebuild.front_hidden
        self._back = rebuild.back
        self._moments = rebuild.front_moments.merged(rebuild.back_moments)
        self._rebuild = None

    # ---- the line --------------------------------------------------------------------------
    def _support_at_mean(self) -> tuple[_Point, float]:
        """(a point of, slope of) the supporting line of the window's hull at the mean x; until
        ``ready`` (and for one point) the horizontal one through the lowest point."""
        if len(self._window) < max(self.min_points, 2):  # the lowest point is a hull vertex
            return min(chain(map(_mirror, self._front.vertices), self._back.vertices), key=_y), 0.0
        x_mean = self._moments.mean_x
        front, back = self._front.vertices, self._back.vertices  # one of them may be empty
        if not front:
            p, q = _edge_at(back, x_mean, 0)
        elif not back:
            q, p = map(_mirror, _edge_at(front, -x_mean, 0))
        else:
            i, j = _bridge(front, back)
            p, q = _mirror(front[i]), back[j]
            if x_mean < p[0]:
                p, q = _edge_at(front, -x_mean, i)
                p, q = _mirror(p), _mirror(q)
            elif x_mean > q[0]:
                p, q = _edge_at(back, x_mean, j)
        slope = (q[1] - p[1]) / (q[0] - p[0])
        if abs(slope) <= self.max_skew:
            return p, slope
        slope = math.copysign(self.max_skew, slope)
        vertices = chain(map(_mirror, front), back)
        return min(vertices, key=lambda v: v[1] - slope * v[0]), slope

    def _compute_fit(self) -> _Fit:
        p, skew = self._support_at_mean()
        mean_delay_s, jitter_s = self._moments.residuals(p, skew)
        return _Fit(
            sensor_s=self._origin[0] + p[0],
            delay_s=self._origin[1] + p[1],
            skew=skew,
            jitter_s=jitter_s,
            mean_delay_s=mean_delay_s,
        )

    # ---- reading ---------------------------------------------------------------------------
    def to_host(self, sensor_time_s: float) -> float:
        """Host time [s] of a sensor time [s] on the current mapping (RuntimeError before the
        first point). Use this rather than ``offset_s`` with large sensor times (UTC): it keeps
        full precision."""
        fit = self._fit
        if fit is None:
            raise RuntimeError("EnvelopeClockSync has no points yet")
        return sensor_time_s + fit.delay_s + fit.skew * (sensor_time_s - fit.sensor_s)

    @property
    def ready(self) -> bool:
        """At least ``min_points`` points in the window."""
        return len(self._window) >= self.min_points

    @property
    def points(self) -> int:
        """Points in the window."""
        return len(self._window)

    @property
    def resets(self) -> int:
        """Restarts so far: explicit ``reset()`` calls, backwards steps and jumps."""
        return self._resets

    @property
    def offset_s(self) -> float:
        """Host time at sensor time 0 [s]; NaN before the first point."""
        fit = self._fit
        return math.nan if fit is None else fit.delay_s - fit.skew * fit.sensor_s

    @property
    def skew(self) -> float:
        """Host seconds per sensor second minus 1 (drift in ppm = skew * 1e6); 0 until
        ``ready``."""
        return 0.0 if self._fit is None else self._fit.skew

    @property
    def jitter_s(self) -> float:
        """RMS of the window's delays above the line [s]."""
        return 0.0 if self._fit is None else self._fit.jitter_s

    @property
    def mean_delay_s(self) -> float:
        """Mean of the window's delays above the line [s]."""
        return 0.0 if self._fit is None else self._fit.mean_delay_s
