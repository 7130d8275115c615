"""Elastic energy of a whole rod and its derivatives, eqns (5a)-(5c) and (7) of Huang &
Jawed 2020.

The rod has ``n`` nodes and DOF vector ``q`` (4n-1,): node ``i`` at ``q[4i:4i+3]`` (m),
edge ``i`` twist angle at ``q[4i+3]`` (rad). The gradient is ``d(E_s + E_b + E_t)/dq``,
i.e. minus the internal force of eqn (6); the Hessian is banded with ``kl = ku = 10`` and
returned in LAPACK general-banded storage, ``ab[10 + i - j, j] = H[i, j]``, as taken by
``scipy.linalg.solve_banded((10, 10), ab, rhs)``.

The Numba kernels (``*_kernel``) take the rest arrays explicitly (``*rest.arrays()``);
the thin wrappers of the same name without the suffix take a :class:`RodRest`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from physics.elastic.banded import BANDWIDTH
from physics.elastic.bend import bend_into, material_curvatures
from physics.elastic.edge_pair import edge_pair_geom, edge_pair_scatter
from physics.elastic.stretch import stretch_into
from physics.elastic.twist import twist_into
from physics.model.frames import (
    material_frames,
    reference_twist,
    row3,
    space_parallel_frames,
    tangents,
    update_frames,
)


@dataclass(frozen=True)
class RodRest:
    """Rest (stress-free) state and stiffnesses of an ``n``-node rod.

    ``l_bar`` (n-1,) rest edge lengths, m; ``l_vor`` (n-2,) Voronoi lengths
    ``(l_bar[i-1] + l_bar[i]) / 2``, m; ``kappa_bar`` (n-2, 2) rest material curvatures;
    ``twist_bar`` (n-2,) rest twists, rad; ``EA`` (n-1,) stretching stiffness per edge, N;
    ``EI``, ``GJ`` (n-2,) bending and twisting stiffness per interior node, N m^2.
    """

    l_bar: np.ndarray
    l_vor: np.ndarray
    kappa_bar: np.ndarray
    twist_bar: np.ndarray
    EA: np.ndarray
    EI: np.ndarray
    GJ: np.ndarray

    def __post_init__(self) -> None:
        for name in ("l_bar", "l_vor", "kappa_bar", "twist_bar", "EA", "EI", "GJ"):
            object.__setattr__(
                self, name, np.ascontiguousarray(getattr(self, name), dtype=np.float64)
            )
        m = self.l_bar.shape[0] if self.l_bar.ndim == 1 else -1
        if m < 2:
            raise ValueError(f"l_bar must be 1-D with at least 2 edges, got shape {self.l_bar.shape}")
        expected = {
            "l_vor": (m - 1,),
            "kappa_bar": (m - 1, 2),
            "twist_bar": (m - 1,),
            "EA": (m,),
            "EI": (m - 1,),
            "GJ": (m - 1,),
        }
        for name, shape in expected.items():
            got = getattr(self, name).shape
            if got != shape:
                raise ValueError(f"{name} must have shape {shape} for {m + 1} nodes, got {got}")

    @property
    def n_nodes(self) -> int:
        """Number of nodes ``n``."""
        return self.l_bar.shape[0] + 1

    def arrays(self) -> tuple[np.ndarray, ...]:
        """``(l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ)``, the order the kernels take."""
        return (self.l_bar, self.l_vor, self.kappa_bar, self.twist_bar, self.EA, self.EI, self.GJ)


@njit(cache=True)
def rod_frames(
    q: np.ndarray, d1_old: np.ndarray, t_old: np.ndarray, ref_twist_old: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frames of configuration ``q`` (4n-1,) reached from the previous step.

    Tangents of ``q``; reference directors time-parallel transported from ``d1_old``
    along ``t_old -> t`` (both (n-1, 3)); reference twist (n-2,) kept continuous with
    ``ref_twist_old``; material frames from the twist angles in ``q``.
    Returns ``(t, d1, d2, ref_twist, m1, m2)``.

    Same results as ``tangents``, ``time_parallel_transport``, ``reference_twist`` and
    ``material_frames`` in sequence (see :func:`physics.model.frames.update_frames`).
    """
    return update_frames(q, d1_old, t_old, ref_twist_old)


# The four kernels below take one argument list, ``(q, d1, d2, ref_twist, m1, m2, l_bar,
# l_vor, kappa_bar, twist_bar, EA, EI, GJ)``: the DOF vector ``q`` (4n-1,); the frames of
# ``q`` as :func:`rod_frames` returns them, ``d1``, ``d2``, ``m1``, ``m2`` (n-1, 3) and
# ``ref_twist`` (n-2,) (``d1``, ``d2`` are not needed once ``m1``, ``m2`` are known; they
# keep the list uniform with the frames); then the rest arrays of :class:`RodRest` in the
# order of :meth:`RodRest.arrays`. They differ only in what they compute and return. The
# list is spelled out in each ``def`` rather than taken as ``*rest``: Numba packs star
# arguments into a tuple on every call, which costs ~0.35 us per call.


