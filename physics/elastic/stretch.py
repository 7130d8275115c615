"""Stretching energy of one edge, eqns (1) and (5a) of Huang & Jawed 2020."""

from __future__ import annotations

import numpy as np
from numba import njit


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
    e = np.empty(3)
    for k in range(3):
        e[k] = x1[k] - x0[k]
    le = np.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    strain = le / l_bar - 1.0
    E = 0.5 * EA * l_bar * strain * strain
    if order < 1:
        return E
    f = EA * strain  # dE/d|e|, N
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
