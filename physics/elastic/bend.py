"""Bending energy at one interior node, eqns (2), (3a), (3b), (5b) of Huang & Jawed 2020.

The element is the edge pair ``e = x1 - x0`` and ``f = x2 - x1`` with local DOF order
``[x0(3), x1(3), x2(3), theta_e, theta_f]``. Derivatives follow the DER convention
(Bergou et al. 2008, 2010): when an edge moves, its material directors follow it by
time-parallel transport, so to first order they only gain a component along the new
tangent. The Hessian is the exact (symmetric) Hessian of the energy under that rule;
the Jacobian of the gradient formula itself also has an antisymmetric part (the holonomy
of parallel transport, proportional to dE/dtheta) which is dropped, as in DER.

Derivatives are first formed in the reduced coordinates ``y = [e(3), f(3), theta_e,
theta_f]`` and then mapped to the nodes with :func:`edge_pair_to_nodes` (one element) or
:func:`edge_pair_scatter` (straight into the rod's gradient and banded Hessian); the small
block helpers here are shared with ``twist.py``.

The kernels are allocation-free: 3-vectors are 3-tuples of floats (see
``physics.frames.vcross``) and the ``*_into`` functions add into scratch arrays the caller
allocates once. Only the per-element wrappers (``bend_element``,
``bend_energy_grad_hess``, ...) allocate.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.elastic.banded import add_band
from physics.frames import dot3, vcross, vec

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


@njit(cache=True)
def _kappa(ae, af, kb) -> float:
    """``0.5 (ae + af) . kb`` for 3-vectors."""
    return (
        0.5 * (ae[0] + af[0]) * kb[0]
        + 0.5 * (ae[1] + af[1]) * kb[1]
        + 0.5 * (ae[2] + af[2]) * kb[2]
    )


@njit(cache=True)
def _curvature_into(
    te, tf, le: float, lf: float, chi: float, kb, ae, be, af, bf, kappa: float,
    Hy: np.ndarray, alpha: float, beta: float, order: int,
):
    """Derivatives in ``y`` of one material curvature ``kappa = 0.5 (ae + af) . kb``.

    ``kappa1`` (eqn (3a)) uses ``a = m2``, ``b = -m1``; ``kappa2`` (eqn (3b)) uses
    ``a = -m1``, ``b = -m2``; ``b = da/dtheta`` and ``db/dtheta = -a``. The gradient is
    the DER one (Bergou et al. 2010): ``dk/de = (2 tf x w - k (te + tf)) / (|e| chi)``,
    ``dk/df = (-2 te x w - k (te + tf)) / (|f| chi)`` with ``w = 0.5 (ae + af)``, and
    ``dk/dtheta = 0.5 b . kb``. The Hessian is the symmetric part of the derivative of
    that gradient when directors follow their edges (``d a_e = -(a_e . d te) te``).
    Returns the gradient ``g`` as an 8-tuple and, if ``order`` >= 2, adds ``alpha H +
    beta g g^T`` into ``Hy`` (8, 8), ``H`` being the Hessian of ``kappa``; with ``alpha =
    stiff (kappa - kappa_bar)`` and ``beta = stiff`` that is the Hessian of ``0.5 stiff
    (kappa - kappa_bar)^2``. ``Hy`` is not symmetrised (only its symmetric part is used).
    All vectors are 3-tuples; allocation-free.
    """
    w = (0.5 * (ae[0] + af[0]), 0.5 * (ae[1] + af[1]), 0.5 * (ae[2] + af[2]))
    s = (te[0] + tf[0], te[1] + tf[1], te[2] + tf[2])
    tfxw = vcross(tf, w)
    texw = vcross(te, w)
    ce = 1.0 / (le * chi)
    cf = 1.0 / (lf * chi)
    ge = (
        ce * (2.0 * tfxw[0] - kappa * s[0]),
        ce * (2.0 * tfxw[1] - kappa * s[1]),
        ce * (2.0 * tfxw[2] - kappa * s[2]),
    )
    gf = (
        cf * (-2.0 * texw[0] - kappa * s[0]),
        cf * (-2.0 * texw[1] - kappa * s[1]),
        cf * (-2.0 * texw[2] - kappa * s[2]),
    )
    be_kb = dot3(be, kb)
    bf_kb = dot3(bf, kb)
    g = (ge[0], ge[1], ge[2], gf[0], gf[1], gf[2], 0.5 * be_kb, 0.5 * bf_kb)
    if order < 2:
        return g

    c = chi - 1.0  # te . tf
    Pe_tf = (tf[0] - c * te[0], tf[1] - c * te[1], tf[2] - c * te[2])  # (I - te te^T) tf
    Pf_te = (te[0] - c * tf[0], te[1] - c * tf[1], te[2] - c * tf[2])  # (I - tf tf^T) te
    ve = (te[0] + Pe_tf[0] / chi, te[1] + Pe_tf[1] / chi, te[2] + Pe_tf[2] / chi)
    vf = (tf[0] + Pf_te[0] / chi, tf[1] + Pf_te[1] / chi, tf[2] + Pf_te[2] / chi)
    ae_te = dot3(ae, te)
    af_tf = dot3(af, tf)
    Pe_ae = (ae[0] - ae_te * te[0], ae[1] - ae_te * te[1], ae[2] - ae_te * te[2])
    Pf_af = (af[0] - af_tf * tf[0], af[1] - af_tf * tf[1], af[2] - af_tf * tf[2])

    g6 = g[6]
    g7 = g[7]
    # Each 3x3 block is a few outer products, a projector p (I - t t^T) = p I - p t t^T
    # and a skewed projector k [w]_x (I - t t^T) = k [w]_x - k (w x t) t^T; the
    # beta g g^T blocks share their left vector with the first term.
    # d(ge)/de; the kb Pe_ae term is from the directors of e following e
    x = alpha * (-1.0 / le)
    v = (x * ve[0] + beta * ge[0], x * ve[1] + beta * ge[1], x * ve[2] + beta * ge[2])
    p = alpha * (-kappa * ce / le)
    add_block(
        Hy, 0, 0, 1.0, ge, v, alpha * (0.5 / (le * le)), kb, Pe_ae,
        alpha * -ce, s, ge, -p, te, te, p, 0.0, w,
    )
    # d(ge)/df
    x = alpha * (-1.0 / (chi * lf))
    v = (x * Pf_te[0] + beta * gf[0], x * Pf_te[1] + beta * gf[1], x * Pf_te[2] + beta * gf[2])
    p = alpha * (-kappa * ce / lf)
    k = alpha * (-2.0 * ce / lf)
    add_block(
        Hy, 0, 3, 1.0, ge, v, -k, vcross(w, tf), tf,
        alpha * -ce, s, gf, -p, tf, tf, p, k, w,
    )
    # d(gf)/df; the kb Pf_af term is from the directors of f following f
    x = alpha * (-1.0 / lf)
    v = (x * vf[0] + beta * gf[0], x * vf[1] + beta * gf[1], x * vf[2] + beta * gf[2])
    p = alpha * (-kappa * cf / lf)
    add_block(
        Hy, 3, 3, 1.0, gf, v, alpha * (0.5 / (lf * lf)), kb, Pf_af,
        alpha * -cf, s, gf, -p, tf, tf, p, 0.0, w,
    )
    # d(gf)/de
    x = alpha * (-1.0 / (chi * le))
    v = (x * Pe_tf[0] + beta * ge[0], x * Pe_tf[1] + beta * ge[1], x * Pe_tf[2] + beta * ge[2])
    p = alpha * (-kappa * cf / le)
    k = alpha * (2.0 * cf / le)
    add_block(
        Hy, 3, 0, 1.0, gf, v, -k, vcross(w, te), te,
        alpha * -cf, s, ge, -p, te, te, p, k, w,
    )
    # position-angle blocks (symmetric pairs)
    tfxbe = vcross(tf, be)
    tfxbf = vcross(tf, bf)
    texbe = vcross(te, be)
    texbf = vcross(te, bf)
    ace = alpha * ce
    acf = alpha * cf
    b6 = beta * g6
    b7 = beta * g7
    for k in range(3):
        v = ace * (tfxbe[k] - 0.5 * be_kb * s[k]) + b6 * ge[k]
        Hy[k, 6] += v
        Hy[6, k] += v
        v = ace * (tfxbf[k] - 0.5 * bf_kb * s[k]) + b7 * ge[k]
        Hy[k, 7] += v
        Hy[7, k] += v
        v = acf * (-texbe[k] - 0.5 * be_kb * s[k]) + b6 * gf[k]
        Hy[3 + k, 6] += v
        Hy[6, 3 + k] += v
        v = acf * (-texbf[k] - 0.5 * bf_kb * s[k]) + b7 * gf[k]
        Hy[3 + k, 7] += v
        Hy[7, 3 + k] += v
    Hy[6, 6] += alpha * (-0.5 * dot3(ae, kb)) + b6 * g6
    Hy[7, 7] += alpha * (-0.5 * dot3(af, kb)) + b7 * g7
    Hy[6, 7] += b6 * g7
    Hy[7, 6] += b6 * g7
    return g


@njit(cache=True)
def bend_into(
    te, tf, le: float, lf: float, chi: float, kb, m1e, m2e, m1f, m2f,
    kappa_bar1: float, kappa_bar2: float, stiff: float, gy: np.ndarray, Hy: np.ndarray,
    order: int,
) -> float:
    """Bending energy (J) of an edge pair with geometry from :func:`edge_pair_geom` and
    directors ``m1e, m2e, m1f, m2f`` (3-tuples); ``stiff = EI / l_vor`` (N m).

    ``order`` >= 1 adds the gradient in ``y = [e, f, theta_e, theta_f]`` into ``gy`` (8,),
    ``order`` >= 2 the Hessian, not symmetrised, into ``Hy`` (8, 8). Allocation-free.
    """
    na = (-m1e[0], -m1e[1], -m1e[2])
    nb = (-m1f[0], -m1f[1], -m1f[2])
    nc = (-m2e[0], -m2e[1], -m2e[2])
    nd = (-m2f[0], -m2f[1], -m2f[2])
    k1 = _kappa(m2e, m2f, kb)
    k2 = _kappa(na, nb, kb)
    d1 = k1 - kappa_bar1
    d2 = k2 - kappa_bar2
    E = 0.5 * stiff * (d1 * d1 + d2 * d2)
    if order < 1:
        return E
    # the Hessian is stiff (d1 H1 + g1 g1^T + d2 H2 + g2 g2^T), H_i that of kappa_i
    g1 = _curvature_into(
        te, tf, le, lf, chi, kb, m2e, na, m2f, nb, k1, Hy, stiff * d1, stiff, order
    )
    g2 = _curvature_into(
        te, tf, le, lf, chi, kb, na, nc, nb, nd, k2, Hy, stiff * d2, stiff, order
    )
    gy[0] += stiff * (d1 * g1[0] + d2 * g2[0])
    gy[1] += stiff * (d1 * g1[1] + d2 * g2[1])
    gy[2] += stiff * (d1 * g1[2] + d2 * g2[2])
    gy[3] += stiff * (d1 * g1[3] + d2 * g2[3])
    gy[4] += stiff * (d1 * g1[4] + d2 * g2[4])
    gy[5] += stiff * (d1 * g1[5] + d2 * g2[5])
    gy[6] += stiff * (d1 * g1[6] + d2 * g2[6])
    gy[7] += stiff * (d1 * g1[7] + d2 * g2[7])
    return E


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
    te, tf, le, lf, chi, kb = edge_pair_geom(vec(x0), vec(x1), vec(x2))
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
    te, tf, le, lf, chi, kb = edge_pair_geom(vec(x0), vec(x1), vec(x2))
    gy = np.zeros(8)
    Hy = np.zeros((8, 8))
    E = bend_into(
        te, tf, le, lf, chi, kb, vec(m1e), vec(m2e), vec(m1f), vec(m2f),
        kappa_bar[0], kappa_bar[1], EI / l_vor, gy, Hy, order,
    )
    if order < 1:
        return E
    if order >= 2:
        symmetrize(Hy)
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
