"""Stretching energy of one edge, eqns (1) and (5a) of Huang & Jawed 2020."""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.elastic.banded import add_band


@njit(cache=True)
def stretch_terms(
    e0: float, e1: float, e2: float, l_bar: float, EA: float
) -> tuple[float, float, float]:
    """Scalars of the stretching of edge ``e = (e0, e1, e2)`` (m): returns ``(E, le, f)``
    with ``E = 0.5 EA l_bar (|e|/l_bar - 1)^2`` (J), ``le = |e|`` (m) and ``f = dE/d|e|``
    (N). Gradient: ``dE/dx1 = -dE/dx0 = f e/|e|``; Hessian block ``K = (EA/l_bar - b) e
    e^T / |e|^2 + b I`` with ``b = f / |e|``, in ``[[K, -K], [-K, K]]``."""
    le = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    strain = le / l_bar - 1.0
    E = 0.5 * EA * l_bar * strain * strain
    return E, le, EA * strain


@njit(cache=True)
def stretch_into(
    q: np.ndarray, i: int, l_bar: float, EA: float, order: int, need_grad: bool,
    grad: np.ndarray, ab: np.ndarray,
) -> float:
    """Stretching of edge ``i`` of the rod DOF vector ``q`` (4n-1,), added in place:
    ``order`` >= 1 (and ``need_grad``) adds the gradient into ``grad`` (4n-1,),
    ``order`` >= 2 the Hessian into banded ``ab`` (21, 4n-1). Returns the energy, J.
    Allocation-free."""
    p = 4 * i
    e0 = q[p + 4] - q[p]
    e1 = q[p + 5] - q[p + 1]
    e2 = q[p + 6] - q[p + 2]
    E, le, f = stretch_terms(e0, e1, e2, l_bar, EA)
    if order < 1:
        return E
    if need_grad:
        g0 = f * (e0 / le)
        g1 = f * (e1 / le)
        g2 = f * (e2 / le)
        grad[p] -= g0
        grad[p + 1] -= g1
        grad[p + 2] -= g2
        grad[p + 4] += g0
        grad[p + 5] += g1
        grad[p + 6] += g2
    if order < 2:
        return E
    a = EA / l_bar
    b = f / le
    ll = le * le
    for r in range(3):
        er = q[p + 4 + r] - q[p + r]
        for c in range(3):
            ec = q[p + 4 + c] - q[p + c]
            kblk = (a - b) * (er * ec / ll)
            if r == c:
                kblk += b
            add_band(ab, p + r, p + c, kblk)
            add_band(ab, p + 4 + r, p + 4 + c, kblk)
            add_band(ab, p + r, p + 4 + c, -kblk)
            add_band(ab, p + 4 + r, p + c, -kblk)
    return E


@njit(cache=True)
def stretch_element(
    x0: np.ndarray,
    x1: np.ndarray,
    l_bar: float,
    EA: float,
    g: np.ndarray,
    H: np.ndarray,
    order: int,
) -> float:
    """Stretching energy of edge ``e = x1 - x0``; optionally its derivatives, in place.

    ``E = 0.5 * EA * l_bar * (|e| / l_bar - 1)**2`` (eqns (1), (5a) of Huang & Jawed 2020).
    ``x0``, ``x1``: (3,) m; ``l_bar``: rest length, m; ``EA``: N. ``order`` >= 1 writes
    the gradient into ``g`` (6,) and ``order`` >= 2 the Hessian into ``H`` (6, 6), local
    DOF order ``[x0, x1]``. Returns the energy, J.
    """
    e0 = x1[0] - x0[0]
    e1 = x1[1] - x0[1]
    e2 = x1[2] - x0[2]
    E, le, f = stretch_terms(e0, e1, e2, l_bar, EA)
    if order < 1:
        return E
    e = (e0, e1, e2)
    for k in range(3):
        t = e[k] / le
        g[k] = -f * t
        g[3 + k] = f * t
    if order < 2:
        return E
    a = EA / l_bar  # coefficient of t t^T
    b = f / le  # coefficient of (I - t t^T)
    for r in range(3):
        for c in range(3):
            tt = e[r] * e[c] / (le * le)
            kblk = (a - b) * tt
            if r == c:
                kblk += b
            H[r, c] = kblk
            H[3 + r, 3 + c] = kblk
            H[r, 3 + c] = -kblk
            H[3 + r, c] = -kblk
    return E


@njit(cache=True)
def stretch_energy_grad_hess(
    x0: np.ndarray, x1: np.ndarray, l_bar: float, EA: float
) -> tuple[float, np.ndarray, np.ndarray]:
    """Energy (J), gradient (6,) and Hessian (6, 6) of the stretching of edge ``x1 - x0``.

    See :func:`stretch_element`; local DOF order ``[x0, x1]``.
    """
    g = np.empty(6)
    H = np.empty((6, 6))
    E = stretch_element(x0, x1, l_bar, EA, g, H, 2)
    return E, g, H
