"""Banded LU with partial pivoting, compiled (the algorithm of LAPACK's dgbtf2 / dgbtrs).

The Newton-Krylov preconditioner (``newton_krylov``) factorises one banded matrix per step and solves
with it at every Krylov iteration, inside compiled code. Storage: the transpose of LAPACK's gbtrf
layout, ``s`` (n, 2 kl + ku + 1) with s[j, kl + ku + i - j] = S[i, j] (a column of S is a contiguous row of s);
the first kl entries of each row take the fill-in of the row interchanges.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def banded_lu(s: np.ndarray, kl: int, ku: int) -> tuple[np.ndarray, int]:
    """Factorise S = P L U in place (LAPACK dgbtf2). Returns (pivots (n,), info): info = j + 1 if U[j, j] = 0."""
    n = s.shape[0]
    kv = kl + ku
    piv = np.empty(n, dtype=np.int64)
    info = 0
    ju = 0
    for j in range(n):
        km = min(kl, n - 1 - j)
        jp = 0
        best = abs(s[j, kv])
        for i in range(1, km + 1):
            v = abs(s[j, kv + i])
            if v > best:
                best, jp = v, i
        piv[j] = j + jp
        if s[j, kv + jp] == 0.0:
            if info == 0:
                info = j + 1
            continue
        ju = max(ju, min(j + ku + jp, n - 1))
        if jp != 0:
            for c in range(j, ju + 1):
                a, b = kv + j - c, kv + j + jp - c
                s[c, a], s[c, b] = s[c, b], s[c, a]
        d = s[j, kv]
        for i in range(1, km + 1):
            s[j, kv + i] /= d
        for c in range(j + 1, ju + 1):
            u = s[c, kv + j - c]
            if u != 0.0:
                for i in range(1, km + 1):
                    s[c, kv + j + i - c] -= s[j, kv + i] * u
    return piv, info


@njit(cache=True)
def banded_solve(s: np.ndarray, kl: int, ku: int, piv: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x = S^{-1} b from the factor of ``banded_lu`` (LAPACK dgbtrs, no transpose)."""
    n = s.shape[0]
    kv = kl + ku
    x = b.copy()
    for j in range(n):
        km = min(kl, n - 1 - j)
        p = piv[j]
        if p != j:
            x[j], x[p] = x[p], x[j]
        xj = x[j]
        if xj != 0.0:
            for i in range(1, km + 1):
                x[j + i] -= s[j, kv + i] * xj
    for j in range(n - 1, -1, -1):
        x[j] /= s[j, kv]
        xj = x[j]
        if xj != 0.0:
            for i in range(max(0, j - kv), j):
                x[i] -= s[j, kv + i - j] * xj
    return x
