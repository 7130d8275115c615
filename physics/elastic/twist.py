"""Twisting energy at one interior node, eqns (4) and (5c) of Huang & Jawed 2020.

Same edge-pair element (``edge_pair.py``) and local DOF order as ``bend.py``:
``[x0(3), x1(3), x2(3), theta_e, theta_f]`` with ``e = x1 - x0``, ``f = x2 - x1``.
Under time-parallel reference frames the reference twist varies with the edges as
``d(ref)/de = kb / (2|e|)``, ``d(ref)/df = kb / (2|f|)`` (Bergou et al. 2010, Sec. 6).
Its Hessian is the symmetric part of the derivative of that expression: the
antisymmetric part is the holonomy of parallel transport, which the energy itself does
not see to second order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from physics.elastic.edge_pair import add_block2, edge_pair_geom, edge_pair_result
from physics.model.frames import vcross, vec


@njit(cache=True)
def _twist_hessian(
    te, tf, le: float, lf: float, chi: float, kb, Hy: np.ndarray, stiff: float, sd: float
) -> None:
    """Add the twisting Hessian ``stiff dtau dtau^T + sd d(dtau)/dy`` into ``Hy`` (8, 8),
    not yet symmetrised, where ``dtau = d(tau)/dy = [kb/(2|e|), kb/(2|f|), -1, 1]`` and
    ``sd = stiff (tau - twist_bar)``. ``d(dtau)/dy`` is the derivative of the reference
    twist rate, using ``d kb = ((2 dte x tf - kb (tf . dte)) + (2 te x dtf - kb (te .
    dtf))) / chi``; in each 3x3 block the terms along ``kb`` are merged into one outer
    product. ``te``, ``tf``, ``kb`` are 3-vectors; allocation-free.
    """
    c = chi - 1.0
    Pe_tf = (tf[0] - c * te[0], tf[1] - c * te[1], tf[2] - c * te[2])  # (I - te te^T) tf
    Pf_te = (te[0] - c * tf[0], te[1] - c * tf[1], te[2] - c * tf[2])  # (I - tf tf^T) te
    # k [w]_x (I - t t^T) = k [w]_x - k (w x t) t^T
    tfxte = vcross(tf, te)
    texf = vcross(te, tf)
    he = 0.5 / le  # dtau_e = he kb
    hf = 0.5 / lf  # dtau_f = hf kb
    # d kb/de = (-2 [tf]_x - kb tf^T) Pe / (chi |e|), applied to kb/(2|e|) and kb/(2|f|);
    # (0, 0) also has the derivative of the 1/(2|e|) prefactor
    a = 1.0 / (2.0 * le * chi * le)
    k = sd * (-2.0 * a)
    x = sd * -a
    y = sd * (-0.5 / (le * le))
    z = stiff * he * he
    v = (x * Pe_tf[0] + y * te[0] + z * kb[0], x * Pe_tf[1] + y * te[1] + z * kb[1],
         x * Pe_tf[2] + y * te[2] + z * kb[2])
    add_block2(Hy, 0, 0, -k, tfxte, te, 1.0, kb, v, k, tf)
    a = 1.0 / (2.0 * lf * chi * le)
    k = sd * (-2.0 * a)
    x = sd * -a
    z = stiff * hf * he
    v = (x * Pe_tf[0] + z * kb[0], x * Pe_tf[1] + z * kb[1], x * Pe_tf[2] + z * kb[2])
    add_block2(Hy, 3, 0, -k, tfxte, te, 1.0, kb, v, k, tf)
    # d kb/df = (2 [te]_x - kb te^T) Pf / (chi |f|); (3, 3) also has the derivative of 1/(2|f|)
    a = 1.0 / (2.0 * le * chi * lf)
    k = sd * (2.0 * a)
    x = sd * -a
    z = stiff * he * hf
    v = (x * Pf_te[0] + z * kb[0], x * Pf_te[1] + z * kb[1], x * Pf_te[2] + z * kb[2])
    add_block2(Hy, 0, 3, -k, texf, tf, 1.0, kb, v, k, te)
    a = 1.0 / (2.0 * lf * chi * lf)
    k = sd * (2.0 * a)
    x = sd * -a
    y = sd * (-0.5 / (lf * lf))
    z = stiff * hf * hf
    v = (x * Pf_te[0] + y * tf[0] + z * kb[0], x * Pf_te[1] + y * tf[1] + z * kb[1],
         x * Pf_te[2] + y * tf[2] + z * kb[2])
    add_block2(Hy, 3, 3, -k, texf, tf, 1.0, kb, v, k, te)
    # rows / columns of the angles in stiff dtau dtau^T (dtau_theta = [-1, 1])
    for i in range(3):
        xe = stiff * (0.5 * kb[i] / le)
        xf = stiff * (0.5 * kb[i] / lf)
        Hy[i, 6] -= xe
        Hy[6, i] -= xe
        Hy[i, 7] += xe
        Hy[7, i] += xe
        Hy[3 + i, 6] -= xf
        Hy[6, 3 + i] -= xf
        Hy[3 + i, 7] += xf
        Hy[7, 3 + i] += xf
    Hy[6, 6] += stiff
    Hy[6, 7] -= stiff
    Hy[7, 6] -= stiff
    Hy[7, 7] += stiff


@njit(cache=True)
def twist_into(
    te, tf, le: float, lf: float, chi: float, kb, theta_e: float, theta_f: float,
    ref_twist: float, twist_bar: float, stiff: float,
    gy: np.ndarray, Hy: np.ndarray, order: int,
) -> float:
    """Twisting energy (J) of an edge pair with geometry from
    :func:`physics.elastic.edge_pair.edge_pair_geom`; ``stiff = GJ / l_vor`` (N m).

    ``order`` >= 1 adds the gradient in ``y = [e, f, theta_e, theta_f]`` into ``gy`` (8,),
    ``order`` >= 2 the Hessian, not yet symmetrised, into ``Hy`` (8, 8). Allocation-free.
    """
    d = theta_f - theta_e + ref_twist - twist_bar
    E = 0.5 * stiff * d * d
    if order < 1:
        return E
    sd = stiff * d
    for k in range(3):
        gy[k] += sd * (0.5 * kb[k] / le)
        gy[3 + k] += sd * (0.5 * kb[k] / lf)
    gy[6] -= sd
    gy[7] += sd
    if order >= 2:
        _twist_hessian(te, tf, le, lf, chi, kb, Hy, stiff, sd)
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
    """Twisting energy (J), gradient (11,) and Hessian (11, 11) at node ``x1``, local DOF
    order ``[x0, x1, x2, theta_e, theta_f]``.

    ``tau = theta_f - theta_e + ref_twist`` (eqn (4)), ``E = 0.5 GJ / l_vor (tau -
    twist_bar)^2`` (eqn (5c) of Huang & Jawed 2020, with a rest twist). Angles in rad,
    ``GJ`` in N m^2, ``l_vor`` in m.
    """
    te, tf, le, lf, chi, kb = edge_pair_geom(vec(x0), vec(x1), vec(x2))
    gy = np.zeros(8)
    Hy = np.zeros((8, 8))
    E = twist_into(
        te, tf, le, lf, chi, kb, theta_e, theta_f, ref_twist, twist_bar, GJ / l_vor, gy, Hy, 2
    )
    return edge_pair_result(E, gy, Hy)