@njit(cache=True)
def _assemble(
    q: np.ndarray, ref_twist: np.ndarray, m1: np.ndarray, m2: np.ndarray,
    l_bar: np.ndarray, l_vor: np.ndarray, kappa_bar: np.ndarray, twist_bar: np.ndarray,
    EA: np.ndarray, EI: np.ndarray, GJ: np.ndarray,
    order: int, need_grad: bool, grad: np.ndarray, ab: np.ndarray,
) -> float:
    """Sum the stretch, bend and twist elements. Returns the energy (J); ``order`` >= 1
    with ``need_grad`` adds the gradient into ``grad`` (4n-1,), ``order`` >= 2 the banded
    Hessian into ``ab`` (21, 4n-1). O(n). The only allocation is one (9, 8) scratch
    block per call; bending and twisting of a node share its edge-pair geometry and are
    summed in the reduced coordinates before one scatter to the rod's DOFs."""
    n = (q.shape[0] + 1) // 4
    E = 0.0
    for i in range(n - 1):
        E += stretch_into(q, i, l_bar[i], EA[i], order, need_grad, grad, ab)

    work = np.empty((9, 8))
    Hy = work[0:8]  # (8, 8) Hessian in y = [e, f, theta_e, theta_f], symmetric part used
    gy = work[8]  # (8,) gradient in y
    for i in range(1, n - 1):
        b = 4 * (i - 1)
        te, tf, le, lf, chi, kb = edge_pair_geom(
            (q[b], q[b + 1], q[b + 2]),
            (q[b + 4], q[b + 5], q[b + 6]),
            (q[b + 8], q[b + 9], q[b + 10]),
        )
        if order >= 1:
            for a in range(8):
                gy[a] = 0.0
        if order >= 2:
            for a in range(8):
                for c in range(8):
                    Hy[a, c] = 0.0
        E += bend_into(
            te, tf, le, lf, chi, kb, row3(m1, i - 1), row3(m2, i - 1), row3(m1, i), row3(m2, i),
            kappa_bar[i - 1, 0], kappa_bar[i - 1, 1], EI[i - 1] / l_vor[i - 1],
            gy, Hy, order,
        )
        E += twist_into(
            te, tf, le, lf, chi, kb, q[b + 3], q[b + 7], ref_twist[i - 1], twist_bar[i - 1],
            GJ[i - 1] / l_vor[i - 1], gy, Hy, order,
        )
        if order >= 1:
            edge_pair_scatter(gy, Hy, b, order, need_grad, grad, ab)
    return E


@njit(cache=True)
def elastic_energy_kernel(q, d1, d2, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ):
    """Elastic energy ``E_s + E_b + E_t`` (J), eqns (5a)-(5c) of Huang & Jawed 2020.
    Arguments: the kernels' common list (above)."""
    return _assemble(q, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ,
                     0, False, np.empty(0), np.empty((0, 0)))


@njit(cache=True)
def elastic_gradient_kernel(q, d1, d2, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ):
    """Gradient (4n-1,) of the elastic energy: N on positions, N m on twist angles; minus
    the internal force ``F^int`` of eqn (6) of Huang & Jawed 2020. Arguments: the
    kernels' common list (above)."""
    grad = np.zeros(q.shape[0])
    _assemble(q, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ,
              1, True, grad, np.empty((0, 0)))
    return grad


@njit(cache=True)
def elastic_hessian_banded_kernel(q, d1, d2, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ):
    """Hessian of the elastic energy (the elastic part of eqn (7) of Huang & Jawed 2020)
    in general-banded storage ``ab`` (21, 4n-1), ``ab[10 + i - j, j] = H[i, j]``.
    Arguments: the kernels' common list (above)."""
    ab = np.zeros((2 * BANDWIDTH + 1, q.shape[0]))
    _assemble(q, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ,
              2, False, np.empty(0), ab)
    return ab


@njit(cache=True)
def elastic_energy_grad_hess_banded_kernel(
    q, d1, d2, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ
):
    """Energy (J), gradient (4n-1,) and banded Hessian (21, 4n-1) in one pass, for a
    Newton step. Arguments: the kernels' common list (above)."""
    grad = np.zeros(q.shape[0])
    ab = np.zeros((2 * BANDWIDTH + 1, q.shape[0]))
    E = _assemble(q, ref_twist, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ,
                  2, True, grad, ab)
    return E, grad, ab


