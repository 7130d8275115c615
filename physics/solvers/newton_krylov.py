"""Newton-Krylov solve of one implicit step in the mobility form (no dense factorisation at all).

The implicit step of eqn (6) with the hydrodynamic force implicit in the velocity (``physics.simulator``)
needs the LSBT resistance C = A^{-1} (eqn 9). The direct solver forms it (Cholesky of the mobility A,
its inverse, a dense LU of the Newton Jacobian): ~3 ms per step, paid at every step while the shape
changes (buckling, relaxation). Here the flagellum's forces y (3M,) are unknowns beside q, so only A
itself is needed, as a matrix-vector product (``hydrodynamics``, eqns 8-13):

    r_q(q, y) = M (q - q^ - h v^) / h^2 + grad E(q) + P^T (D V + B_out^T y) = 0     (eqn 6; N, N m)
    r_y(q, y) = sigma (A y - B V) = 0                                            (eqns 8-10; N)

with V = P (q - q^) / h - omega e_s the generalised velocities (node velocities, head spin rate),
B V = u - H U - g s the flagellum velocities minus the head's flow (eqn 10), B_out^T y the forces the
flagellum's Stokeslets put on the nodes and the head (eqns 11-13: -H^T y or, as printed, K y; the
axial torque -g.y), D the head's own drag (eqn 12), and sigma = 8 pi mu 2 delta a scale that gives
r_y the units of a force. At the solution y = C B V: exactly the reduced step's hydrodynamic force.

Newton on (q, y) with the exact Jacobian applied matrix-free,

    J = [[M/h^2 + K(q) + K_c(q) + P^T D P / h,   P^T B_out^T],
         [-sigma B P / h,                        sigma A    ]],

each direction from GMRES (right-preconditioned, Saad & Schultz 1986) to a relative ``GMRES_RTOL``.
The preconditioner is the block factorisation of J with A replaced by its band (entries between nodes at
most ``MOBILITY_BAND_NODES`` apart) in the y-block, the head's flow coupling kept, and the Schur complement
replaced by the banded S = M/h^2 + K + K_c + (D + P_f^T R_loc P_f) / h, R_loc the local resistance of
resistive-force theory (``rft``, Lighthill's coefficients; half-bandwidth 10, contact blocks where they fall
inside the band). Both banded matrices are symmetric and were positive definite at every step measured:
two banded Cholesky factorisations per step (``banded_cholesky``; the LU of ``banded_lu`` where a pivot is
not positive), three banded solves per application.

Prescribed DOFs (the motor's Dirichlet twist) are identity rows and columns, as in the direct solver.
The iteration starts from the BDF predictor for q and, for y, from the cubic through the node forces of the
last four accepted steps (``AdaptiveState.force_start``; the last forces right after a
restart): a third fewer GMRES iterations per step than starting from the last forces (docs/time_integration.md).

The whole iteration of a step (residual, contact, convergence tests, GMRES directions) is one compiled call
(``newton_krylov_loop``); Python only sets up the step's operators (``MobilityStep.begin``).
"""

from __future__ import annotations

import math
import time
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from physics.linalg.banded_jacobian import add_banded_drag, add_blocks_to_banded, banded_dirichlet
from physics.linalg.banded_cholesky import banded_cholesky, banded_cholesky_solve_in_place, lower_band
from physics.linalg.banded_lu import banded_lu, banded_solve
from physics.errors import StepFailed
from physics.model.geometry import nodes_array
from physics.elastic import BANDWIDTH, elastic_hessian_banded_kernel, rod_frames
from physics.solvers.implicit_residual import (assemble_residual, block_max_abs, forces_converged, generalised_velocity,
                                       internal_forces_at)
from physics.hydro.rft import rft_blocks
from physics.forces.contact import ContactParams, ContactState
from physics.forces.step_context import (StepSystem, SystemDescription, active_contacts, compiled_contact_args,
                                         frames_at, step_system)
from physics.integrate.time_integrator import ContractionRate, contraction_update

#: relative residual reduction asked of GMRES for each Newton direction
GMRES_RTOL = 1e-4
#: the preconditioner keeps the mobility's entries between nodes at most this many apart
MOBILITY_BAND_NODES = 3
#: Krylov iterations before a direction is given up (the step then fails and is retried shorter)
GMRES_MAX_ITER = 60


_EYE = np.eye(3)


class KrylovFailed(Exception):
    """GMRES did not reach its tolerance (the caller turns it into a failed step)."""


