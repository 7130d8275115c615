"""Time discretisation of eqn (6) of Huang & Jawed 2020: implicit Euler and variable-step BDF of order up to
2, 3 or 4 (``NumericsConfig.integrator``: euler, bdf2, bdf3, bdf4), with a local error estimate and a step-size
controller.

Every scheme gives the same nonlinear system as the paper's implicit Euler,

    M (q - q^ - h_e v^) / h_e^2 + grad E(q) + P^T R (P (q - q^) / h_e - omega e_s) = 0,

only with different base values (q^, v^) and an effective step h_e, so the residual, the
Jacobian M/h_e^2 + K + P^T R P / h_e and every solver are shared:

* implicit Euler (order 1): h_e = h, q^ = q_n, v^ = v_n (eqn 6 as printed).
* BDF of order k (variable step; Hairer & Wanner, *Solving ODEs II*, Sec. III.5): v_{n+1} = sum_j alpha_j
  q(tau_j) over t_{n+1} and the last k accepted points, alpha_j the derivative at t_{n+1} of the Lagrange basis
  polynomials (``bdf_coefficients``); the same formula for the acceleration from the velocities. So
  h_e = 1 / alpha_0, q^ = -sum_{j>0} alpha_j q_j / alpha_0, likewise v^. For k = 2 with ratio w = h_n / h_{n-1}:
  alpha = ((1 + 2w) / (h (1 + w)), -(1 + w) / h, w^2 / (h (1 + w))). BDF2 is L-stable like implicit Euler (the
  stiff elastic and twist modes are damped, not rung); BDF3 and BDF4 are A(alpha)-stable (see
  ``COLLAPSED_STEPS`` below for what is done when that shows). The order ramps up by one per step after a
  restart (``order_after``).

Local error (Milne's device): the predictor P is the polynomial through the last p + 1 accepted
points (p = the order), evaluated at t_{n+1}. For a solution with smooth (p+1)-th derivative,
P misses by E_p = q^{(p+1)}/(p+1)! * prod_j (t_{n+1} - t_j) and the corrector by
E_c = q^{(p+1)}/(p+1)! * (its own error constant), with the opposite sign, so
E_c ~ k / (1 + k) * (q_c - P), k = E_c / E_p (``error_ratio``). Constant steps: k = 1/2
(Euler), 2/9 (BDF2).

The error is measured in units that mean something for this rod: node positions in rod radii
r0, twist angles in radians, as a max norm (a local kink must not hide in an average).

A motor-speed change puts a kink in q(t) (the velocity jumps): the history is restarted there,
the first step after it is implicit Euler at ``h_start``, and no estimate crosses the kink.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

#: step-size controller: safety factor, largest growth and shrink per step, and the band of
#: growth factors in which the step is kept as it is (so factorisations at h_e stay valid)
SAFETY = 0.9
GROW_MAX = 2.0
SHRINK_MIN = 0.2
KEEP_BELOW = 1.25


@dataclass(frozen=True)
class StepBase:
    """What one implicit step needs besides the state: h (s), the effective step h_e (s), the base
    values q^ and v^ (ndof,), the Newton start ``q_pred`` (ndof,), the order, and the error ratio
    k of the estimate (None: no estimate for this step)."""

    h: float
    h_eff: float
    q_hat: np.ndarray
    v_hat: np.ndarray
    q_pred: np.ndarray
    order: int
    error_ratio: float | None


#: the largest order of each scheme (``NumericsConfig.integrator``)
SCHEME_ORDER = {"euler": 1, "bdf2": 2, "bdf3": 3, "bdf4": 4}

#: Collapsed steps: BDF3 and BDF4 are only A(alpha)-stable (alpha 86 and 73 deg; Hairer & Wanner II, Sec. V.2),
#: so a lightly damped fast mode near the imaginary axis, or the kinks of a resistance rebuilt in jumps, can hold
#: their error-controlled steps at microseconds (BDF3 at step_tol 1e-7 from rest: 3324 steps of ~3 us in 0.05 s,
#: BDF2 124; a random-policy env episode at faithful sat at 1-2.5 us steps at 150 rpm with contact active, for more
#: than 15 minutes). After this many accepted steps within one span of ``Simulator._adaptive`` (dt, 0.1 s by default;
#: normal runs take at most ~200) the step restarts and the order is held at 2, A-stable, until the motor speed
#: changes (or ``set_state``), as CVODE's stability
#: limit detection lowers the order (Hindmarsh et al., ACM TOMS 31, 2005, Sec. 2.3).
COLLAPSED_STEPS = 1000
#: ... and after this many the span fails with ``SimulationError`` (too much work, as CVODE's mxstep).
MAX_STEPS_PER_SPAN = 50_000


@njit(cache=True)
def bdf_coefficients(t_new: float, times: np.ndarray) -> np.ndarray:
    """alpha_j of the variable-step BDF formula q'(t_new) ~ sum_j alpha_j q(tau_j) over the nodes
    tau_0 = t_new, tau_j = times[-j] (times (k,) s, oldest first): the derivative at t_new of the Lagrange basis
    polynomials (Hairer & Wanner, *Solving ODEs II*, Sec. III.5). (k+1,), 1/s."""
    k = times.shape[0]
    tau = np.empty(k + 1)
    tau[0] = t_new
    for j in range(1, k + 1):
        tau[j] = times[k - j]
    alpha = np.empty(k + 1)
    a0 = 0.0
    for m in range(1, k + 1):
        a0 += 1.0 / (tau[0] - tau[m])
    alpha[0] = a0
    for j in range(1, k + 1):
        num = 1.0
        for m in range(1, k + 1):
            if m != j:
                num *= tau[0] - tau[m]
        den = 1.0
        for m in range(k + 1):
            if m != j:
                den *= tau[j] - tau[m]
        alpha[j] = num / den
    return alpha


@njit(cache=True)
def order_after(top: int, npts: int) -> int:
    """The order of the next step with ``npts`` accepted points since the last restart, for a scheme of largest
    order ``top`` (``SCHEME_ORDER``): implicit Euler first, then BDF2, and an order above 2 only once the step can be
    checked by the estimate at that order (order + 1 earlier points): the order ramps up by one per step after a
    restart."""
    if npts == 1 or top == 1:
        return 1
    return max(2, min(top, npts - 1))


@njit(cache=True)
def base_kernel(times: np.ndarray, qs: np.ndarray, vs: np.ndarray, h: float, order: int):
    """(q^, v^, h_e, predictor, error ratio k or -1 for none) of a step of h (s) at ``order`` from the last m
    accepted points (times (m,) s, qs and vs (m, ndof), newest last; m = order + 1, or fewer right after
    a restart; m >= order for order >= 2).

    BDF base over the newest ``order`` points; predictor: the polynomial through the m points at
    t_n + h (q_n + h v_n with one point), and the error ratio k = E_c / E_p of the corrector when there are
    order + 1 points: with S_m = sum_{j<m} 1 / (t_{n+1} - t_{n-j}), the predictor misses by E_p = c pi(t_{n+1}),
    the corrector by E_c = E_p (1 - S_{p+1} / S_p) (c = q^{(p+1)} / (p+1)!, pi the node polynomial of the p + 1
    earlier points), so k = S_{p+1} / S_p - 1: 1/2 (Euler), 2/9 (BDF2), 3/22 (BDF3), 12/125 (BDF4) at constant
    steps."""
    m = times.shape[0]
    t0 = times[m - 1]
    q0, v0 = qs[m - 1], vs[m - 1]
    nd = q0.shape[0]
    t_new = t0 + h
    if order == 1:
        q_hat, v_hat, h_eff = q0, v0, h
    else:
        alpha = bdf_coefficients(t_new, times[m - order:])
        q_hat = np.zeros(nd)
        v_hat = np.zeros(nd)
        for j in range(1, order + 1):
            c = alpha[j] / alpha[0]
            qj, vj = qs[m - j], vs[m - j]
            for i in range(nd):
                q_hat[i] -= c * qj[i]
            for i in range(nd):
                v_hat[i] -= c * vj[i]
        h_eff = 1.0 / alpha[0]
    if m < 2:
        q_pred = np.empty(nd)
        for i in range(nd):
            q_pred[i] = q0[i] + h * v0[i]
        return q_hat, v_hat, h_eff, q_pred, -1.0
    q_pred = np.zeros(nd)
    for a in range(m):
        w = 1.0
        for b in range(m):
            if b != a:
                w *= (t_new - times[b]) / (times[a] - times[b])
        qa = qs[a]
        for i in range(nd):
            q_pred[i] += w * qa[i]
    if m < order + 1:  # BDF2 right after a restart: linear extrapolation, no estimate
        return q_hat, v_hat, h_eff, q_pred, -1.0
    s_all = 0.0
    s_but_oldest = 0.0
    for j in range(m):  # newest first
        s = 1.0 / (t_new - times[m - 1 - j])
        s_all += s
        if j < m - 1:
            s_but_oldest += s
    return q_hat, v_hat, h_eff, q_pred, s_all / s_but_oldest - 1.0


#: accepted points the force extrapolation uses: a cubic, as the BDF3 predictor of q
EXTRAPOLATION_POINTS = 4


@njit(cache=True)
def extrapolate_kernel(ts: np.ndarray, ys: np.ndarray, t_new: float) -> np.ndarray:
    """The polynomial through (ts (k,) s, ys (k, n)) at t_new (s), (n,) (k = 1 to ``EXTRAPOLATION_POINTS``,
    oldest first; degree k - 1), by Newton's divided differences: the start of an iteration for quantities the scheme
    does not integrate (the flagellum's node forces of the Newton-Krylov step), predicted as the BDF predictor
    predicts q (as IDA predicts every component of a DAE: Hindmarsh et al., ACM TOMS 31, 2005, Sec. 2.1)."""
    k, n = ys.shape
    diff = ys.copy()  # row m becomes y[t_0, ..., t_m]
    for level in range(1, k):
        for m in range(k - 1, level - 1, -1):
            dt = ts[m] - ts[m - level]
            for i in range(n):
                diff[m, i] = (diff[m, i] - diff[m - 1, i]) / dt
    out = diff[k - 1].copy()
    for m in range(k - 2, -1, -1):  # Horner on the Newton form
        c = t_new - ts[m]
        for i in range(n):
            out[i] = diff[m, i] + c * out[i]
    return out


@njit(cache=True)
def weighted_max_abs_diff(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> float:
    """max_i |a_i - b_i| w_i over (n,) vectors, NaN if any term is NaN (``np.max(np.abs(a - b) * w)``)."""
    m = -np.inf
    for i in range(a.shape[0]):
        v = abs(a[i] - b[i]) * w[i]
        if v != v:
            return v
        if v > m:
            m = v
    return m


@njit(cache=True)
def next_step(h: float, err: float, order: int, keep: bool = True) -> float:
    """The step (s) after one of length h with error ratio ``err`` (error / tolerance) at ``order``:
    the classic controller h (SAFETY / err)^(1/(p+1)), growth at most GROW_MAX, shrink at least
    SHRINK_MIN; with ``keep``, a growth below KEEP_BELOW keeps h (a changed h_e costs a refactorisation of
    a reused Jacobian; a Newton-Krylov step factorises its preconditioner anyway: no reason to keep h)."""
    if err <= 0.0:
        fac = GROW_MAX
    else:
        fac = min(GROW_MAX, max(SHRINK_MIN, SAFETY * err ** (-1.0 / (order + 1))))
    if keep and 1.0 <= fac < KEEP_BELOW:
        return h
    return h * fac


#: CVODE's test of the nonlinear iteration of an error-controlled step (Hindmarsh et al., ACM TOMS 31, 2005,
#: Sec. 2.1): converged when the last correction, times the estimated contraction rate, is below this
#: fraction of the local error tolerance (both in the estimate's units: r0 for positions, rad for twists)
NONLINEAR_ERROR_FRACTION = 0.1


#: steps after which an unmeasured contraction rate counts as 1 (``ContractionRate.MAX_AGE``)
RATE_MAX_AGE = 10


@njit(cache=True)
def contraction_update(size: float, rho: float, prev: float, age: int) -> tuple[bool, float, float, int]:
    """``ContractionRate.converged`` for compiled loops: after a correction of weighted size ``size`` (in units
    of step_tol), from the rate state (rho, the previous correction's size in this step or -1 for none, age in
    steps): (converged, rho, prev, age)."""
    if prev > 0.0:
        rho = max(0.3 * rho, size / prev)
        age = 0
    prev = size
    rho_now = rho if age < RATE_MAX_AGE else 1.0
    return size * min(1.0, rho_now) <= NONLINEAR_ERROR_FRACTION, rho, prev, age


class ContractionRate:
    """The convergence test of the Newton / chord iteration of an error-controlled step (CVODE's): the rate
    rho = max(0.3 rho_old, |dz_m| / |dz_{m-1}|), measured whenever a step takes two corrections or more, is
    carried from step to step (1 at the start), and the iteration stops after a correction dz (weighted max
    norm / step_tol) with |dz| min(1, rho) <= NONLINEAR_ERROR_FRACTION: the error left in the iterate is then a
    tenth of what the step's error test allows. A rate not measured for ``MAX_AGE`` steps counts as 1 (the next
    step takes two corrections and measures it again). One instance per iteration scheme (the chord iteration
    and Newton-Krylov contract at very different rates)."""

    MAX_AGE = RATE_MAX_AGE

    def __init__(self) -> None:
        self.rho = 1.0
        self.prev: float | None = None  # the last correction's size in this step (None: none yet)
        self.age = self.MAX_AGE  # steps since the rate was last measured

    def start(self) -> None:
        """A new step's iteration begins (its first correction cannot measure a rate)."""
        self.prev = None
        self.age += 1

    def converged(self, dz_over_tol: float) -> bool:
        """After a correction of weighted size ``dz_over_tol`` (in units of step_tol): is the iterate converged?"""
        if self.prev is not None and self.prev > 0.0:
            self.rho = max(0.3 * self.rho, dz_over_tol / self.prev)
            self.age = 0
        self.prev = dz_over_tol
        rho = self.rho if self.age < self.MAX_AGE else 1.0
        return dz_over_tol * min(1.0, rho) <= NONLINEAR_ERROR_FRACTION


@njit(cache=True)
def split_remaining(h: float, remaining: float, stretch: bool = True) -> float:
    """A step no longer than ``remaining`` (s) that avoids a sliver at the end: the whole rest if it is
    within 30 % of h (within h if not ``stretch``: right after a rejected step), half of it if it is
    within 2 h."""
    if remaining <= (1.3 if stretch else 1.0) * h:
        return remaining
    if remaining < 2.0 * h:
        return 0.5 * remaining
    return h


def step_spans(duration_s: float, numerics: Any) -> list[float | None]:
    """The ``step`` arguments that advance by ``duration_s``: whole steps of dt (None), rounded with fixed
    steps; with adaptive steps (step_tol > 0) the rest as a last, shorter span, so the time is exact."""
    dt = numerics.dt
    if getattr(numerics, "step_tol", 0.0) <= 0.0:
        return [None] * int(round(duration_s / dt))
    n = int(math.floor(duration_s / dt + 1e-9))
    rest = duration_s - n * dt
    return [None] * n + ([rest] if rest > 1e-9 * dt else [])
