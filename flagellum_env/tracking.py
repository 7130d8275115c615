"""Waypoint bookkeeping: which waypoint is next, progress along the path, cross-track error.

Segment i runs from vertex i to vertex i + 1 of ``WaypointPath.vertices`` (vertex 0 is the
origin, vertex i + 1 is waypoint i). While waypoint i is the target, the head is on segment i.
All positions are in the start frame, metres.
"""

from __future__ import annotations


import numpy as np
from numba import njit

from flagellum_env.paths import WaypointPath
from physics.linalg.vec3 import norm3, segment_projection


class PathTracker:
    """Follows the head along a ``WaypointPath``; a waypoint counts once the head is within
    ``reach_radius_m`` of it, and only the current target can be reached (in order)."""

    def __init__(self, path: WaypointPath, reach_radius_m: float) -> None:
        if not reach_radius_m > 0.0:
            raise ValueError(f"reach_radius_m={reach_radius_m!r} must be > 0 (metres)")
        self.path = path
        self.reach_radius_m = float(reach_radius_m)
        self._vertices = path.vertices
        self._lengths = path.segment_lengths
        self._cumulative = np.concatenate([[0.0], np.cumsum(self._lengths)])
        self._cumulative.setflags(write=False)
        self.path_length_m = path.length_m  # m
        self._n_waypoints = path.n_waypoints
        self.index = 0  # current target waypoint; == n_waypoints when the path is complete

    @property
    def done(self) -> bool:
        """True once the last waypoint has been reached."""
        return self.index >= self._n_waypoints

    @property
    def n_reached(self) -> int:
        return self.index

    def update(self, position: np.ndarray) -> int:
        """Advance past every waypoint now within the reach radius; returns how many, (3,) m input."""
        reached = 0
        while not self.done and norm3(position - self.path.waypoints[self.index]) <= self.reach_radius_m:
            self.index += 1
            reached += 1
        return reached

    def mark_reached(self, count: int) -> None:
        """Count the next ``count`` waypoints as reached: for a caller that applied ``update``'s test itself
        (``agents.surrogate_legs``, along a leg)."""
        if count < 0 or self.index + count > self.path.n_waypoints:
            raise ValueError(f"count={count!r} must be in [0, {self.path.n_waypoints - self.index}] (waypoints left)")
        self.index += count

    def _segment(self) -> int:
        return min(self.index, self.path.n_waypoints - 1)

    def segment(self) -> tuple[np.ndarray, np.ndarray]:
        """The current segment's start and end, ((3,), (3,)) m (the last one once the path is complete)."""
        i = self._segment()
        return self._vertices[i], self._vertices[i + 1]

    def _projection(self, position: np.ndarray) -> tuple[float, np.ndarray]:
        """(clipped arc length along the current segment, m; closest point on it, (3,) m)."""
        i = self._segment()
        s, c0, c1, c2 = segment_projection(np.asarray(position, dtype=np.float64), self._vertices[i],
                                           self._vertices[i + 1], float(self._lengths[i]))
        return s, np.array([c0, c1, c2])

    def progress(self, position: np.ndarray) -> float:
        """Arc length of the path covered, m: the finished segments plus the head's clipped
        projection onto the current one (the full length once the path is complete)."""
        return path_progress(np.asarray(position, dtype=np.float64), self.index, self._vertices, self._lengths,
                             self._cumulative)

    @property
    def cumulative_m(self) -> np.ndarray:
        """The path's length up to each vertex, (k + 1,) m from 0 (read-only; ``path_progress``)."""
        return self._cumulative

    def cross_track_error(self, position: np.ndarray) -> float:
        """Distance from the head to the current segment, m (to the last one once complete)."""
        _, closest = self._projection(position)
        return norm3(position - closest)

    def distance_to_target(self, position: np.ndarray) -> float:
        """Distance from the head to the current target waypoint (the last one once complete), m."""
        return norm3(position - self.path.waypoints[self._segment()])

    def targets(self, count: int) -> np.ndarray:
        """The next ``count`` waypoints from the current target on, the last repeated, (count, 3) m."""
        last = self._n_waypoints - 1
        return self.path.waypoints[[min(k, last) for k in range(self.index, self.index + count)]]


@njit(cache=True)
def path_progress(position: np.ndarray, index: int, vertices: np.ndarray, lengths: np.ndarray,
                  cumulative: np.ndarray) -> float:
    """``PathTracker.progress``: the arc length (m) covered at ``position`` (3,) m with waypoint ``index`` the target,
    the finished segments plus the clipped projection onto the current one (the full length once ``index`` is past
    the last); ``vertices`` (k + 1, 3) m, ``lengths`` (k,) m, ``cumulative`` (k + 1,) m (``cumulative_m``)."""
    n = lengths.shape[0]
    if index >= n:
        return cumulative[n]
    s = segment_projection(position, vertices[index], vertices[index + 1], lengths[index])[0]
    return cumulative[index] + s


class BucklingMonitor:
    """Counts buckling events from the end-to-end ratio L'/L with hysteresis.

    An event starts when L'/L drops below ``threshold``; the next one can start only after
    L'/L has risen above ``release`` (the flagellum relaxed).
    """

    def __init__(self, threshold: float = 0.9, release: float = 0.95) -> None:
        if not 0.0 < threshold < release:
            raise ValueError(f"buckling threshold={threshold!r} and release={release!r} need 0 < threshold < release")
        self.threshold = float(threshold)
        self.release = float(release)
        self.buckled = False
        self.events = 0

    def update(self, end_to_end_ratio: float) -> bool:
        """Feed one L'/L value; True if a new buckling event started."""
        if not self.buckled and end_to_end_ratio < self.threshold:
            self.buckled = True
            self.events += 1
            return True
        if self.buckled and end_to_end_ratio > self.release:
            self.buckled = False
        return False