@njit(cache=True)
def banded_to_dense(ab: np.ndarray) -> np.ndarray:
    """Dense (N, N) matrix from general-banded storage ``ab`` (kl + ku + 1, N) with
    ``kl = ku = (ab.shape[0] - 1) // 2``."""
    N = ab.shape[1]
    ku = (ab.shape[0] - 1) // 2
    D = np.zeros((N, N))
    for j in range(N):
        for i in range(max(0, j - ku), min(N, j + ku + 1)):
            D[i, j] = ab[ku + i - j, j]
    return D


def rest_from_configuration(
    q: np.ndarray,
    EA: float | np.ndarray,
    EI: float | np.ndarray,
    GJ: float | np.ndarray,
) -> tuple[RodRest, np.ndarray, np.ndarray, np.ndarray]:
    """Take configuration ``q`` (4n-1,) as the stress-free state.

    Space-parallel reference frames, reference twist from zero, rest curvatures
    (eqns (3a), (3b)) and rest twists ``theta_f - theta_e + ref_twist`` (eqn (4)) of ``q``
    itself, so ``q`` is an exact equilibrium. ``EA`` (N) is a scalar or (n-1,) array,
    ``EI``, ``GJ`` (N m^2) scalars or (n-2,) arrays. Returns ``(rest, d1, d2, ref_twist)``
    with ``d1``, ``d2`` (n-1, 3) and ``ref_twist`` (n-2,).
    """
    q = np.ascontiguousarray(q, dtype=np.float64)
    if q.ndim != 1 or (q.shape[0] + 1) % 4 != 0 or q.shape[0] < 11:
        raise ValueError(f"q must have shape (4n-1,) with n >= 3, got {q.shape}")
    n = (q.shape[0] + 1) // 4
    x = np.stack([q[4 * i:4 * i + 3] for i in range(n)])
    theta = np.ascontiguousarray(q[3::4])
    t = tangents(q)
    d1, d2 = space_parallel_frames(t)
    ref = reference_twist(d1, t, np.zeros(n - 2))
    m1, m2 = material_frames(d1, d2, theta)
    l_bar = np.linalg.norm(np.diff(x, axis=0), axis=1)
    kappa_bar = np.empty((n - 2, 2))
    for i in range(1, n - 1):
        kappa_bar[i - 1] = material_curvatures(
            x[i - 1], x[i], x[i + 1], m1[i - 1], m2[i - 1], m1[i], m2[i]
        )
    rest = RodRest(
        l_bar=l_bar,
        l_vor=0.5 * (l_bar[:-1] + l_bar[1:]),
        kappa_bar=kappa_bar,
        twist_bar=theta[1:] - theta[:-1] + ref,
        EA=np.broadcast_to(np.asarray(EA, dtype=np.float64), (n - 1,)),
        EI=np.broadcast_to(np.asarray(EI, dtype=np.float64), (n - 2,)),
        GJ=np.broadcast_to(np.asarray(GJ, dtype=np.float64), (n - 2,)),
    )
    return rest, d1, d2, ref


def elastic_energy(
    q: np.ndarray, d1: np.ndarray, d2: np.ndarray, ref_twist: np.ndarray,
    m1: np.ndarray, m2: np.ndarray, rest: RodRest,
) -> float:
    """Elastic energy (J) of ``q``; :func:`elastic_energy_kernel` with ``rest``'s arrays."""
    return elastic_energy_kernel(q, d1, d2, ref_twist, m1, m2, *rest.arrays())


def elastic_gradient(
    q: np.ndarray, d1: np.ndarray, d2: np.ndarray, ref_twist: np.ndarray,
    m1: np.ndarray, m2: np.ndarray, rest: RodRest,
) -> np.ndarray:
    """Elastic gradient (4n-1,), minus the internal force of eqn (6);
    :func:`elastic_gradient_kernel` with ``rest``'s arrays."""
    return elastic_gradient_kernel(q, d1, d2, ref_twist, m1, m2, *rest.arrays())


def elastic_hessian_banded(
    q: np.ndarray, d1: np.ndarray, d2: np.ndarray, ref_twist: np.ndarray,
    m1: np.ndarray, m2: np.ndarray, rest: RodRest,
) -> np.ndarray:
    """Banded elastic Hessian ``ab`` (21, 4n-1), ``ab[10 + i - j, j] = H[i, j]``;
    :func:`elastic_hessian_banded_kernel` with ``rest``'s arrays."""
    return elastic_hessian_banded_kernel(q, d1, d2, ref_twist, m1, m2, *rest.arrays())


def elastic_energy_grad_hess_banded(
    q: np.ndarray, d1: np.ndarray, d2: np.ndarray, ref_twist: np.ndarray,
    m1: np.ndarray, m2: np.ndarray, rest: RodRest,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Energy, gradient and banded Hessian in one pass;
    :func:`elastic_energy_grad_hess_banded_kernel` with ``rest``'s arrays."""
    return elastic_energy_grad_hess_banded_kernel(q, d1, d2, ref_twist, m1, m2, *rest.arrays())
