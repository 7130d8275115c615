"""The edge-pair element shared by bending (``bend.py``) and twisting (``twist.py``):
nodes ``x0, x1, x2`` with edges ``e = x1 - x0``, ``f = x2 - x1`` and local DOF order
``[x0(3), x1(3), x2(3), theta_e, theta_f]``.

- :func:`edge_pair_geom`: the geometry both energies use (tangents, lengths, ``chi``,
  curvature binormal ``kb``, eqn (2) of Huang & Jawed 2020).
- Derivatives are formed in the reduced coordinates ``y = [e(3), f(3), theta_e,
  theta_f]`` (gradient ``gy`` (8,), Hessian ``Hy`` (8, 8), only its symmetric part used)
  and then mapped to the nodes: :func:`edge_pair_to_nodes` for one element,
  :func:`edge_pair_result` for the per-element ``*_energy_grad_hess`` functions,
  :func:`edge_pair_scatter` straight into the rod's gradient and banded Hessian.
- :func:`add_block`, :func:`add_block2`: 3x3 block updates of ``Hy`` with one
  read-modify-write per entry.

3-vectors are 3-tuples of floats (see ``physics.model.frames.vcross``); only
:func:`edge_pair_result` allocates.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.elastic.banded import add_band
from physics.model.frames import dot3, vcross

# Column c of the (8, 11) map dy/dq_local: up to two (row, coefficient) pairs.
_MAP_ROW = np.array(
    [[0, 0], [1, 1], [2, 2], [0, 3], [1, 4], [2, 5], [3, 3], [4, 4], [5, 5], [6, 6], [7, 7]],
    dtype=np.int64,
)
_MAP_COEF = np.array(
    [[-1.0, 0.0], [-1.0, 0.0], [-1.0, 0.0], [1.0, -1.0], [1.0, -1.0], [1.0, -1.0],
     [1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]
)


@njit(cache=True, inline="always")
def _add_row(
    M: np.ndarray, i: int, c0: int, x1: float, v1, x2: float, v2, x3: float, v3, x4: float, v4,
    e0: float, e1: float, e2: float,
) -> None:
    """``M[i, c0:c0+3] += x1 v1 + x2 v2 + x3 v3 + x4 v4 + (e0, e1, e2)``."""
    M[i, c0] += x1 * v1[0] + x2 * v2[0] + x3 * v3[0] + x4 * v4[0] + e0
    M[i, c0 + 1] += x1 * v1[1] + x2 * v2[1] + x3 * v3[1] + x4 * v4[1] + e1
    M[i, c0 + 2] += x1 * v1[2] + x2 * v2[2] + x3 * v3[2] + x4 * v4[2] + e2


@njit(cache=True, inline="always")
def add_block(
    M: np.ndarray, r0: int, c0: int,
    a1: float, u1, v1, a2: float, u2, v2, a3: float, u3, v3, a4: float, u4, v4,
    d: float, k: float, w,
) -> None:
    """``M[r0:r0+3, c0:c0+3] += a1 u1 v1^T + a2 u2 v2^T + a3 u3 v3^T + a4 u4 v4^T + d I
    + k [w]_x`` for 3-vectors (``[w]_x v = w x v``), with a single read-modify-write per
    entry. Inlined so all indices are static."""
    kw0 = k * w[0]
    kw1 = k * w[1]
    kw2 = k * w[2]
    _add_row(
        M, r0, c0, a1 * u1[0], v1, a2 * u2[0], v2, a3 * u3[0], v3, a4 * u4[0], v4, d, -kw2, kw1
    )
    _add_row(
        M, r0 + 1, c0, a1 * u1[1], v1, a2 * u2[1], v2, a3 * u3[1], v3, a4 * u4[1], v4, kw2, d, -kw0
    )
    _add_row(
        M, r0 + 2, c0, a1 * u1[2], v1, a2 * u2[2], v2, a3 * u3[2], v3, a4 * u4[2], v4, -kw1, kw0, d
    )


@njit(cache=True, inline="always")
def _add_row2(
    M: np.ndarray, i: int, c0: int, x1: float, v1, x2: float, v2, e0: float, e1: float, e2: float
) -> None:
    """``M[i, c0:c0+3] += x1 v1 + x2 v2 + (e0, e1, e2)``."""
    M[i, c0] += x1 * v1[0] + x2 * v2[0] + e0
    M[i, c0 + 1] += x1 * v1[1] + x2 * v2[1] + e1
    M[i, c0 + 2] += x1 * v1[2] + x2 * v2[2] + e2


@njit(cache=True, inline="always")
def add_block2(
    M: np.ndarray, r0: int, c0: int, a1: float, u1, v1, a2: float, u2, v2, k: float, w
) -> None:
    """``M[r0:r0+3, c0:c0+3] += a1 u1 v1^T + a2 u2 v2^T + k [w]_x`` for 3-vectors, with a
    single read-modify-write per entry (see :func:`add_block`)."""
    kw0 = k * w[0]
    kw1 = k * w[1]
    kw2 = k * w[2]
    _add_row2(M, r0, c0, a1 * u1[0], v1, a2 * u2[0], v2, 0.0, -kw2, kw1)
    _add_row2(M, r0 + 1, c0, a1 * u1[1], v1, a2 * u2[1], v2, kw2, 0.0, -kw0)
    _add_row2(M, r0 + 2, c0, a1 * u1[2], v1, a2 * u2[2], v2, -kw1, kw0, 0.0)


@njit(cache=True)
def symmetrize(M: np.ndarray) -> None:
    """Replace square ``M`` by ``(M + M^T) / 2`` in place."""
    n = M.shape[0]
    for r in range(n):
        for c in range(r + 1, n):
            s = 0.5 * (M[r, c] + M[c, r])
            M[r, c] = s
            M[c, r] = s


@njit(cache=True)
def edge_pair_to_nodes(
    gy: np.ndarray, Hy: np.ndarray, g: np.ndarray, H: np.ndarray, order: int
) -> None:
    """Map a gradient (8,) / Hessian (8, 8) in ``[e, f, theta_e, theta_f]`` to the local
    node DOFs ``[x0, x1, x2, theta_e, theta_f]``: ``g = A^T gy``, ``H = A^T Hy A`` with
    ``e = x1 - x0``, ``f = x2 - x1``. Writes ``g`` (11,) and, if ``order`` >= 2, ``H`` (11, 11).
    """
    for a in range(11):
        s = 0.0
        for p in range(2):
            s += _MAP_COEF[a, p] * gy[_MAP_ROW[a, p]]
        g[a] = s
    if order < 2:
        return
    for a in range(11):
        for b in range(a, 11):
            s = 0.0
            for p in range(2):
                ca = _MAP_COEF[a, p]
                if ca == 0.0:
                    continue
                for r in range(2):
                    cb = _MAP_COEF[b, r]
                    if cb == 0.0:
                        continue
                    s += ca * cb * Hy[_MAP_ROW[a, p], _MAP_ROW[b, r]]
            H[a, b] = s
            H[b, a] = s


@njit(cache=True)
def edge_pair_result(
    E: float, gy: np.ndarray, Hy: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray]:
    """``(E, g, H)`` of one element from its reduced derivatives: ``Hy`` (8, 8) is
    symmetrised in place, then ``gy`` (8,), ``Hy`` are mapped to the gradient ``g`` (11,)
    and Hessian ``H`` (11, 11) in local order ``[x0, x1, x2, theta_e, theta_f]``."""
    symmetrize(Hy)
    g = np.empty(11)
    H = np.empty((11, 11))
    edge_pair_to_nodes(gy, Hy, g, H, 2)
    return E, g, H


@njit(cache=True)
def _sym(M: np.ndarray, a: int, b: int) -> float:
    """Entry ``(a, b)`` of the symmetric part ``(M + M^T) / 2`` (as :func:`symmetrize`)."""
    return 0.5 * (M[a, b] + M[b, a])


@njit(cache=True)
def edge_pair_scatter(
    gy: np.ndarray, Hy: np.ndarray, b: int, order: int, need_grad: bool,
    grad: np.ndarray, ab: np.ndarray,
) -> None:
    """Add an edge-pair gradient (8,) / Hessian (8, 8) in ``[e, f, theta_e, theta_f]`` to
    the rod's gradient ``grad`` (4n-1,) (if ``need_grad``) and, if ``order`` >= 2, the
    symmetric part of ``Hy`` to its banded Hessian ``ab`` (21, 4n-1) (so ``Hy`` need not
    be symmetrised first). The element's nodes ``x0, x1, x2`` sit at ``q[b:b+3]``,
    ``q[b+4:b+7]``, ``q[b+8:b+11]`` and its angles at ``q[b+3]``, ``q[b+7]``; same map as
    :func:`edge_pair_to_nodes`."""
    if need_grad:
        for k in range(3):
            grad[b + k] -= gy[k]
            grad[b + 4 + k] += gy[k] - gy[3 + k]
            grad[b + 8 + k] += gy[3 + k]
        grad[b + 3] += gy[6]
        grad[b + 7] += gy[7]
    if order < 2:
        return
    for p in range(3):
        for r in range(3):
            hee = _sym(Hy, p, r)
            hef = _sym(Hy, p, 3 + r)
            hfe = _sym(Hy, 3 + p, r)
            hff = _sym(Hy, 3 + p, 3 + r)
            v01 = -hee + hef
            v12 = hef - hff
            add_band(ab, b + p, b + r, hee)
            add_band(ab, b + p, b + 4 + r, v01)
            add_band(ab, b + 4 + r, b + p, v01)
            add_band(ab, b + p, b + 8 + r, -hef)
            add_band(ab, b + 8 + r, b + p, -hef)
            # grouped so that the (r, p) entry gets bit-for-bit the same value
            add_band(ab, b + 4 + p, b + 4 + r, (hee + hff) - (hef + hfe))
            add_band(ab, b + 4 + p, b + 8 + r, v12)
            add_band(ab, b + 8 + r, b + 4 + p, v12)
            add_band(ab, b + 8 + p, b + 8 + r, hff)
        for j in range(2):
            col = b + 3 + 4 * j
            he = _sym(Hy, p, 6 + j)
            hf = _sym(Hy, 3 + p, 6 + j)
            v0 = -he
            v1 = he - hf
            add_band(ab, b + p, col, v0)
            add_band(ab, col, b + p, v0)
            add_band(ab, b + 4 + p, col, v1)
            add_band(ab, col, b + 4 + p, v1)
            add_band(ab, b + 8 + p, col, hf)
            add_band(ab, col, b + 8 + p, hf)
    h67 = _sym(Hy, 6, 7)
    add_band(ab, b + 3, b + 3, Hy[6, 6])
    add_band(ab, b + 3, b + 7, h67)
    add_band(ab, b + 7, b + 3, h67)
    add_band(ab, b + 7, b + 7, Hy[7, 7])


@njit(cache=True)
def edge_pair_geom(x0, x1, x2):
    """Edge-pair geometry of nodes ``x0, x1, x2`` (3-vectors, m): unit tangents ``te``,
    ``tf``, lengths ``le``, ``lf`` (m), ``chi = 1 + te.tf`` and the dimensionless curvature
    binormal ``kb = 2 te x tf / chi``, eqn (2) of Huang & Jawed 2020. Returns
    ``(te, tf, le, lf, chi, kb)`` with ``te``, ``tf``, ``kb`` 3-tuples."""
    e0 = x1[0] - x0[0]
    e1 = x1[1] - x0[1]
    e2 = x1[2] - x0[2]
    f0 = x2[0] - x1[0]
    f1 = x2[1] - x1[1]
    f2 = x2[2] - x1[2]
    le = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    lf = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    te = (e0 / le, e1 / le, e2 / le)
    tf = (f0 / lf, f1 / lf, f2 / lf)
    chi = 1.0 + dot3(te, tf)
    c = vcross(te, tf)
    s = 2.0 / chi
    kb = (c[0] * s, c[1] * s, c[2] * s)
    return te, tf, le, lf, chi, kb
