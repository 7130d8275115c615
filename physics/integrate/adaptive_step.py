"""The bookkeeping of one error-controlled step, compiled once: its start, the error estimate, the new step size
after a rejection or an acceptance, and the commit of an accepted point.

Two drivers take the steps (``physics.simulator``): the Python one (``Simulator._adaptive``: every chord and RFT
step, and any Newton-Krylov attempt outside a span) and the compiled span of Newton-Krylov steps
(``physics.solvers.krylov_span``). They differ in the solve; everything around it is these functions, which both
call, so a step is begun, judged and committed the same way whichever driver takes it.

The accepted points live in fixed arrays owned by ``AdaptiveState`` (``physics.integrate.adaptive_state``): the
last ``HISTORY_POINTS`` (t, q, v) for BDF and Milne's estimate, and the last ``EXTRAPOLATION_POINTS`` node forces
for the Newton-Krylov step's start, oldest first.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.integrate.time_integrator import SAFETY, SHRINK_MIN, next_step, weighted_max_abs_diff

#: accepted points kept for the scheme: BDF4 and its error estimate
HISTORY_POINTS = 5


@njit(cache=True)
def step_start(q_pred: np.ndarray, q_cur: np.ndarray, prescribed: np.ndarray, h: float, omega: float) -> np.ndarray:
    """The iteration's start (ndof,): the scheme's predictor q_pred with the motor's prescribed twist at the end of
    a step of h (s) from q_cur (q_cur[k] + h omega on the prescribed DOFs k; omega rad/s)."""
    q = q_pred.copy()
    for k in prescribed:
        q[k] = q_cur[k] + h * omega
    return q


@njit(cache=True)
def local_error(q: np.ndarray, q_pred: np.ndarray, ratio: float, weights: np.ndarray, tol: float) -> float:
    """Milne's estimate of the local error of the converged iterate q (ndof,) over the tolerance (<= 1: accept):
    k / (1 + k) max_i |q_i - q_pred_i| w_i / tol for the error ratio k of the step (``time_integrator.base_kernel``;
    negative: the step has no estimate, 0). ``weights``: 1/r0 on positions, 1 on twists."""
    if ratio < 0.0:
        return 0.0
    return weighted_max_abs_diff(q, q_pred, weights) * (ratio / (1.0 + ratio)) / tol


@njit(cache=True)
def rejected_step(h: float, err: float, order: int) -> float:
    """The step (s) to retry after one of h (s) rejected with error ratio err > 1 at ``order``: the controller's
    h (SAFETY / err)^(1/(p+1)), shrunk at most to SHRINK_MIN h."""
    return h * max(SHRINK_MIN, SAFETY * err ** (-1.0 / (order + 1)))


@njit(cache=True)
def accepted_step(h: float, err: float, order: int, h_ctl: float, dt: float, keep: bool) -> float:
    """The controller's next step (s) after an accepted one of h (s) with error ratio err at ``order``
    (``time_integrator.next_step``; ``keep``: a growth below KEEP_BELOW keeps h), where h_ctl (s) was the
    controller's step: a step shortened to land on the span's end says nothing against h_ctl. At most dt (s)."""
    proposal = next_step(h, err, order, keep)
    if h < h_ctl and proposal >= h:
        proposal = max(proposal, h_ctl)
    return min(proposal, dt)


@njit(cache=True)
def push_point(times: np.ndarray, first: np.ndarray, second: np.ndarray, count: int, t: float, y1: np.ndarray,
               y2: np.ndarray) -> int:
    """Append the point (t s, y1, y2) to newest-last points (times (m,), first (m, k1), second (m, k2)) holding
    ``count`` of them, dropping the oldest when all m are taken (second may be (m, 0): one value per point).
    Returns the new count."""
    m = times.shape[0]
    if count == m:
        for j in range(m - 1):
            times[j] = times[j + 1]
            first[j] = first[j + 1]
            second[j] = second[j + 1]
        count -= 1
    times[count] = t
    first[count] = y1
    second[count] = y2
    return count + 1


@njit(cache=True)
def commit_point(q: np.ndarray, q_cur: np.ndarray, q_hat: np.ndarray, h: float, h_eff: float, order: int,
                 t_new: float, keep_history: bool, times: np.ndarray, qs: np.ndarray, vs: np.ndarray, count: int,
                 forces: np.ndarray, force_times: np.ndarray, force_values: np.ndarray,
                 force_count: int) -> tuple[np.ndarray, int, int]:
    """Commit the accepted iterate q (ndof,) of a step of h (s) from q_cur, at time t_new (s).

    The velocity (ndof,): (q - q_cur) / h for implicit Euler at its own step, else the scheme's (q - q^) / h_e. With
    ``keep_history`` (error-controlled or BDF steps) (t_new, q, v) joins the points (times (5,), qs and vs (5, ndof),
    ``count`` of them); the node forces (3 n,) N join the force points (force_times (4,), force_values (4, 3 n),
    ``force_count``). Returns (v, the points' count, the force points' count)."""
    if order == 1 and h_eff == h:
        v = (q - q_cur) / h
    else:
        v = (q - q_hat) / h_eff
    if keep_history:
        count = push_point(times, qs, vs, count, t_new, q, v)
    none = np.empty((force_times.shape[0], 0))  # the force points hold one value each
    force_count = push_point(force_times, force_values, none, force_count, t_new, forces, none[0])
    return v, count, force_count
