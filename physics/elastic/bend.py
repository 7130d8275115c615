"""Bending energy at one interior node, eqns (2), (3a), (3b), (5b) of Huang & Jawed 2020.

The element is the edge pair ``e = x1 - x0`` and ``f = x2 - x1`` with local DOF order
``[x0(3), x1(3), x2(3), theta_e, theta_f]``. Derivatives follow the DER convention
(Bergou et al. 2008, 2010): when an edge moves, its material directors follow it by
time-parallel transport, so to first order they only gain a component along the new
tangent. The Hessian is the exact (symmetric) Hessian of the energy under that rule;
the Jacobian of the gradient formula itself also has an antisymmetric part (the holonomy
of parallel transport, proportional to dE/dtheta) which is dropped, as in DER.

Derivatives are first formed in the reduced coordinates ``y = [e(3), f(3), theta_e,
theta_f]`` and then mapped to the nodes with :func:`edge_pair_to_nodes`; the small block
helpers here are shared with ``twist.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.frames import cross3, dot3

# Column c of the (8, 11) map dy/dq_local: up to two (row, coefficient) pairs.
_MAP_ROW = np.array(
    [[0, 0], [1, 1], [2, 2], [0, 3], [1, 4], [2, 5], [3, 3], [4, 4], [5, 5], [6, 6], [7, 7]],
    dtype=np.int64,
)
_MAP_COEF = np.array(
    [[-1.0, 0.0], [-1.0, 0.0], [-1.0, 0.0], [1.0, -1.0], [1.0, -1.0], [1.0, -1.0],
     [1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]
)


@njit(cache=True)
def add_outer(M: np.ndarray, r0: int, c0: int, alpha: float, u: np.ndarray, v: np.ndarray) -> None:
    """``M[r0:r0+3, c0:c0+3] += alpha * u v^T`` for (3,) vectors ``u``, ``v``."""
    for r in range(3):
        for c in range(3):
            M[r0 + r, c0 + c] += alpha * u[r] * v[c]


@njit(cache=True)
def add_projector(M: np.ndarray, r0: int, c0: int, alpha: float, t: np.ndarray) -> None:
    """``M[r0:r0+3, c0:c0+3] += alpha * (I - t t^T)`` for a unit (3,) vector ``t``."""
    for r in range(3):
        M[r0 + r, c0 + r] += alpha
        for c in range(3):
            M[r0 + r, c0 + c] -= alpha * t[r] * t[c]


@njit(cache=True)
def add_skew_projected(
    M: np.ndarray, r0: int, c0: int, alpha: float, w: np.ndarray, t: np.ndarray
) -> None:
    """``M[r0:r0+3, c0:c0+3] += alpha * [w]_x (I - t t^T)`` where ``[w]_x v = w x v``."""
    M[r0 + 0, c0 + 1] -= alpha * w[2]
    M[r0 + 0, c0 + 2] += alpha * w[1]
    M[r0 + 1, c0 + 0] += alpha * w[2]
    M[r0 + 1, c0 + 2] -= alpha * w[0]
    M[r0 + 2, c0 + 0] -= alpha * w[1]
    M[r0 + 2, c0 + 1] += alpha * w[0]
    add_outer(M, r0, c0, -alpha, cross3(w, t), t)


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
def edge_pair_geometry(
    x0: np.ndarray, x1: np.ndarray, x2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, float, float, np.ndarray]:
    """Edge-pair geometry of nodes ``x0, x1, x2`` (3,) m: unit tangents ``te``, ``tf`` (3,),
    lengths ``le``, ``lf`` (m), ``chi = 1 + te.tf`` and the dimensionless curvature binormal
    ``kb = 2 te x tf / chi`` (3,), eqn (2) of Huang & Jawed 2020."""
    te = np.empty(3)
    tf = np.empty(3)
    for k in range(3):
        te[k] = x1[k] - x0[k]
        tf[k] = x2[k] - x1[k]
    le = np.sqrt(dot3(te, te))
    lf = np.sqrt(dot3(tf, tf))
    for k in range(3):
        te[k] /= le
        tf[k] /= lf
    chi = 1.0 + dot3(te, tf)
    kb = cross3(te, tf)
    for k in range(3):
        kb[k] *= 2.0 / chi
    return te, tf, le, lf, chi, kb


@njit(cache=True)
def _curvature_derivatives(
    te: np.ndarray,
    tf: np.ndarray,
    le: float,
    lf: float,
    chi: float,
    kb: np.ndarray,
    ae: np.ndarray,
    be: np.ndarray,
    af: np.ndarray,
    bf: np.ndarray,
    gy: np.ndarray,
    Hy: np.ndarray,
    order: int,
) -> float:
    """One material curvature ``kappa = 0.5 (ae + af) . kb`` and its derivatives in ``y``.

    ``kappa1`` (eqn (3a)) uses ``a = m2``, ``b = -m1``; ``kappa2`` (eqn (3b)) uses
    ``a = -m1``, ``b = -m2``; ``b = da/dtheta`` and ``db/dtheta = -a``. The gradient is
    the DER one (Bergou et al. 2010): ``dk/de = (2 tf x w - k (te + tf)) / (|e| chi)``,
    ``dk/df = (-2 te x w - k (te + tf)) / (|f| chi)`` with ``w = 0.5 (ae + af)``, and
    ``dk/dtheta = 0.5 b . kb``. ``Hy`` is the symmetric part of the derivative of that
    gradient when directors follow their edges (``d a_e = -(a_e . d te) te``).
    Writes ``gy`` (8,) and, if ``order`` >= 2, ``Hy`` (8, 8). Returns ``kappa`` (1/1).
    """
    w = np.empty(3)
    s = np.empty(3)
    for k in range(3):
        w[k] = 0.5 * (ae[k] + af[k])
        s[k] = te[k] + tf[k]
    kappa = dot3(w, kb)
    if order < 1:
        return kappa
    tfxw = cross3(tf, w)
    texw = cross3(te, w)
    ce = 1.0 / (le * chi)
    cf = 1.0 / (lf * chi)
    for k in range(3):
        gy[k] = ce * (2.0 * tfxw[k] - kappa * s[k])
        gy[3 + k] = cf * (-2.0 * texw[k] - kappa * s[k])
    be_kb = dot3(be, kb)
    bf_kb = dot3(bf, kb)
    gy[6] = 0.5 * be_kb
    gy[7] = 0.5 * bf_kb
    if order < 2:
        return kappa

    ge = gy[0:3]
    gf = gy[3:6]
    c = chi - 1.0  # te . tf
    Pe_tf = np.empty(3)  # (I - te te^T) tf
    Pf_te = np.empty(3)  # (I - tf tf^T) te
    ve = np.empty(3)  # te + Pe_tf / chi
    vf = np.empty(3)  # tf + Pf_te / chi
    for k in range(3):
        Pe_tf[k] = tf[k] - c * te[k]
        Pf_te[k] = te[k] - c * tf[k]
        ve[k] = te[k] + Pe_tf[k] / chi
        vf[k] = tf[k] + Pf_te[k] / chi
    Pe_ae = np.empty(3)
    Pf_af = np.empty(3)
    ae_te = dot3(ae, te)
    af_tf = dot3(af, tf)
    for k in range(3):
        Pe_ae[k] = ae[k] - ae_te * te[k]
        Pf_af[k] = af[k] - af_tf * tf[k]

    Hy[:, :] = 0.0
    # d(ge)/de
    add_outer(Hy, 0, 0, -1.0 / le, ge, ve)
    add_outer(Hy, 0, 0, 0.5 / (le * le), kb, Pe_ae)  # directors of e follow e
    add_outer(Hy, 0, 0, -ce, s, ge)
    add_projector(Hy, 0, 0, -kappa * ce / le, te)
    # d(ge)/df
    add_outer(Hy, 0, 3, -1.0 / (chi * lf), ge, Pf_te)
    add_skew_projected(Hy, 0, 3, -2.0 * ce / lf, w, tf)
    add_outer(Hy, 0, 3, -ce, s, gf)
    add_projector(Hy, 0, 3, -kappa * ce / lf, tf)
    # d(gf)/df
    add_outer(Hy, 3, 3, -1.0 / lf, gf, vf)
    add_outer(Hy, 3, 3, 0.5 / (lf * lf), kb, Pf_af)  # directors of f follow f
    add_outer(Hy, 3, 3, -cf, s, gf)
    add_projector(Hy, 3, 3, -kappa * cf / lf, tf)
    # d(gf)/de
    add_outer(Hy, 3, 0, -1.0 / (chi * le), gf, Pe_tf)
    add_skew_projected(Hy, 3, 0, 2.0 * cf / le, w, te)
    add_outer(Hy, 3, 0, -cf, s, ge)
    add_projector(Hy, 3, 0, -kappa * cf / le, te)
    # position-angle blocks (already symmetric pairs)
    tfxbe = cross3(tf, be)
    tfxbf = cross3(tf, bf)
    texbe = cross3(te, be)
    texbf = cross3(te, bf)
    for k in range(3):
        v = ce * (tfxbe[k] - 0.5 * be_kb * s[k])
        Hy[k, 6] = v
        Hy[6, k] = v
        v = ce * (tfxbf[k] - 0.5 * bf_kb * s[k])
        Hy[k, 7] = v
        Hy[7, k] = v
        v = cf * (-texbe[k] - 0.5 * be_kb * s[k])
        Hy[3 + k, 6] = v
        Hy[6, 3 + k] = v
        v = cf * (-texbf[k] - 0.5 * bf_kb * s[k])
        Hy[3 + k, 7] = v
        Hy[7, 3 + k] = v
    Hy[6, 6] = -0.5 * dot3(ae, kb)
    Hy[7, 7] = -0.5 * dot3(af, kb)
    symmetrize(Hy)
    return kappa


@njit(cache=True)
def material_curvatures(
    x0: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    m1e: np.ndarray,
    m2e: np.ndarray,
    m1f: np.ndarray,
    m2f: np.ndarray,
) -> np.ndarray:
    """Material curvatures ``[kappa1, kappa2]`` (2,) at node ``x1`` (dimensionless, as in
    eqns (3a), (3b) of Huang & Jawed 2020). ``x*``: (3,) m; ``m*``: (3,) unit directors of
    edges ``e = x1 - x0`` and ``f = x2 - x1``."""
    te, tf, le, lf, chi, kb = edge_pair_geometry(x0, x1, x2)
    out = np.empty(2)
    out[0] = 0.5 * (dot3(m2e, kb) + dot3(m2f, kb))
    out[1] = -0.5 * (dot3(m1e, kb) + dot3(m1f, kb))
    return out


@njit(cache=True)
def bend_element(
    x0: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    m1e: np.ndarray,
    m2e: np.ndarray,
    m1f: np.ndarray,
    m2f: np.ndarray,
    kappa_bar: np.ndarray,
    l_vor: float,
    EI: float,
    g: np.ndarray,
    H: np.ndarray,
    order: int,
) -> float:
    """Bending energy (J) at node ``x1``; ``order`` >= 1 / >= 2 also writes the gradient
    ``g`` (11,) / Hessian ``H`` (11, 11) in local order ``[x0, x1, x2, theta_e, theta_f]``.

    ``E = 0.5 EI / l_vor ((k1 - kb1)^2 + (k2 - kb2)^2)``, eqn (5b) of Huang & Jawed 2020.
    ``EI``: N m^2; ``l_vor``: Voronoi length, m; ``kappa_bar``: (2,) rest curvatures.
    """
    te, tf, le, lf, chi, kb = edge_pair_geometry(x0, x1, x2)
    na = np.empty(3)  # -m1e
    nb = np.empty(3)  # -m1f
    nc = np.empty(3)  # -m2e
    nd = np.empty(3)  # -m2f
    for k in range(3):
        na[k] = -m1e[k]
        nb[k] = -m1f[k]
        nc[k] = -m2e[k]
        nd[k] = -m2f[k]
    g1 = np.empty(8)
    g2 = np.empty(8)
    H1 = np.empty((8, 8))
    H2 = np.empty((8, 8))
    k1 = _curvature_derivatives(te, tf, le, lf, chi, kb, m2e, na, m2f, nb, g1, H1, order)
    k2 = _curvature_derivatives(te, tf, le, lf, chi, kb, na, nc, nb, nd, g2, H2, order)
    stiff = EI / l_vor
    d1 = k1 - kappa_bar[0]
    d2 = k2 - kappa_bar[1]
    E = 0.5 * stiff * (d1 * d1 + d2 * d2)
    if order < 1:
        return E
    gy = np.empty(8)
    for a in range(8):
        gy[a] = stiff * (d1 * g1[a] + d2 * g2[a])
    Hy = H1  # reuse: Hy = stiff (g1 g1^T + g2 g2^T + d1 H1 + d2 H2)
    if order >= 2:
        for a in range(8):
            for b in range(8):
                Hy[a, b] = stiff * (
                    g1[a] * g1[b] + g2[a] * g2[b] + d1 * H1[a, b] + d2 * H2[a, b]
                )
    edge_pair_to_nodes(gy, Hy, g, H, order)
    return E


@njit(cache=True)
def bend_energy_grad_hess(
    x0: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    m1e: np.ndarray,
    m2e: np.ndarray,
    m1f: np.ndarray,
    m2f: np.ndarray,
    kappa_bar: np.ndarray,
    l_vor: float,
    EI: float,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Bending energy (J), gradient (11,) and Hessian (11, 11) at node ``x1``.

    See :func:`bend_element`; local DOF order ``[x0, x1, x2, theta_e, theta_f]``.
    """
    g = np.empty(11)
    H = np.empty((11, 11))
    E = bend_element(x0, x1, x2, m1e, m2e, m1f, m2f, kappa_bar, l_vor, EI, g, H, 2)
    return E, g, H
