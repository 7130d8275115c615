"""Numba kernels of the implicit residual of eqn (6) with implicit hydrodynamics, and of its Jacobian.

r(q) = M (q - q_k - h v_k) / h^2 + grad E(q) - P^T G,   G = -Q~ R_ref Q~^T V,
V = P (q - q_k) / h - omega e_s   (node velocities, then the head spin rate s).

Q~ applies the rigid rotation Q (3,3) to every node block (see ``rigid_alignment``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from physics.forces.contact import ContactParams, ContactState, contact_broad_phase, contact_kernel
from physics.elastic.rod_energy import (banded_to_dense, elastic_gradient_kernel, elastic_hessian_banded_kernel,
                                        rod_frames)
from physics.linalg.banded_jacobian import add_banded_drag, add_blocks_to_banded, banded_dirichlet
from physics.model.geometry import nodes_array


@njit(cache=True)
def rotate_node_blocks(y: np.ndarray, Q: np.ndarray, transpose: bool) -> np.ndarray:
    """Apply Q (or Q^T) to each node block y[4i:4i+3] of a DOF-layout vector (4n-1,)."""
    out = y.copy()
    n = (y.shape[0] + 1) // 4
    for i in range(n):
        a, b, c = y[4 * i], y[4 * i + 1], y[4 * i + 2]
        for k in range(3):
            if transpose:
                out[4 * i + k] = Q[0, k] * a + Q[1, k] * b + Q[2, k] * c
            else:
                out[4 * i + k] = Q[k, 0] * a + Q[k, 1] * b + Q[k, 2] * c
    return out


@njit(cache=True)
def generalised_velocity(q: np.ndarray, q_k: np.ndarray, h: float, vdofs: np.ndarray, spin: bool,
                         omega: float, Q: np.ndarray) -> np.ndarray:
    """V = P (q - q_k)/h - omega e_s, node blocks rotated to the reference frame (Q^T v). (nv,)"""
    nv = vdofs.shape[0]
    V = np.empty(nv)
    for a in range(nv):
        V[a] = (q[vdofs[a]] - q_k[vdofs[a]]) / h
    if spin:
        V[nv - 1] -= omega
    n3 = nv - 1 if spin else nv
    for i in range(n3 // 3):
        a, b, c = V[3 * i], V[3 * i + 1], V[3 * i + 2]
        for k in range(3):
            V[3 * i + k] = Q[0, k] * a + Q[1, k] * b + Q[2, k] * c
    return V


@njit(cache=True)
def generalised_force(G_ref: np.ndarray, Q: np.ndarray, vdofs: np.ndarray, spin: bool, nd: int) -> np.ndarray:
    """P^T Q~ G_ref (nd,): generalised forces G_ref (nv,) given in the resistance's reference frame (node blocks,
    then the head's axial torque when the head spins), node blocks rotated by Q (3, 3) to the lab frame and
    scattered to their DOFs. N on positions, N m on the motor twist; zero elsewhere."""
    nv = vdofs.shape[0]
    G = G_ref.copy()
    n3 = nv - 1 if spin else nv
    for i in range(n3 // 3):
        a, b, c = G[3 * i], G[3 * i + 1], G[3 * i + 2]
        for k in range(3):
            G[3 * i + k] = Q[k, 0] * a + Q[k, 1] * b + Q[k, 2] * c
    f = np.zeros(nd)
    for a in range(nv):
        f[vdofs[a]] = G[a]
    return f


@njit(cache=True)
def inertia_force(q: np.ndarray, q_k: np.ndarray, v_k: np.ndarray, h: float, mass: np.ndarray) -> np.ndarray:
    """M (q - q_k - h v_k) / h^2 (ndof,), N / N m: the inertia term of eqn (6) divided by h^2, with the
    arithmetic of ``assemble_residual``."""
    nd = q.shape[0]
    out = np.empty(nd)
    for j in range(nd):
        out[j] = mass[j] * (q[j] - q_k[j] - h * v_k[j]) / (h * h)
    return out


@njit(cache=True)
def assemble_residual(q: np.ndarray, q_k: np.ndarray, v_k: np.ndarray, h: float, mass: np.ndarray,
                      grad: np.ndarray, G_ref: np.ndarray, Q: np.ndarray, vdofs: np.ndarray, spin: bool,
                      prescribed: np.ndarray):
    """Residual r (4n-1,), hydrodynamic generalised force f (4n-1,) and inertia term (4n-1,).

    G_ref: hydrodynamic generalised force in the reference frame (node blocks rotated back by Q).
    Units: N on positions, N m on twists.
    """
    nd = q.shape[0]
    f = generalised_force(G_ref, Q, vdofs, spin, nd)
    inertia = np.empty(nd)
    r = np.empty(nd)
    for j in range(nd):
        inertia[j] = mass[j] * (q[j] - q_k[j] - h * v_k[j]) / (h * h)
        r[j] = inertia[j] + grad[j] - f[j]
    for j in prescribed:
        r[j] = 0.0
    return r, f, inertia


@njit(cache=True)
def block_max_abs(y: np.ndarray, idx: np.ndarray) -> float:
    m = 0.0
    for j in idx:
        v = abs(y[j])
        if v > m:
            m = v
    return m


@njit(cache=True)
def assemble_dense_jacobian(ab: np.ndarray, mass: np.ndarray, h: float, R: np.ndarray, vdofs: np.ndarray) -> np.ndarray:
    """The Newton Jacobian of the residual, J = K + M/h^2 + P^T R P / h, dense (ndof, ndof).

    ab: elastic Hessian K in general-banded storage (21, ndof) (``physics.elastic``); mass (ndof,);
    R (nv, nv) resistance in the lab frame; vdofs (nv,) the DOFs of the generalised velocities
    (prescribed DOFs are the caller's: after any further terms). Same arithmetic, in the same order, as
    ``banded_to_dense`` + diagonal + ``J[np.ix_(vdofs, vdofs)] += R / h`` (bit-identical, one pass).
    """
    nd = ab.shape[1]
    J = banded_to_dense(ab)
    for j in range(nd):
        J[j, j] += mass[j] / (h * h)
    nv = vdofs.shape[0]
    for a in range(nv):
        ia = vdofs[a]
        for b in range(nv):
            J[ia, vdofs[b]] += R[a, b] / h
    return J


class BandedNewtonTerms(NamedTuple):
    """The parts of the banded Newton Jacobian of an RFT step (``step_solvers.BandedNewtonSolver``) that stay fixed
    through the step, at its effective step h (s): M/h^2 (ndof,) kg/s^2 (kg m^2/s^2 on twists), the RFT blocks / h
    (M, 3, 3) N/m of the flagellum nodes from node ``first``, the head's drags / h (translation N/m, spin N m), and
    ``jac_fresh``: always True, the Jacobian is exact at every iteration (the chord loop has no stall to hand back,
    as ``BandedNewtonSolver.on_stall`` refactorises nothing)."""

    mass_h2: np.ndarray
    blocks_h: np.ndarray
    first: int
    head_t: float
    head_r: float
    jac_fresh: bool


@njit(cache=True)
def banded_newton_matrix(q: np.ndarray, frames: tuple, rest: tuple, terms: BandedNewtonTerms, nodes_c: np.ndarray,
                         blocks_c: np.ndarray, prescribed: np.ndarray) -> np.ndarray:
    """The exact Newton Jacobian of an RFT step at q (ndof,), in general-banded storage (21, ndof)
    (ab[10 + i - j, j] = J[i, j], as ``scipy.linalg.solve_banded`` takes it): J = K(q) + M/h^2 + P^T R P / h + the
    contact Hessian blocks that fall inside the band, the prescribed DOFs as identity rows and columns. K: the DER
    elastic Hessian of eqns (5a)-(5c) (``elastic_hessian_banded_kernel``) at the frames (t, d1, d2, ref_twist, m1,
    m2) of q; R: block-diagonal (local RFT and the head's Stokes drag, ``terms``); rest: the 7 rest arrays;
    nodes_c (A, 4), blocks_c (A, 12, 12) N/m: the active contacts at q (none: (0, 4), (0, 12, 12)). Both the Python
    increment (``BandedNewtonSolver.increment``) and the compiled one (``chord_iteration``) build it here."""
    t, d1, d2, rt, m1, m2 = frames
    l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ = rest
    ab = elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ)
    add_banded_drag(ab, terms.mass_h2, terms.blocks_h, terms.first, terms.head_t, terms.head_r)
    add_blocks_to_banded(ab, nodes_c, blocks_c)
    for k in prescribed:
        banded_dirichlet(ab, k)
    return ab


@njit(cache=True)
def rotate_dense_blocks(R: np.ndarray, Q: np.ndarray, spin: bool) -> np.ndarray:
    """Q~ R Q~^T for the block rotation Q~ = diag(Q, ..., Q[, 1]) (the spin entry, if any, last):
    the resistance of a rigidly rotated configuration (``rigid_alignment``). O(9 n^2), no dense products."""
    nv = R.shape[0]
    nb = (nv - 1) // 3 if spin else nv // 3
    out = np.empty_like(R)
    tmp = np.empty_like(R)
    # tmp = R Q~^T (columns of each block rotated)
    for i in range(nv):
        for b in range(nb):
            r0, r1, r2 = R[i, 3 * b], R[i, 3 * b + 1], R[i, 3 * b + 2]
            for k in range(3):
                tmp[i, 3 * b + k] = r0 * Q[k, 0] + r1 * Q[k, 1] + r2 * Q[k, 2]
        if spin:
            tmp[i, nv - 1] = R[i, nv - 1]
    # out = Q~ tmp (rows of each block rotated)
    for j in range(nv):
        for b in range(nb):
            t0, t1, t2 = tmp[3 * b, j], tmp[3 * b + 1, j], tmp[3 * b + 2, j]
            for k in range(3):
                out[3 * b + k, j] = Q[k, 0] * t0 + Q[k, 1] * t1 + Q[k, 2] * t2
        if spin:
            out[nv - 1, j] = tmp[nv - 1, j]
    return out


@njit(cache=True)
def contact_candidates(q: np.ndarray, model: ContactParams, q_start: np.ndarray, pos: np.ndarray,
                       first_step: bool) -> ContactState:
    """A new broad phase at q (ndof,), its boxes padded by twice the largest node move from the step's start
    q_start (at least r0 / 2; none on the first step): the iterates of the step stay that close to it (model =
    ``ContactModel.model``). The step's start takes it at the predictor, ``contact_state_at`` when an iterate
    leaves the boxes."""
    move = 0.0 if first_step else block_max_abs(q - q_start, pos)
    pad = max(0.5 * model.r0, 2.0 * move)
    pairs, head = contact_broad_phase(nodes_array(q), model, pad)
    return ContactState(q.copy(), pad, pairs, head, pairs.shape[0] == 0 and head.shape[0] == 0)


@njit(cache=True)
def contact_state_at(q: np.ndarray, model: ContactParams, cstate: ContactState, q_start: np.ndarray, pos: np.ndarray,
                     first_step: bool) -> ContactState:
    """The contact state valid at q (ndof,): ``cstate`` itself while q stays within half the pad of the broad
    phase's q, else a new broad phase at q (``contact_candidates``)."""
    if block_max_abs(q - cstate.q, pos) > 0.5 * cstate.pad:  # the iterate left the padded boxes
        return contact_candidates(q, model, q_start, pos, first_step)
    return cstate


@njit(cache=True)
def internal_forces_at(q: np.ndarray, frames_old: tuple, rest: tuple, contact_on: bool, model: ContactParams,
                       cstate: ContactState, q_start: np.ndarray, pos: np.ndarray, first_step: bool):
    """``Simulator.internal_forces`` from compiled code: the gradient of the elastic (eqns 5a-5c) and contact
    energies at q (ndof,) N and N m, the frames of q, the contact state (redone when q left the padded
    broad-phase boxes) and the active contacts (energy J, nodes (A, 4), Hessian blocks (A, 12, 12) N/m).

    frames_old = (d1, t, ref_twist) of the step's start; rest = the 7 rest arrays; model, cstate: the
    ``contact.ContactParams`` and ``contact.ContactState`` (placeholders without contact)."""
    d1_old, t_old, rt_old = frames_old
    l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ = rest
    t, d1, d2, rt, m1, m2 = rod_frames(q, d1_old, t_old, rt_old)
    grad = elastic_gradient_kernel(q, d1, d2, rt, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ)
    e_c = 0.0
    nodes_c = np.zeros((0, 4), dtype=np.int64)
    blocks_c = np.zeros((0, 12, 12))
    if contact_on:
        cstate = contact_state_at(q, model, cstate, q_start, pos, first_step)
        if not cstate.none:
            e_c, g_c, nodes_c, blocks_c = contact_kernel(nodes_array(q), cstate.pairs, model.head_radius,
                                                         cstate.head_edges, model.r0, model.eps, model.stiffness)
            if nodes_c.shape[0]:
                for k in range(3):
                    grad[k::4] += g_c[k::3]
    return grad, (t, d1, d2, rt, m1, m2), cstate, e_c, nodes_c, blocks_c


@njit(cache=True)
def forces_converged(r: np.ndarray, grad: np.ndarray, f: np.ndarray, inertia: np.ndarray, pos: np.ndarray,
                     free_twist: np.ndarray, tol: float, f_floor: float, r0: float) -> bool:
    """``Simulator._converged``: the force residual below tol relative to the largest force term, per block."""
    s_pos = max(block_max_abs(grad, pos), block_max_abs(f, pos), block_max_abs(inertia, pos), f_floor)
    if block_max_abs(r, pos) > tol * s_pos:
        return False
    s_tw = max(block_max_abs(grad, free_twist), block_max_abs(f, free_twist), block_max_abs(inertia, free_twist),
               f_floor * r0)
    return block_max_abs(r, free_twist) <= tol * s_tw
