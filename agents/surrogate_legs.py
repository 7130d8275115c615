"""One straight leg of the turn-level surrogate's head: waypoints reached on it, its cross-track integral, the
path's end, leaving the path, the time budget.

``FlagellumSteer-v0`` checks these at every physics step and control step (``flagellum_env.steer_env``,
``flagellum_env.tracking.PathTracker``); the surrogate moves the head along straight legs (cruise, hover, the chord
of a turn) at a uniform speed and evaluates the same bookkeeping on each leg in closed form or by quadrature:

- a waypoint counts where the leg first enters its reach sphere (|a + s (b - a) - w| = R, the smaller root),
  and only the current target can be reached, in order (``PathTracker.update``);
- the cross-track error (``PathTracker.cross_track_error``) is integrated over time, int e dt, by 3-point
  Gauss-Legendre per piece between waypoint switches (the physics env sums e x control_dt per control step:
  ``flagellum_env.rewards``, term ``cross_track``);
- off the path: e > ``off_path_m`` at a quadrature point or the leg's end ends the leg there;
- the time budget (``time_limit_s``) cuts the leg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flagellum_env.tracking import PathTracker

#: 3-point Gauss-Legendre nodes on [0, 1] and weights.
_GAUSS_X = (0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6))
_GAUSS_W = (5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0)


@dataclass
class LegResult:
    """What a leg did: ``end`` (3,) m where the head stopped, ``duration_s`` flown, ``reached`` waypoints,
    ``cross_integral`` (m s, int e dt), ``off_path`` / ``timed_out`` (why it stopped early, if so),
    ``energy_j`` (set by the caller, J)."""

    end: np.ndarray
    duration_s: float
    reached: int = 0
    cross_integral: float = 0.0
    off_path: bool = False
    timed_out: bool = False
    energy_j: float = 0.0


def _entry(a, v, w, radius: float) -> tuple[float, float] | None:
    """(s of the first entry into the sphere |x - w| <= radius along x = a + s v, s in [0, 1]; s of the closest
    approach, clipped) or None if the leg stays outside; a, v, w 3-sequences of floats (m)."""
    q0, q1, q2 = a[0] - w[0], a[1] - w[1], a[2] - w[2]
    aa = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    bb = 2.0 * (q0 * v[0] + q1 * v[1] + q2 * v[2])
    cc = q0 * q0 + q1 * q1 + q2 * q2 - radius * radius
    if cc <= 0.0:
        return 0.0, 0.0
    if aa <= 0.0:
        return None
    disc = bb * bb - 4.0 * aa * cc
    if disc < 0.0:
        return None
    s = (-bb - math.sqrt(disc)) / (2.0 * aa)
    if not 0.0 <= s <= 1.0:
        return None
    return s, min(max(-bb / (2.0 * aa), 0.0), 1.0)


class SegmentFrames:
    """The path's segments as floats for fast cross-track errors: segment i from vertex i (``start``) along the unit
    ``direction`` for ``length`` m; the error of a point is its distance from the closest point of the current
    segment (``PathTracker.cross_track_error``'s definition: projection clipped to the segment)."""

    def __init__(self, tracker: PathTracker) -> None:
        vertices = tracker.path.vertices
        lengths = tracker.path.segment_lengths
        self.frames = [(tuple(vertices[i].tolist()), tuple(((vertices[i + 1] - vertices[i]) / lengths[i]).tolist()),
                        float(lengths[i])) for i in range(len(lengths))]
        self.waypoints = [tuple(w) for w in tracker.path.waypoints.tolist()]

    def error(self, index: int, x0: float, x1: float, x2: float) -> float:
        """Cross-track error (m) of the point (x0, x1, x2) m while waypoint ``index`` is the target."""
        (a0, a1, a2), (u0, u1, u2), length = self.frames[min(index, len(self.frames) - 1)]
        r0, r1, r2 = x0 - a0, x1 - a1, x2 - a2
        s = min(max(r0 * u0 + r1 * u1 + r2 * u2, 0.0), length)
        e0, e1, e2 = r0 - s * u0, r1 - s * u1, r2 - s * u2
        return math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


def fly_leg(tracker: PathTracker, frames: SegmentFrames, start: np.ndarray, end: np.ndarray, duration_s: float,
            time_s: float, time_limit_s: float, off_path_m: float, stop_at_waypoint: bool) -> LegResult:
    """Move the head from ``start`` to ``end`` (3,) m in ``duration_s`` s starting at episode time ``time_s``
    (module docstring); ``stop_at_waypoint``: end the leg where a waypoint is reached (the planner re-plans then).
    ``frames``: ``SegmentFrames(tracker)``. Advances ``tracker``."""
    a = start.tolist()
    b = end.tolist()
    timed_out = False
    if duration_s > 0.0 and time_s + duration_s > time_limit_s:
        frac = max(time_limit_s - time_s, 0.0) / duration_s
        b = [a[c] + frac * (b[c] - a[c]) for c in range(3)]
        duration_s, timed_out = duration_s * frac, True
    out = LegResult(end=start, duration_s=0.0)
    left = duration_s
    grazed = False  # a tangent entry that ``PathTracker.update`` did not count: fly the rest without looking again
    while True:
        v = [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
        index = tracker.index
        hit = None if tracker.done or grazed else _entry(a, v, frames.waypoints[index], tracker.reach_radius_m)
        s = 1.0 if hit is None else hit[0] + 0.01 * (hit[1] - hit[0])  # just inside the sphere
        piece = left * s
        # cross-track integral of a -> a + s v (and the off-path check at the same points)
        total = 0.0
        for x, wgt in zip(_GAUSS_X, _GAUSS_W):
            xs = x * s
            e = frames.error(index, a[0] + xs * v[0], a[1] + xs * v[1], a[2] + xs * v[2])
            if e > off_path_m:
                # ends here; the integral so far taken at this point's error (e > off_path_m ends the episode)
                out.end = np.array([a[0] + xs * v[0], a[1] + xs * v[1], a[2] + xs * v[2]])
                out.duration_s += piece * x
                out.cross_integral += e * piece * x
                out.off_path = True
                return out
            total += wgt * e
        p = [a[0] + s * v[0], a[1] + s * v[1], a[2] + s * v[2]]
        out.cross_integral += total * piece
        out.duration_s += piece
        left -= piece
        if hit is None:
            break
        n = tracker.update(np.array(p))
        out.reached += n
        a, grazed = p, n == 0
        if tracker.done or (stop_at_waypoint and n > 0) or left <= 0.0:
            break
    out.end = np.array(p)
    if not tracker.done and frames.error(tracker.index, *p) > off_path_m:
        out.off_path = True
    out.timed_out = timed_out and not tracker.done and not out.off_path and left <= 1e-12
    return out
