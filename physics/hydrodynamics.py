"""Generalised hydrodynamic resistance of head + flagellum (eqns 8-13 of Huang & Jawed 2020).

Generalised velocity V = [u_0, u_1, ..., u_{n-1}, s] (node velocities of the whole rod,
node 0 being the head centre U_h when there is a head, then the head spin rate s about the
head axis a = t^0 when the head spins). The hydrodynamic generalised force (forces on the
nodes, then the axial torque on the head) is G = -R V with

    R = D + B^T C B,   C = A_reg^{-1} (LSBT resistance, eqn 9),   B = [-H | I | -g],
    D = diag(6 pi mu b I_3, 0, 8 pi mu b^3).

This is eqns (9)-(13) solved together: the flagellum forces F = -C (u - H U - g s) follow from
eqn (8) with the head flow of eqn (10) subtracted, the head force f_0 = -6 pi mu b U - H^T F
is eqn (12) with eqn (11), and the head's axial torque -8 pi mu b^3 s - g^T F is the axial
part of eqn (13)'s head terms. With the reciprocal head forms of ``higdon_head`` R is
symmetric positive definite (the system can only dissipate energy).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from physics.higdon_head import head_flow_operators, sphere_rotational_drag, sphere_translational_drag
from physics.lsbt import lsbt_mobility, node_tangents


class HydroError(RuntimeError):
    """The hydrodynamic mobility could not be inverted (geometry degenerate)."""


def spd_inverse(a: np.ndarray, require_spd: bool = True) -> np.ndarray:
    """Inverse of a symmetric positive-definite matrix by Cholesky (LAPACK potrf/potri).

    With ``require_spd=False`` an indefinite matrix (plain eqn 8, no smoothing) is inverted by LU.
    """
    if not require_spd:
        return np.linalg.inv(a)
    c, info = lapack.dpotrf(a, lower=0, clean=0, overwrite_a=0)
    if info != 0:
        raise HydroError(f"LSBT mobility is not positive definite (Cholesky failed at pivot {info})")
    inv, info = lapack.dpotri(c, lower=0, overwrite_c=1)
    if info != 0:
        raise HydroError(f"LSBT mobility inversion failed (potri info {info})")
    inv = np.triu(inv)
    return inv + np.triu(inv, 1).T


def resistance_matrix(nodes: np.ndarray, mu: float, delta: float, head_radius: float,
                      head_spins: bool, smoothing: float) -> np.ndarray:
    """Generalised resistance R, (3n[+1], 3n[+1]), SI (N s/m, N s, N m s).

    nodes: (n,3) rod nodes, m (node 0 is the head centre if head_radius > 0).
    head_spins: append the head spin rate s as the last generalised velocity.
    """
    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    if head_radius <= 0.0:
        a = lsbt_mobility(nodes, node_tangents(nodes), mu, delta, smoothing)
        return spd_inverse(a, smoothing > 0.0)
    flag = np.ascontiguousarray(nodes[1:])
    a = lsbt_mobility(flag, node_tangents(flag), mu, delta, smoothing)
    c = spd_inverse(a, smoothing > 0.0)
    e0 = nodes[1] - nodes[0]
    axis = e0 / math.sqrt(e0 @ e0)
    H, g = head_flow_operators(flag, nodes[0].copy(), axis, head_radius)
    m3 = flag.shape[0] * 3
    nv = m3 + 3 + (1 if head_spins else 0)
    R = np.zeros((nv, nv))
    CH = c @ H
    R[0:3, 0:3] = sphere_translational_drag(mu, head_radius) * np.eye(3) + H.T @ CH
    R[0:3, 3:3 + m3] = -CH.T
    R[3:3 + m3, 0:3] = -CH
    R[3:3 + m3, 3:3 + m3] = c
    if head_spins:
        Cg = c @ g
        R[0:3, -1] = H.T @ Cg
        R[-1, 0:3] = R[0:3, -1]
        R[3:3 + m3, -1] = -Cg
        R[-1, 3:3 + m3] = -Cg
        R[-1, -1] = sphere_rotational_drag(mu, head_radius) + g @ Cg
    return R