@njit(cache=True)
def banded_matvec_add(ab: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """out += A v for A in general-banded storage ab (2 bw + 1, n), ab[bw + i - j, j] = A[i, j] (terms with
    v[j] = 0 are skipped). One stored diagonal at a time (contiguous rows of ab), the lowest first, so that each
    out[i] receives its terms in the order of increasing j, as a column-by-column product would add them."""
    bw = (ab.shape[0] - 1) // 2
    n = ab.shape[1]
    for r in range(2 * bw, -1, -1):
        off = r - bw  # the diagonal i = j + off
        lo, hi = max(0, -off), min(n, n - off)
        o, row, vs = out[lo + off:hi + off], ab[r, lo:hi], v[lo:hi]
        for j in range(hi - lo):  # a select, not a branch: the loop vectorises (~5x faster)
            vj = vs[j]
            s = o[j] + row[j] * vj
            o[j] = s if vj != 0.0 else o[j]


@njit(cache=True)
def contact_matvec_add(nodes: np.ndarray, blocks: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """out += K_c v for contact Hessian blocks (A, 12, 12) over node quadruples (A, 4), DOF layout (stride 4)."""
    for a in range(nodes.shape[0]):
        for p in range(4):
            for k in range(3):
                acc = 0.0
                for q in range(4):
                    for m in range(3):
                        acc += blocks[a, 3 * p + k, 3 * q + m] * v[4 * nodes[a, q] + m]
                out[4 * nodes[a, p] + k] += acc


@njit(cache=True)
def preconditioner_band(ab: np.ndarray, mass: np.ndarray, h: float, rloc: np.ndarray, first: int,
                        head_t: float, head_r: float, nodes: np.ndarray, blocks: np.ndarray,
                        prescribed: np.ndarray) -> np.ndarray:
    """S = K + M/h^2 + (D + R_loc)/h (+ the contact blocks inside the band), prescribed DOFs as identity, in
    the general-banded storage of ``ab`` (2 bw + 1, n), band[bw + i - j, j] = S[i, j]. Symmetric.

    ab: elastic Hessian (2 bw + 1, n); rloc (M, 3, 3) N s/m for the flagellum nodes, the first of which is
    node ``first``; head_t, head_r: head drag N s/m and N m s (0 without a head / spin)."""
    band = ab.copy()
    add_banded_drag(band, mass / (h * h), rloc / h, first, head_t / h, head_r / h)
    add_blocks_to_banded(band, nodes, blocks)
    for k in prescribed:
        banded_dirichlet(band, k)
    return band


@njit(cache=True)
def factor_symmetric_band(band: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Factorise the symmetric banded matrix in general-banded storage (2 bw + 1, n): Cholesky
    (``banded_cholesky``; pivots of length 0) where it is positive definite, else the partial-pivoting LU of
    ``banded_lu``. Returns (factor, pivots, info); solve with ``factor_solve``."""
    bw = (band.shape[0] - 1) // 2
    n = band.shape[1]
    c = np.ascontiguousarray(band[bw:, :].T)
    if banded_cholesky(c, bw) == 0:
        return c, np.zeros(0, dtype=np.int64), 0
    s = np.zeros((n, 3 * bw + 1))
    s[:, bw:] = band.T
    piv, info = banded_lu(s, bw, bw)
    return s, piv, info


@njit(cache=True)
def factor_mobility_band(A: np.ndarray, bw: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Factorise the entries of the symmetric mobility A (n, n) within bw of the diagonal, as
    ``factor_symmetric_band`` does."""
    c = lower_band(A, bw)
    if banded_cholesky(c, bw) == 0:
        return c, np.zeros(0, dtype=np.int64), 0
    s = band_of(A, bw)
    piv, info = banded_lu(s, bw, bw)
    return s, piv, info


@njit(cache=True)
def factor_solve(f: np.ndarray, piv: np.ndarray, bw: int, b: np.ndarray) -> np.ndarray:
    """x = S^{-1} b for a factor of ``factor_symmetric_band`` / ``factor_mobility_band`` (half-bandwidth bw)."""
    x = b.copy()
    factor_solve_in_place(f, piv, bw, x)
    return x


@njit(cache=True)
def factor_solve_in_place(f: np.ndarray, piv: np.ndarray, bw: int, x: np.ndarray) -> None:
    """x <- S^{-1} x, as ``factor_solve`` (in place for the Cholesky factor; the LU's solve allocates)."""
    if piv.shape[0] == 0:
        banded_cholesky_solve_in_place(f, bw, x)
    else:
        x[:] = banded_solve(f, bw, bw, piv, x)


@njit(cache=True)
def preconditioner_factors(q: np.ndarray, frames_old: tuple, rest: tuple, mass: np.ndarray, h: float,
                           zeta_perp: float, zeta_par: float, first: int, head_t: float, head_r: float,
                           nodes_c: np.ndarray, blocks_c: np.ndarray, prescribed: np.ndarray, A: np.ndarray,
                           abw: int):
    """The preconditioner of a step at the predictor q, compiled: the elastic Hessian at q (ab, banded), the
    factor of S (``preconditioner_band``; local RFT drag with Lighthill's coefficients zeta N s/m^2) and
    that of the mobility's band within abw of the diagonal (``factor_symmetric_band``: Cholesky, or LU where a
    pivot is not positive). Returns (ab, (lu, piv, info), (alu, apiv, ainfo)): info / ainfo = j + 1 if the
    LU's pivot j is zero."""
    d1_old, t_old, rt_old = frames_old
    l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ = rest
    x = nodes_array(q)
    rloc = rft_blocks(np.ascontiguousarray(x[first:]), zeta_perp, zeta_par)
    t, d1, d2, rt, m1, m2 = rod_frames(q, d1_old, t_old, rt_old)
    ab = elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ)
    lu, piv, info = factor_symmetric_band(preconditioner_band(ab, mass, h, rloc, first, head_t, head_r, nodes_c,
                                                              blocks_c, prescribed))
    alu, apiv, ainfo = factor_mobility_band(A, abw)
    return ab, (lu, piv, info), (alu, apiv, ainfo)


@njit(cache=True)
def band_of(A: np.ndarray, bw: int) -> np.ndarray:
    """The entries of the dense A (n, n) within bw of the diagonal, in the storage of ``banded_lu``."""
    n = A.shape[0]
    s = np.zeros((n, 3 * bw + 1))
    for j in range(n):
        for i in range(max(0, j - bw), min(n, j + bw + 1)):
            s[j, 2 * bw + i - j] = A[i, j]
    return s


@njit(cache=True)
def head_flow_apply(V: np.ndarray, H: np.ndarray, g: np.ndarray, has_head: bool, spin: bool) -> np.ndarray:
    """B V = u - H U - g s (3M,), m/s: the flagellum's velocities minus the head's flow (eqn 10)."""
    out = np.empty(H.shape[0] if has_head else V.shape[0])
    head_flow_apply_into(V, H, g, has_head, spin, out)
    return out


@njit(cache=True)
def head_flow_apply_into(V: np.ndarray, H: np.ndarray, g: np.ndarray, has_head: bool, spin: bool,
                         out: np.ndarray) -> None:
    """out (3M,) <- B V, as ``head_flow_apply``."""
    if not has_head:
        out[:] = V
        return
    s = V[V.shape[0] - 1] if spin else 0.0
    for i in range(out.shape[0]):
        out[i] = V[3 + i] - (H[i, 0] * V[0] + H[i, 1] * V[1] + H[i, 2] * V[2]) - g[i] * s


@njit(cache=True)
def drag_and_coupling(V: np.ndarray, y: np.ndarray, Kh: np.ndarray, g: np.ndarray, drag_t: float,
                      drag_r: float, has_head: bool, spin: bool) -> np.ndarray:
    """D V + B_out^T y (nv,): minus the hydrodynamic generalised force for flagellum forces y (3M,) N: the
    head's own drag (eqn 12), the Stokeslets' force on the head Kh y (eqn 11; Kh = -H^T, or K as printed),
    the flagellum forces, the axial torque -g.y (eqn 13)."""
    out = np.empty(V.shape[0])
    drag_and_coupling_into(V, y, Kh, g, drag_t, drag_r, has_head, spin, out)
    return out


@njit(cache=True)
def drag_and_coupling_into(V: np.ndarray, y: np.ndarray, Kh: np.ndarray, g: np.ndarray, drag_t: float,
                           drag_r: float, has_head: bool, spin: bool, out: np.ndarray) -> None:
    """out (nv,) <- D V + B_out^T y, as ``drag_and_coupling``."""
    nv = V.shape[0]
    if not has_head:
        out[:] = y
        return
    m3 = y.shape[0]
    for k in range(3):
        acc = 0.0
        for i in range(m3):
            acc += Kh[k, i] * y[i]
        out[k] = drag_t * V[k] + acc
    out[3:3 + m3] = y
    if spin:
        acc = 0.0
        for i in range(m3):
            acc += g[i] * y[i]
        out[nv - 1] = drag_r * V[nv - 1] - acc


@njit(cache=True)
def krylov_workspace(nd: int, m3: int, nv: int, max_iter: int) -> tuple:
    """The arrays ``krylov_direction``, ``jacobian_vector`` and ``precondition`` work in, allocated once per step
    for nd DOFs, 3M flagellum forces, nv generalised velocities and at most ``max_iter`` GMRES iterations:
    (V (max_iter + 1, n), Z (max_iter, n), Hm (max_iter + 1, max_iter), cs, sn (max_iter,), gv (max_iter + 1,),
    w (n,), then v (nd,), vel, c, zero (nv,), am, hf, t (3M,)), n = nd + 3M; zero stays 0."""
    n = nd + m3
    return (np.empty((max_iter + 1, n)), np.empty((max_iter, n)), np.empty((max_iter + 1, max_iter)),
            np.empty(max_iter), np.empty(max_iter), np.empty(max_iter + 1), np.empty(n),
            np.empty(nd), np.empty(nv), np.empty(nv), np.zeros(nv), np.empty(m3), np.empty(m3), np.empty(m3))


@njit(cache=True)
def jacobian_vector(z: np.ndarray, out: np.ndarray, work: tuple, nd: int, vdofs: np.ndarray,
                    prescribed: np.ndarray, mass_h2: np.ndarray, ab: np.ndarray, cnodes: np.ndarray,
                    cblocks: np.ndarray, h: float, sigma: float, A: np.ndarray, H: np.ndarray, g: np.ndarray,
                    Kh: np.ndarray, drag_t: float, drag_r: float, has_head: bool, spin: bool) -> None:
    """out <- J z for the stacked vector z = (dq (nd,), dy (3M,)) (see the module doc for J); work from
    ``krylov_workspace``."""
    v, V, c, am, hf = work[7], work[8], work[9], work[11], work[12]
    w = z[nd:]
    v[:] = z[:nd]
    for k in prescribed:
        v[k] = 0.0
    oq = out[:nd]
    for i in range(nd):
        oq[i] = mass_h2[i] * v[i]
    banded_matvec_add(ab, v, oq)
    if cnodes.shape[0]:
        contact_matvec_add(cnodes, cblocks, v, oq)
    nv = vdofs.shape[0]
    for a in range(nv):
        V[a] = v[vdofs[a]] / h
    drag_and_coupling_into(V, w, Kh, g, drag_t, drag_r, has_head, spin, c)
    for a in range(nv):
        oq[vdofs[a]] += c[a]
    for k in prescribed:
        oq[k] = z[k]
    np.dot(A, w, am)
    head_flow_apply_into(V, H, g, has_head, spin, hf)
    for i in range(am.shape[0]):
        out[nd + i] = sigma * (am[i] - hf[i])


@njit(cache=True)
def precondition(z: np.ndarray, out: np.ndarray, work: tuple, nd: int, vdofs: np.ndarray, prescribed: np.ndarray,
                 lu: np.ndarray, piv: np.ndarray, alu: np.ndarray, apiv: np.ndarray, abw: int, h: float,
                 sigma: float, H: np.ndarray, g: np.ndarray, Kh: np.ndarray, has_head: bool, spin: bool) -> None:
    """out <- ~J^{-1} z: the block factorisation of J with A replaced by its band (``alu``: factor of the entries
    within ``abw`` of the diagonal) and the Schur complement by the banded S (``lu``); work from
    ``krylov_workspace``."""
    V, c, zero, hf, t = work[8], work[9], work[10], work[12], work[13]
    a = z[:nd]
    t[:] = z[nd:]
    factor_solve_in_place(alu, apiv, abw, t)
    for i in range(t.shape[0]):
        t[i] = t[i] / sigma
    nv = vdofs.shape[0]
    drag_and_coupling_into(zero, t, Kh, g, 0.0, 0.0, has_head, spin, c)
    x = out[:nd]
    x[:] = a
    for i in range(nv):
        x[vdofs[i]] -= c[i]
    for k in prescribed:
        x[k] = a[k]
    factor_solve_in_place(lu, piv, BANDWIDTH, x)
    for i in range(nv):
        V[i] = x[vdofs[i]] / h
    for k in prescribed:  # prescribed DOFs have no velocity in J's columns
        for i in range(nv):
            if vdofs[i] == k:
                V[i] = 0.0
    head_flow_apply_into(V, H, g, has_head, spin, hf)
    factor_solve_in_place(alu, apiv, abw, hf)
    for i in range(t.shape[0]):
        out[nd + i] = t[i] + hf[i]


@njit(cache=True)
def krylov_direction(b: np.ndarray, rtol: float, max_iter: int, work: tuple, nd: int, vdofs: np.ndarray,
                     prescribed: np.ndarray, mass_h2: np.ndarray, ab: np.ndarray, cnodes: np.ndarray,
                     cblocks: np.ndarray, h: float, sigma: float, A: np.ndarray, H: np.ndarray, g: np.ndarray,
                     Kh: np.ndarray, drag_t: float, drag_r: float, has_head: bool, spin: bool, lu: np.ndarray,
                     piv: np.ndarray, alu: np.ndarray, apiv: np.ndarray, abw: int) -> tuple[np.ndarray, int, float]:
    """J^{-1} b by right-preconditioned GMRES (Saad & Schultz 1986; modified Gram-Schmidt, Givens rotations)
    from 0, no restart, to ||b - J x|| <= rtol ||b||, in the arrays of ``work`` (``krylov_workspace`` for at
    least ``max_iter`` iterations). Returns (x, iterations, reached relative residual): iterations = -1 if
    ``max_iter`` did not reach rtol."""
    n = b.shape[0]
    beta = math.sqrt(b @ b)
    if beta == 0.0:
        return np.zeros(n), 0, 0.0
    V, Z, Hm, cs, sn, gv, w = work[:7]  # every entry read below is written first in this call
    gv[0] = beta
    for j in range(n):
        V[0, j] = b[j] / beta
    target = rtol * beta
    for k in range(max_iter):
        precondition(V[k], Z[k], work, nd, vdofs, prescribed, lu, piv, alu, apiv, abw, h, sigma, H, g, Kh,
                     has_head, spin)
        jacobian_vector(Z[k], w, work, nd, vdofs, prescribed, mass_h2, ab, cnodes, cblocks, h, sigma, A, H, g, Kh,
                        drag_t, drag_r, has_head, spin)
        for i in range(k + 1):
            hik = w @ V[i]
            Hm[i, k] = hik
            for j in range(n):
                w[j] -= hik * V[i, j]
        hn = math.sqrt(w @ w)
        Hm[k + 1, k] = hn
        breakdown = hn <= 1e-14 * beta  # the Krylov space holds the solution
        if not breakdown:
            for j in range(n):
                V[k + 1, j] = w[j] / hn
        for i in range(k):
            t = cs[i] * Hm[i, k] + sn[i] * Hm[i + 1, k]
            Hm[i + 1, k] = -sn[i] * Hm[i, k] + cs[i] * Hm[i + 1, k]
            Hm[i, k] = t
        r = math.hypot(Hm[k, k], Hm[k + 1, k])
        cs[k] = Hm[k, k] / r
        sn[k] = Hm[k + 1, k] / r
        Hm[k, k] = r
        Hm[k + 1, k] = 0.0
        gv[k + 1] = -sn[k] * gv[k]
        gv[k] = cs[k] * gv[k]
        if abs(gv[k + 1]) <= target or breakdown:
            m = k + 1
            yk = np.zeros(m)
            for i in range(m - 1, -1, -1):  # back substitution with the triangular Hessenberg factor
                acc = gv[i]
                for j in range(i + 1, m):
                    acc -= Hm[i, j] * yk[j]
                yk[i] = acc / Hm[i, i]
            x = np.zeros(n)
            for i in range(m):
                for j in range(n):
                    x[j] += yk[i] * Z[i, j]
            return x, m, abs(gv[k + 1]) / beta
    return np.zeros(n), -1, abs(gv[max_iter]) / beta


class MobilityHydro(NamedTuple):
    """The mobility form's operators of a step (``MobilityStep.begin``): the mobility a (3M, 3M) m/(N s), the
    head's flow H (3M, 3), spin flow g (3M,) and force map Kh (3, 3M), its drags (N s/m, N m s), the head flags and
    the scale sigma of the mobility rows (Pa s m)."""

    a: np.ndarray
    H: np.ndarray
    g: np.ndarray
    Kh: np.ndarray
    drag_t: float
    drag_r: float
    has_head: bool
    spin: bool
    sigma: float


class Preconditioner(NamedTuple):
    """The banded preconditioner's factors (``preconditioner_factors``): LU and pivots of the position-twist band,
    LU and pivots of the mobility band, and the mobility band's half width."""

    lu: np.ndarray
    piv: np.ndarray
    alu: np.ndarray
    apiv: np.ndarray
    abw: int


class KrylovTols(NamedTuple):
    """The Newton-Krylov iteration's tolerances (``NumericsConfig``) and GMRES's (relative tolerance, iteration
    limit); f_floor N, r0 m."""

    newton_tol: float
    max_iter: int
    step_tol: float
    f_floor: float
    r0: float
    gmres_rtol: float
    gmres_max_iter: int


class KrylovRate(NamedTuple):
    """The Newton-Krylov ``ContractionRate``: rho and the age in steps."""

    rho: float
    age: int


@njit(cache=True)
def mobility_residual(q: np.ndarray, y: np.ndarray, h: float, grad: np.ndarray, base: tuple, system: StepSystem,
                      hydro: MobilityHydro):
    """(r_q (ndof,) N / N m, r_y (3M,) N, f (ndof,), inertia (ndof,)) at (q, y) for the internal forces grad
    (module doc). base = (q^, v^, h_e)."""
    q_hat, v_hat, h_eff = base
    mass, vdofs, prescribed, head_spins, omega = (system.mass, system.vdofs, system.prescribed, system.head_spins,
                                                  system.omega)
    A, H, g, Kh, drag_t, drag_r, has_head, spin, sigma = (hydro.a, hydro.H, hydro.g, hydro.Kh, hydro.drag_t,
                                                          hydro.drag_r, hydro.has_head, hydro.spin, hydro.sigma)
    V = generalised_velocity(q, q_hat, h, vdofs, head_spins, omega, _EYE)
    G = -drag_and_coupling(V, y, Kh, g, drag_t, drag_r, has_head, spin)
    r, f, inertia = assemble_residual(q, q_hat, v_hat, h_eff, mass, grad, G, _EYE, vdofs, head_spins, prescribed)
    r_y = sigma * (A @ y - head_flow_apply(V, H, g, has_head, spin))
    return r, r_y, f, inertia


#: outcome codes of ``newton_krylov_loop``
CONVERGED, NONFINITE_RESIDUAL, KRYLOV_FAILED, NEWTON_FAILED = 0, 1, 2, 3


@njit(cache=True)
def newton_krylov_loop(q: np.ndarray, y: np.ndarray, h: float, q_start: np.ndarray, frames_old: tuple, rest: tuple,
                       base: tuple, system: StepSystem, hydro: MobilityHydro, contact_on: bool, model: ContactParams,
                       cstate: ContactState, first_step: bool, precond: Preconditioner, ab0: np.ndarray,
                       tols: KrylovTols, rate: KrylovRate, work: tuple):
    """The Newton-Krylov iteration of one step, entirely compiled: from (q, y) (the predictor and the last
    forces), each iteration the residual, the convergence tests, a GMRES direction with the Jacobian at the
    iterate (the elastic Hessian ab0 at the predictor is reused for the first), the update.

    system, hydro, precond, tols and rate (the ``ContractionRate``, used when step_tol > 0): the named tuples
    above; work = GMRES's arrays (``krylov_workspace`` for at least the
    iteration limit; the caller keeps them from step to step). Returns (code, q, y, r, grad, f, frames, cstate, (contact
    energy, count), (residuals evaluated in the loop, GMRES iterations), (rho, age), value): value = the GMRES
    relative residual reached (KRYLOV_FAILED) or the max force residual (NEWTON_FAILED)."""
    mass, vdofs, prescribed, pos, twist, free_twist, weights = (system.mass, system.vdofs, system.prescribed,
                                                                system.pos, system.twist, system.free_twist,
                                                                system.weights)
    A, H, g, Kh, drag_t, drag_r, has_head, spin, sigma = (hydro.a, hydro.H, hydro.g, hydro.Kh, hydro.drag_t,
                                                          hydro.drag_r, hydro.has_head, hydro.spin, hydro.sigma)
    lu, piv, alu, apiv, abw = precond.lu, precond.piv, precond.alu, precond.apiv, precond.abw
    newton_tol, max_iter, step_tol, f_floor, r0, gmres_rtol, gmres_max_iter = (
        tols.newton_tol, tols.max_iter, tols.step_tol, tols.f_floor, tols.r0, tols.gmres_rtol, tols.gmres_max_iter)
    rho, age = rate.rho, rate.age
    nd = q.shape[0]
    l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ = rest
    mass_h2 = mass / (h * h)
    step_scale = max(block_max_abs(q - q_start, pos), 1e-6 * r0)
    adaptive = step_tol > 0.0
    prev = -1.0  # the last correction's size (ContractionRate), none yet
    if adaptive:
        age += 1
    evaluated = 0
    krylov_its = 0
    q = q.copy()
    y = y.copy()
    grad, fr, cstate, e_c, nodes_c, blocks_c = internal_forces_at(q, frames_old, rest, contact_on, model, cstate,
                                                                  q_start, pos, first_step)
    r, r_y, f, inertia = mobility_residual(q, y, h, grad, base, system, hydro)
    for it in range(max_iter):
        evaluated += 1
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(r_y))):
            return (NONFINITE_RESIDUAL, q, y, r, grad, f, fr, cstate, (e_c, nodes_c.shape[0]),
                    (evaluated, krylov_its), (rho, age), 0.0)
        y_scale = max(np.abs(f).max(), f_floor)
        if (forces_converged(r, grad, f, inertia, pos, free_twist, newton_tol, f_floor, r0)
                and np.abs(r_y).max() <= newton_tol * y_scale):
            return (CONVERGED, q, y, r, grad, f, fr, cstate, (e_c, nodes_c.shape[0]), (evaluated, krylov_its),
                    (rho, age), 0.0)
        t, d1, d2, rt, m1, m2 = fr
        ab = ab0 if it == 0 else elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, l_bar, l_vor, kappa_bar,
                                                               twist_bar, EA, EI, GJ)
        rhs = np.concatenate((r, r_y))
        z, its, reached = krylov_direction(rhs, gmres_rtol, gmres_max_iter, work, nd, vdofs, prescribed, mass_h2,
                                           ab, nodes_c, blocks_c, h, sigma, A, H, g, Kh, drag_t, drag_r, has_head,
                                           spin, lu, piv, alu, apiv, abw)
        if its < 0:
            return (KRYLOV_FAILED, q, y, r, grad, f, fr, cstate, (e_c, nodes_c.shape[0]), (evaluated, krylov_its),
                    (rho, age), reached)
        krylov_its += its
        dq = z[:nd]
        q = q - dq
        y = y - z[nd:]
        dz = block_max_abs(dq, pos)
        converged = (it >= 1 and dz <= max(newton_tol * step_scale, 1e-10 * r0)
                     and block_max_abs(dq, twist) <= max(newton_tol, 1e-10))
        if adaptive and not converged:  # ContractionRate.converged
            converged, rho, prev, age = contraction_update(np.max(np.abs(dq) * weights) / step_tol, rho, prev, age)
        grad, fr, cstate, e_c, nodes_c, blocks_c = internal_forces_at(q, frames_old, rest, contact_on, model,
                                                                      cstate, q_start, pos, first_step)
        r, r_y, f, inertia = mobility_residual(q, y, h, grad, base, system, hydro)
        if converged:
            return (CONVERGED, q, y, r, grad, f, fr, cstate, (e_c, nodes_c.shape[0]), (evaluated, krylov_its),
                    (rho, age), 0.0)
    return (NEWTON_FAILED, q, y, r, grad, f, fr, cstate, (e_c, nodes_c.shape[0]), (evaluated, krylov_its),
            (rho, age), np.abs(r).max())

