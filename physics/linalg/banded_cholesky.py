"""Banded Cholesky factorisation, compiled (the algorithm of LAPACK's dpbtf2 / dpbtrs, lower form).

The Newton-Krylov preconditioner (``newton_krylov``) factorises two symmetric banded matrices per step: the
banded Schur complement S = K + M/h^2 + (D + R_loc)/h and the band of the LSBT mobility. Both are symmetric
positive definite wherever they were measured (burst and relaxation of the faithful swimmer: smallest /
largest eigenvalue >= 2.4e-10 and 3.6e-2), so Cholesky does a quarter of the partial-pivoting LU's work
(n kd^2 / 2 against ~2 n kd^2 flops) and its solves two thirds; where a pivot is not positive the caller
falls back to the LU of ``banded_lu``.

Storage: ``c`` (n, kd + 1), c[j, d] = S[j + d, j] for d = 0..kd (column j of the lower triangle, contiguous);
overwritten by L with S = L L^T.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def banded_cholesky(c: np.ndarray, kd: int) -> int:
    """Factorise S = L L^T in place. Returns info: 0, or j + 1 if the pivot of column j is not positive
    (S is not positive definite; c is then partly overwritten)."""
    n = c.shape[0]
    for j in range(n):
        d = c[j, 0]
        if not d > 0.0:
            return j + 1
        d = math.sqrt(d)
        c[j, 0] = d
        km = min(kd, n - 1 - j)
        for i in range(1, km + 1):
            c[j, i] /= d
        for a in range(1, km + 1):  # the trailing block: S[j+b, j+a] -= L[j+b, j] L[j+a, j]
            la = c[j, a]
            if la != 0.0:
                col = j + a
                for b in range(a, km + 1):
                    c[col, b - a] -= c[j, b] * la
    return 0


@njit(cache=True)
def banded_cholesky_solve(c: np.ndarray, kd: int, b: np.ndarray) -> np.ndarray:
    """x = S^{-1} b from the factor of ``banded_cholesky`` (L y = b, then L^T x = y)."""
    x = b.copy()
    banded_cholesky_solve_in_place(c, kd, x)
    return x


@njit(cache=True)
def banded_cholesky_solve_in_place(c: np.ndarray, kd: int, x: np.ndarray) -> None:
    """x <- S^{-1} x from the factor of ``banded_cholesky``: the solve of ``banded_cholesky_solve`` without the
    copy (the same operations in the same order)."""
    n = c.shape[0]
    for j in range(n):
        xj = x[j] / c[j, 0]
        x[j] = xj
        for i in range(1, min(kd, n - 1 - j) + 1):
            x[j + i] -= c[j, i] * xj
    for j in range(n - 1, -1, -1):
        s = x[j]
        for i in range(1, min(kd, n - 1 - j) + 1):
            s -= c[j, i] * x[j + i]
        x[j] = s / c[j, 0]


@njit(cache=True)
def lower_band(A: np.ndarray, kd: int) -> np.ndarray:
    """The lower band of the dense symmetric A (n, n) within kd of the diagonal, in the storage above."""
    n = A.shape[0]
    c = np.zeros((n, kd + 1))
    for j in range(n):
        for d in range(min(kd, n - 1 - j) + 1):
            c[j, d] = A[j + d, j]
    return c
