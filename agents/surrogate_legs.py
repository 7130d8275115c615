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
import numpy as np
from numba import njit

from flagellum_env.tracking import PathTracker
from physics.linalg.vec3 import dot3s

#: 3-point Gauss-Legendre nodes on [0, 1] and weights.
_GAUSS_X = (0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6))
_GAUSS_W = (5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0)


#: ``SurrogateEpisode.state``, float64 (STATE_SIZE,): the head (3, m) from HEAD, the unit heading (3) from HEADING, the
#: episode's time (s), motor energy (J) and int e dt (m s), and, since the reward was last taken, the motor energy
#: (J), int e dt (m s), the waypoints reached (a count) and whether the head left the path (1.0).
HEAD, HEADING, TIME, ENERGY, CROSS, ACC_ENERGY, ACC_CROSS, ACC_REACHED, OFF_PATH = 0, 3, 6, 7, 8, 9, 10, 11, 12
STATE_SIZE = 13
#: A leg's constants, float64 (LEG_SIZE,): the reach radius (m), the time limit (s), the off-path distance (m), the
#: cruise speed (m/s), the cruise power (W), the control step (s), the map period (s), and the swimmer's relaxation
#: time, burst time and viscosity over the map's (``SurrogateSwimmer``'s ``tau_ratio``, ``time_factor``,
#: ``mu_ratio``).
REACH, TIME_LIMIT, OFF_PATH_M, SPEED, CRUISE_POWER, DT, PERIOD, TAU_RATIO, TIME_FACTOR, MU_RATIO = range(10)
LEG_SIZE = 10
#: How a leg ended (``fly_state``): on (the episode goes on), terminated (the path done or left), truncated (out of
#: time).
GOES_ON, TERMINATED, TRUNCATED = 0, 1, 2


class SegmentFrames:
    """The path's segments and waypoints as one array for the compiled leg (``fly_state``): row i of ``table`` (N, 10)
    holds segment i's start (vertex i, m), its unit direction, its length (m) and waypoint i (m); the cross-track
    error of a point is its distance from the closest point of the current segment (``PathTracker.cross_track_error``'s
    definition: projection clipped to the segment)."""

    def __init__(self, tracker: PathTracker) -> None:
        vertices = tracker.path.vertices
        lengths = tracker.path.segment_lengths
        self.table = np.concatenate([vertices[:-1], (vertices[1:] - vertices[:-1]) / lengths[:, None],
                                     lengths[:, None], tracker.path.waypoints], axis=1)


@njit(cache=True)
def fly_state(state: np.ndarray, b0: float, b1: float, b2: float, duration_s: float, power_w: float,
              energy_j: float, prorate: bool, stop_at_waypoint: bool, index: int, table: np.ndarray,
              consts: np.ndarray) -> tuple[int, int]:
    """Move the head of ``state`` (``STATE_SIZE``) to (b0, b1, b2) m in ``duration_s`` s from its time on (module
    docstring) and add the leg to ``state``; ``stop_at_waypoint``: end the leg where a waypoint is reached (the
    planner re-plans then). Its motor energy: ``energy_j`` (J) prorated if the leg stops early (``prorate``), else
    ``power_w`` (W) x its duration. ``index``: the target waypoint; ``table``: ``SegmentFrames.table``; ``consts``
    (``LEG_SIZE``). Returns (the waypoints reached, ``GOES_ON``, ``TERMINATED`` or ``TRUNCATED``)."""
    e0, e1, e2, flown, reached, cross, off_path, timed_out = _fly(
        state[0], state[1], state[2], b0, b1, b2, duration_s, state[TIME], consts[TIME_LIMIT], consts[OFF_PATH_M],
        stop_at_waypoint, index, consts[REACH], table)
    if prorate:
        energy = energy_j * (flown / duration_s if duration_s > 0.0 else 1.0)
    else:
        energy = power_w * flown
    state[0], state[1], state[2] = e0, e1, e2
    state[TIME] += flown
    state[ENERGY] += energy
    state[CROSS] += cross
    state[ACC_ENERGY] += energy
    state[ACC_CROSS] += cross
    state[ACC_REACHED] += reached
    if off_path:
        state[OFF_PATH] = 1.0
    if index + reached >= table.shape[0] or off_path:
        return reached, TERMINATED
    return reached, TRUNCATED if timed_out else GOES_ON


