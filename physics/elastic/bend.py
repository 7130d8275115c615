"""Bending energy at one interior node, eqns (2), (3a), (3b), (5b) of Huang & Jawed 2020.

The element is the edge pair ``e = x1 - x0`` and ``f = x2 - x1`` with local DOF order
``[x0(3), x1(3), x2(3), theta_e, theta_f]``. Derivatives follow the DER convention
(Bergou et al. 2008, 2010): when an edge moves, its material directors follow it by
time-parallel transport, so to first order they only gain a component along the new
tangent. The Hessian is the exact (symmetric) Hessian of the energy under that rule;
the Jacobian of the gradient formula itself also has an antisymmetric part (the holonomy
of parallel transport, proportional to dE/dtheta) which is dropped, as in DER.

Derivatives are first formed in the reduced coordinates ``y = [e(3), f(3), theta_e,
theta_f]`` and then mapped to the nodes; the edge-pair geometry, that map and the block
helpers are shared with ``twist.py`` in ``edge_pair.py``.

The kernels are allocation-free: 3-vectors are 3-tuples of floats (see
``physics.model.frames.vcross``) and :func:`bend_into` adds into scratch arrays the caller
allocates once. Only the per-element :func:`bend_energy_grad_hess` allocates.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.elastic.edge_pair import add_block, edge_pair_geom, edge_pair_result
from physics.model.frames import dot3, vcross, vec


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
    """Bending energy (J), gradient (11,) and Hessian (11, 11) at node ``x1``, local DOF
    order ``[x0, x1, x2, theta_e, theta_f]``.

    ``E = 0.5 EI / l_vor ((k1 - kb1)^2 + (k2 - kb2)^2)``, eqn (5b) of Huang & Jawed 2020.
    ``x*``: (3,) m; ``m*``: (3,) unit directors of edges ``e = x1 - x0`` and ``f = x2 -
    x1``; ``kappa_bar``: (2,) rest curvatures; ``l_vor``: Voronoi length, m; ``EI``: N m^2.
    """
    te, tf, le, lf, chi, kb = edge_pair_geom(vec(x0), vec(x1), vec(x2))
    gy = np.zeros(8)
    Hy = np.zeros((8, 8))
    E = bend_into(
        te, tf, le, lf, chi, kb, vec(m1e), vec(m2e), vec(m1f), vec(m2f),
        kappa_bar[0], kappa_bar[1], EI / l_vor, gy, Hy, 2,
    )
    return edge_pair_result(E, gy, Hy)