class MobilityStep:
    """The mobility-form system of one step: the resistance operator's pieces (A, H, g, head drag) at the
    predicted geometry, the local resistance and the banded preconditioner. Built by ``begin``;
    ``solve`` runs the Newton-Krylov iteration from the predictor (one compiled call). ``system``: the
    ``step_context.SystemDescription``; ``state``: the stepped object (``step_solvers.StepState``: the step's
    ``StepContext``, the kept contact state, the counters)."""

    def __init__(self, system: SystemDescription, state: Any, rloc_coefficients: tuple[float, float]) -> None:
        self.system, self.state = system, state
        p = system.params
        self.zeta = rloc_coefficients
        self.first = 1 if p.has_head else 0
        self.sigma = 8.0 * math.pi * p.viscosity * 2.0 * p.cutoff_length
        self.hyd = None
        self._work: tuple | None = None  # GMRES's arrays (``krylov_workspace``), kept from step to step
        self.contraction = ContractionRate()  # the Newton iteration's convergence test (adaptive steps)

    def begin(self, hyd: Any, q_pred: np.ndarray, h: float) -> None:
        """Take the resistance operator ``hyd`` (built at q_pred) and factorise the preconditioner at q_pred, h."""
        system, ctx = self.system, self.state.step_context(h)
        self.hyd = hyd
        t0 = time.perf_counter()
        m3 = hyd.m3
        if hyd.has_head:
            self.H, self.g = hyd.H, (hyd.g if hyd.spin else np.zeros(m3))
            self.Kh = np.ascontiguousarray(hyd.K if hyd.printed else -hyd.H.T)
            self.drag_t, self.drag_r = hyd.drag_t, (hyd.drag_r if hyd.spin else 0.0)
        else:
            self.H, self.g, self.Kh = np.zeros((m3, 3)), np.zeros(m3), np.zeros((3, m3))
            self.drag_t = self.drag_r = 0.0
        nodes_c, blocks_c = active_contacts(q_pred, ctx, system)
        self.abw = 3 * MOBILITY_BAND_NODES + 2
        self.ab, (self.lu, self.piv, info), (self.alu, self.apiv, ainfo) = preconditioner_factors(
            q_pred, ctx.frames, system.rest, system.mass, h, *self.zeta, self.first,
            self.drag_t, self.drag_r, nodes_c, blocks_c, system.prescribed, hyd.a, self.abw)
        if info != 0:
            raise KrylovFailed(f"banded preconditioner is singular (pivot {info} is zero)")
        if ainfo != 0:
            raise KrylovFailed(f"banded mobility of the preconditioner is singular (pivot {ainfo} is zero)")
        self.h = h
        self.state.stats.preconditioner_factorisations += 1
        self.state.stats.time_jacobian_refresh += time.perf_counter() - t0

    def residual(self, q: np.ndarray, y: np.ndarray, h: float):
        """(r_q (ndof,) N / N m, r_y (3M,) N, grad (ndof,), f (ndof,), inertia (ndof,), frames (t, d1, ref_twist))
        at (q, y); keeps the contact state (a Python reference of ``newton_krylov_loop``'s residual)."""
        system, ctx = self.system, self.state.step_context(h)
        contact_on, model, cstate = compiled_contact_args(q, ctx, system)
        grad, fr, cstate, e_c, nodes_c, _ = internal_forces_at(q, ctx.frames, system.rest, contact_on, model, cstate,
                                                               ctx.q_start, system.pos, ctx.first_step)
        self.state.keep_contact_state(cstate, e_c, nodes_c.shape[0])
        r, r_y, f, inertia = mobility_residual(q, y, h, grad, self._base(ctx), self._system(ctx), self._hydro())
        t, d1, d2, rt, m1, m2 = fr
        return r, r_y, grad, f, inertia, (t, d1, rt)

    @staticmethod
    def _base(ctx) -> tuple:
        return ctx.q_hat, ctx.v_hat, ctx.h

    def _system(self, ctx) -> StepSystem:
        return step_system(self.system, ctx.omega)

    def _hydro(self) -> MobilityHydro:
        hyd = self.hyd
        return MobilityHydro(a=hyd.a, H=self.H, g=self.g, Kh=self.Kh, drag_t=self.drag_t, drag_r=self.drag_r,
                             has_head=hyd.has_head, spin=hyd.spin, sigma=self.sigma)

    def _jacobian_arrays(self, q: np.ndarray, h: float) -> tuple:
        system, hyd, ctx = self.system, self.hyd, self.state.step_context(h)
        t, d1, d2, rt, m1, m2 = frames_at(q, ctx)
        ab = elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, *system.rest)
        nodes_c, blocks_c = active_contacts(q, ctx, system)
        return (q.size, system.vdofs, system.prescribed, system.mass / (h * h), ab, nodes_c, blocks_c, h, self.sigma,
                hyd.a, self.H, self.g, self.Kh, self.drag_t, self.drag_r, hyd.has_head, hyd.spin)

    def workspace(self, max_iter: int) -> tuple:
        """The kept ``krylov_workspace`` (made anew when the sizes change or more iterations are asked)."""
        sizes = (self.system.ndof, self.hyd.m3, self.system.vdofs.size)
        w = self._work
        if w is None or (w[7].size, w[11].size, w[8].size) != sizes or w[1].shape[0] < max_iter:
            w = self._work = krylov_workspace(*sizes, max_iter)
        return w

    def jacobian_vector(self, q: np.ndarray, h: float, z: np.ndarray) -> np.ndarray:
        """J z at q (the elastic and contact Hessians at q) for z = (dq (ndof,), dy (3M,))."""
        out = np.empty_like(z)
        jacobian_vector(z, out, self.workspace(GMRES_MAX_ITER), *self._jacobian_arrays(q, h))
        return out

    def direction(self, q: np.ndarray, h: float, rhs: np.ndarray, rtol: float = GMRES_RTOL,
                  max_iter: int = GMRES_MAX_ITER) -> tuple[np.ndarray, int, float]:
        """GMRES for J z = rhs at q: (z, iterations (-1: not converged), relative residual reached)."""
        return krylov_direction(rhs, rtol, max_iter, self.workspace(max_iter), *self._jacobian_arrays(q, h),
                                self.lu, self.piv, self.alu, self.apiv, self.abw)

    def solve(self, q: np.ndarray, y: np.ndarray, h: float):
        """Newton-Krylov from (q, y), one compiled call (``newton_krylov_loop``): (q, r, grad, f, frames) at
        convergence; ``StepFailed`` otherwise. Updates the stepped object's contact state and counters."""
        system, state = self.system, self.state
        nm, p = system.numerics, system.params
        ctx = state.step_context(h)
        contact_on, model, cstate = compiled_contact_args(q, ctx, system)
        rate = self.contraction
        code, q, y, r, grad, f, frames, cstate, (e_c, count), (evaluated, its), (rate.rho, rate.age), value = (
            newton_krylov_loop(q, y, h, ctx.q_start, ctx.frames, system.rest,
                               self._base(ctx), self._system(ctx), self._hydro(), contact_on, model, cstate,
                               ctx.first_step,
                               Preconditioner(lu=self.lu, piv=self.piv, alu=self.alu, apiv=self.apiv, abw=self.abw),
                               self.ab,
                               KrylovTols(newton_tol=nm.newton_tol, max_iter=nm.newton_max_iter, step_tol=nm.step_tol,
                                          f_floor=system.f_floor, r0=p.rod_radius, gmres_rtol=GMRES_RTOL,
                                          gmres_max_iter=GMRES_MAX_ITER),
                               KrylovRate(rho=rate.rho, age=rate.age), self.workspace(GMRES_MAX_ITER)))
        state.stats.newton_iterations += evaluated
        state.stats.krylov_iterations += its
        state.keep_contact_state(cstate, e_c, count)
        if code == NONFINITE_RESIDUAL:
            raise StepFailed("residual", "non-finite (NaN/inf) force residual")
        if code == KRYLOV_FAILED:
            raise StepFailed("Newton-Krylov", f"GMRES reached {value:.2e} of the initial residual after "
                                              f"{GMRES_MAX_ITER} iterations (asked {GMRES_RTOL:g})")
        if code == NEWTON_FAILED:
            raise StepFailed("Newton", f"Newton-Krylov did not converge after {nm.newton_max_iter} iterations "
                                       f"(max force residual {value:.3e})")
        t, d1, d2, rt, m1, m2 = frames
        return q, r, grad, f, (t, d1, rt)