@njit(cache=True)
def _entry(a0: float, a1: float, a2: float, v0: float, v1: float, v2: float, w0: float, w1: float, w2: float,
           radius: float) -> tuple[float, float]:
    """(s of the first entry into the sphere |x - w| <= radius along x = a + s v, s in [0, 1]; s of the closest
    approach, clipped), or (-1, -1) if the leg stays outside; m."""
    q0, q1, q2 = a0 - w0, a1 - w1, a2 - w2
    aa = v0 * v0 + v1 * v1 + v2 * v2
    bb = 2.0 * (q0 * v0 + q1 * v1 + q2 * v2)
    cc = q0 * q0 + q1 * q1 + q2 * q2 - radius * radius
    if cc <= 0.0:
        return 0.0, 0.0
    if aa <= 0.0:
        return -1.0, -1.0
    disc = bb * bb - 4.0 * aa * cc
    if disc < 0.0:
        return -1.0, -1.0
    s = (-bb - math.sqrt(disc)) / (2.0 * aa)
    if not 0.0 <= s <= 1.0:
        return -1.0, -1.0
    return s, min(max(-bb / (2.0 * aa), 0.0), 1.0)


@njit(cache=True)
def _error(index: int, x0: float, x1: float, x2: float, table: np.ndarray) -> float:
    """Cross-track error (m) of the point (x0, x1, x2) m while waypoint ``index`` is the target (``SegmentFrames``)."""
    row = table[min(index, table.shape[0] - 1)]
    u0, u1, u2 = row[3], row[4], row[5]
    r0, r1, r2 = x0 - row[0], x1 - row[1], x2 - row[2]
    s = min(max(r0 * u0 + r1 * u1 + r2 * u2, 0.0), row[6])
    e0, e1, e2 = r0 - s * u0, r1 - s * u1, r2 - s * u2
    return math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@njit(cache=True)
def _fly(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float, duration_s: float, time_s: float,
         time_limit_s: float, off_path_m: float, stop_at_waypoint: bool, index: int, reach: float, table: np.ndarray
         ) -> tuple[float, float, float, float, int, float, bool, bool]:
    """``fly_state``'s leg from (a0, a1, a2) to (b0, b1, b2) m, the target ``index`` on: (end x, y, z m, duration
    flown s, waypoints reached, cross-track integral m s, off the path, timed out). A waypoint counts when the head is
    within ``reach`` m of it (``PathTracker.update``'s test, its distance rounded alike)."""
    n_wp = table.shape[0]
    timed_out = False
    if duration_s > 0.0 and time_s + duration_s > time_limit_s:
        frac = max(time_limit_s - time_s, 0.0) / duration_s
        b0, b1, b2 = a0 + frac * (b0 - a0), a1 + frac * (b1 - a1), a2 + frac * (b2 - a2)
        duration_s, timed_out = duration_s * frac, True
    flown, reached, cross = 0.0, 0, 0.0
    left = duration_s
    grazed = False  # a tangent entry the reach test did not count: fly the rest without looking again
    p0, p1, p2 = a0, a1, a2
    while True:
        v0, v1, v2 = b0 - a0, b1 - a1, b2 - a2
        hit0, hit1 = -1.0, -1.0
        if index < n_wp and not grazed:
            hit0, hit1 = _entry(a0, a1, a2, v0, v1, v2, table[index, 7], table[index, 8], table[index, 9], reach)
        hit = hit0 >= 0.0
        s = hit0 + 0.01 * (hit1 - hit0) if hit else 1.0  # just inside the sphere
        piece = left * s
        # cross-track integral of a -> a + s v (and the off-path check at the same points)
        total = 0.0
        for g in range(3):
            x = _GAUSS_X[g]
            xs = x * s
            x0, x1, x2 = a0 + xs * v0, a1 + xs * v1, a2 + xs * v2
            e = _error(index, x0, x1, x2, table)
            if e > off_path_m:
                # ends here; the integral so far taken at this point's error (e > off_path_m ends the episode)
                return x0, x1, x2, flown + piece * x, reached, cross + e * piece * x, True, False
            total += _GAUSS_W[g] * e
        p0, p1, p2 = a0 + s * v0, a1 + s * v1, a2 + s * v2
        cross += total * piece
        flown += piece
        left -= piece
        if not hit:
            break
        n = 0
        while index < n_wp:
            d0, d1, d2 = p0 - table[index, 7], p1 - table[index, 8], p2 - table[index, 9]
            if math.sqrt(dot3s(d0, d1, d2, d0, d1, d2)) > reach:
                break
            index += 1
            n += 1
        reached += n
        a0, a1, a2, grazed = p0, p1, p2, n == 0
        if index >= n_wp or (stop_at_waypoint and n > 0) or left <= 0.0:
            break
    done = index >= n_wp
    off_path = not done and _error(index, p0, p1, p2, table) > off_path_m
    return p0, p1, p2, flown, reached, cross, off_path, timed_out and not done and not off_path and left <= 1e-12
