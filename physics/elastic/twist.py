"""Twisting energy at one interior node, eqns (4) and (5c) of Huang & Jawed 2020.

Same edge-pair element and local DOF order as ``bend.py``: ``[x0(3), x1(3), x2(3),
theta_e, theta_f]`` with ``e = x1 - x0``, ``f = x2 - x1``. Under time-parallel reference
frames the reference twist varies with the edges as ``d(ref)/de = kb / (2|e|)``,
``d(ref)/df = kb / (2|f|)`` (Bergou et al. 2010, Sec. 6). Its Hessian is the symmetric
part of the derivative of that expression: the antisymmetric part is the holonomy of
parallel transport, which the energy itself does not see to second order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.elastic.bend import (
    add_outer,
    add_skew_projected,
    edge_pair_geom,
    edge_pair_to_nodes,
    symmetrize,
)
from physics.frames import vec


@njit(cache=True)
def _reference_twist_hessian(
    te, tf, le: float, lf: float, chi: float, kb, Hy: np.ndarray, alpha: float
) -> None:
    """Add ``alpha`` times the derivative (8, 8) of ``[kb/(2|e|), kb/(2|f|), 0, 0]`` with
    respect to ``y = [e, f, theta_e, theta_f]`` into ``Hy``, not yet symmetrised (only the
    6x6 position block is touched). Uses ``d kb = ((2 dte x tf - kb (tf . dte)) + (2 te x
    dtf - kb (te . dtf))) / chi``. ``te``, ``tf``, ``kb`` are 3-vectors; allocation-free.
    """
    c = chi - 1.0
    Pe_tf = (tf[0] - c * te[0], tf[1] - c * te[1], tf[2] - c * te[2])
    Pf_te = (te[0] - c * tf[0], te[1] - c * tf[1], te[2] - c * tf[2])
    # d(kb/(2|e|))/de and d(kb/(2|f|))/de: d kb/de = (-2 [tf]_x - kb tf^T) Pe / (chi |e|)
    a = 1.0 / (2.0 * le * chi * le)
    add_skew_projected(Hy, 0, 0, alpha * (-2.0 * a), tf, te)
    add_outer(Hy, 0, 0, alpha * -a, kb, Pe_tf)
    a = 1.0 / (2.0 * lf * chi * le)
    add_skew_projected(Hy, 3, 0, alpha * (-2.0 * a), tf, te)
    add_outer(Hy, 3, 0, alpha * -a, kb, Pe_tf)
    # d kb/df = (2 [te]_x - kb te^T) Pf / (chi |f|)
    a = 1.0 / (2.0 * le * chi * lf)
    add_skew_projected(Hy, 0, 3, alpha * (2.0 * a), te, tf)
    add_outer(Hy, 0, 3, alpha * -a, kb, Pf_te)
    a = 1.0 / (2.0 * lf * chi * lf)
    add_skew_projected(Hy, 3, 3, alpha * (2.0 * a), te, tf)
    add_outer(Hy, 3, 3, alpha * -a, kb, Pf_te)
    # derivative of the 1/(2|e|) and 1/(2|f|) prefactors
    add_outer(Hy, 0, 0, alpha * (-0.5 / (le * le)), kb, te)
    add_outer(Hy, 3, 3, alpha * (-0.5 / (lf * lf)), kb, tf)


@njit(cache=True)
def twist_into(
    te, tf, le: float, lf: float, chi: float, kb, theta_e: float, theta_f: float,
    ref_twist: float, twist_bar: float, stiff: float,
    gy: np.ndarray, Hy: np.ndarray, dtau: np.ndarray, order: int,
) -> float:
    """Twisting energy (J) of an edge pair with geometry from
    :func:`physics.elastic.bend.edge_pair_geom`; ``stiff = GJ / l_vor`` (N m).

    ``order`` >= 1 adds the gradient in ``y = [e, f, theta_e, theta_f]`` into ``gy`` (8,),
    ``order`` >= 2 the Hessian, not yet symmetrised, into ``Hy`` (8, 8). ``dtau`` (8,) is
    scratch. Allocation-free.
    """
    d = theta_f - theta_e + ref_twist - twist_bar
    E = 0.5 * stiff * d * d
    if order < 1:
        return E
    for k in range(3):
        dtau[k] = 0.5 * kb[k] / le
        dtau[3 + k] = 0.5 * kb[k] / lf
    dtau[6] = -1.0
    dtau[7] = 1.0
    sd = stiff * d
    for a in range(8):
        gy[a] += sd * dtau[a]
    if order < 2:
        return E
    for a in range(8):
        da = stiff * dtau[a]
        for b in range(8):
            Hy[a, b] += da * dtau[b]
    _reference_twist_hessian(te, tf, le, lf, chi, kb, Hy, sd)
    return E


@njit(cache=True)
def twist_element(
    x0: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    theta_e: float,
    theta_f: float,
    ref_twist: float,
    twist_bar: float,
    l_vor: float,
    GJ: float,
    g: np.ndarray,
    H: np.ndarray,
    order: int,
) -> float:
    """Twisting energy (J) at node ``x1``; ``order`` >= 1 / >= 2 also writes the gradient
    ``g`` (11,) / Hessian ``H`` (11, 11) in local order ``[x0, x1, x2, theta_e, theta_f]``.

    ``tau = theta_f - theta_e + ref_twist`` (eqn (4)), ``E = 0.5 GJ / l_vor (tau -
    twist_bar)^2`` (eqn (5c) of Huang & Jawed 2020, with a rest twist). Angles in rad,
    ``GJ`` in N m^2, ``l_vor`` in m.
    """
    te, tf, le, lf, chi, kb = edge_pair_geom(vec(x0), vec(x1), vec(x2))
    gy = np.zeros(8)
    dtau = np.empty(8)
    Hy = np.zeros((8, 8))
    E = twist_into(
        te, tf, le, lf, chi, kb, theta_e, theta_f, ref_twist, twist_bar, GJ / l_vor,
        gy, Hy, dtau, order,
    )
    if order < 1:
        return E
    if order >= 2:
        symmetrize(Hy)
    edge_pair_to_nodes(gy, Hy, g, H, order)
    return E


@njit(cache=True)
def twist_energy_grad_hess(
    x0: np.ndarray,
    x1: np.ndarray,
    x2: np.ndarray,
    theta_e: float,
    theta_f: float,
    ref_twist: float,
    twist_bar: float,
    l_vor: float,
    GJ: float,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Twisting energy (J), gradient (11,) and Hessian (11, 11) at node ``x1``.

    See :func:`twist_element`; local DOF order ``[x0, x1, x2, theta_e, theta_f]``.
    """
    g = np.empty(11)
    H = np.empty((11, 11))
    E = twist_element(x0, x1, x2, theta_e, theta_f, ref_twist, twist_bar, l_vor, GJ, g, H, 2)
    return E, g, H
