"""The chord iteration of a step, compiled end to end (one Numba call per step attempt): the dense LSBT chord
iteration and the banded Newton iteration of RFT, one loop.

Each step solves the implicit residual of eqn (6) (Huang & Jawed 2020; ``implicit_residual``) by
q <- q - J^{-1} r(q) (with ``single_iteration``: one such solve from the predictor). ``chord_loop`` is that
iteration in one compiled call; its Python reference, one kernel call per piece with the same operations in the same
order, is tests/physics/chord_reference.py (bit-identical iterates). Two solvers plug into it (``step_solvers``),
chosen at compile time by the type of its ``hydro`` and ``lin`` arguments (``hydro_force`` and ``newton_increment``:
one compiled variant of the loop per solver, no placeholders):

* LSBT (``DenseChordSolver``; ``ChordHydro``, ``ChordLinear``): while the hydrodynamic resistance is reused through
  a rigid rotation (steady swimming), the chord iteration on the reused dense LU of J = M/h^2 + K + P^T R P / h,
  its node blocks rotated by the best-fit rotation Qj (``rigid_alignment``). The hydrodynamic force -R V in the
  resistance's reference frame (``resistance_apply``, the arithmetic of ``ResistanceOperator.apply``: NumPy's own
  dgemv / ddot and SciPy's dpotrs, ``compiled_lapack``); the increment: LAPACK dgetrs on the kept LU
  (``compiled_lapack.getrs``) between the rotations by Qj. Where NumPy has no bundled OpenBLAS the products are
  Numba's (``compiled_lapack.NUMPY_BLAS``): the same up to rounding.
* RFT (``BandedNewtonSolver``; ``LocalDrag``, ``implicit_residual.BandedNewtonTerms``): local drag, so R is
  block-diagonal (``rft.local_drag_apply``) and the exact Jacobian at every iterate is banded
  (``implicit_residual.banded_newton_matrix``: elastic Hessian of eqns (5a)-(5c), M/h^2, RFT blocks / h, the contact
  blocks inside the band, Dirichlet rows), solved by LAPACK dgbsv on the array ``scipy.linalg.solve_banded`` builds
  (``compiled_lapack.gbsv``): a Newton iteration, no stall, no factorisation kept.

Common to both: the residual (frames, elastic and contact forces with the contact broad-phase redo,
``internal_forces_at``; the hydrodynamic force; ``assemble_residual``); the tests: the force residual
(``forces_converged``), the stall test, the increment criterion, CVODE's contraction-rate test
(``time_integrator.ContractionRate``).

Python acts only where the iteration does something other than arithmetic (LSBT only): a stall (the
Jacobian is refactorised, ``DenseChordSolver.on_stall``) and the moment the resistance operator forms its explicit
inverse (``ResistanceOperator.inverse``, after ``INVERSE_AFTER_SOLVES`` Cholesky solves); the loop returns there
and ``chord_solve`` resumes it where it stopped (``phase``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit, types
from numba.extending import overload

from physics.elastic import BANDWIDTH
from physics.linalg.compiled_lapack import gbsv, getrs, numpy_dot, numpy_matvec, potrs_upper
from physics.errors import StepFailed
from physics.hydro.hydrodynamics import INVERSE_AFTER_SOLVES, HydroError
from physics.hydro.rft import local_drag_apply
from physics.solvers.implicit_residual import (BandedNewtonTerms, assemble_residual, banded_newton_matrix,
                                               block_max_abs, forces_converged, generalised_velocity,
                                               internal_forces_at, rotate_node_blocks)
from physics.forces.step_context import StepSystem, compiled_contact_args, step_system
from physics.integrate.time_integrator import contraction_update

#: outcome codes of ``chord_loop``
CONVERGED, NONFINITE_RESIDUAL, NEWTON_FAILED, STALL, NEED_INVERSE, HYDRO_FAILED, LINEAR_FAILED = range(7)
#: where ``chord_loop`` starts: at an iteration's residual, at its increment (after a stall), at the final
#: residual of an iterate accepted by the contraction-rate test
AT_RESIDUAL, AT_INCREMENT, AT_FINAL_RESIDUAL = range(3)
_NO_MATRIX = np.asfortranarray(np.zeros((2, 2)))  # stands for the inverse or the factor not (yet) there


class SchemeBase(NamedTuple):
    """The scheme's base values of a step (``time_integrator.StepBase``): q^, v^ (ndof,) and h_e (s)."""

    q_hat: np.ndarray
    v_hat: np.ndarray
    h_eff: float


class ChordHydro(NamedTuple):
    """The resistance of a chord step (``ResistanceOperator``): the kept inverse C (or a placeholder), the upper
    Cholesky factor (or a placeholder), the head's flow H (3M, 3), spin flow g (3M,), force map K (3, 3M; printed
    head), drags N s/m and N m s, the head flags, and Qh (3, 3) from the resistance's frame to the lab."""

    inv: np.ndarray
    chol: np.ndarray
    H: np.ndarray
    g: np.ndarray
    K: np.ndarray
    drag_t: float
    drag_r: float
    has_head: bool
    spin: bool
    printed: bool
    Qh: np.ndarray


class LocalDrag(NamedTuple):
    """The resistance of an RFT step (``force_terms.LocalResistance``, built at the step's predicted geometry): the
    blocks (M, 3, 3) N s/m of the flagellum nodes from node ``first`` (1 with a head, 0 without), the head's drags
    N s/m and N m s (0 N m s when it does not spin), whether the head spin is a generalised velocity, and Qh (3, 3):
    the identity (the resistance is not rotated)."""

    blocks: np.ndarray
    first: int
    drag_t: float
    drag_r: float
    spin: bool
    Qh: np.ndarray


class InverseState(NamedTuple):
    """Whether the resistance applies its kept inverse, its Cholesky solves so far, and the solves after which it
    forms the inverse (``ResistanceOperator.solve``)."""

    use_inv: bool
    applies: int
    applies_max: int


class ChordLinear(NamedTuple):
    """The kept chord Jacobian: LU (ndof, ndof) F order, 1-based pivots int32, the rotation Qj (3, 3) of its node
    blocks, and whether it was factorised in this step."""

    lu: np.ndarray
    piv1: np.ndarray
    Qj: np.ndarray
    jac_fresh: bool


class ChordTols(NamedTuple):
    """The iteration's tolerances (``NumericsConfig``): newton_tol, newton_max_iter, step_tol, the force floor f_floor
    (N), r0 (m), the step's own displacement (m, the increment criterion's scale) and ``single_iteration`` (one
    solve from the predictor: the linearly implicit step)."""

    newton_tol: float
    max_iter: int
    step_tol: float
    f_floor: float
    r0: float
    step_scale: float
    single: bool


class RateState(NamedTuple):
    """The ``ContractionRate`` of the chord iteration: rho, the previous correction's size / step_tol (-1: none),
    age in steps."""

    rho: float
    prev: float
    age: int


class ResidualHistory(NamedTuple):
    """The last two max force residuals of the iteration (N / N m), newest first."""

    newest: float
    previous: float


class Carried(NamedTuple):
    """What an iterate carries across a return to Python: r, grad, f (ndof,), the frames at it (``rod_frames``), the
    contact energy (J) and active interactions."""

    r: np.ndarray
    grad: np.ndarray
    f: np.ndarray
    frames: tuple
    energy: float
    count: int


@njit(cache=True)
def resistance_apply(V: np.ndarray, inv: np.ndarray, chol: np.ndarray, use_inv: bool, H: np.ndarray,
                     g: np.ndarray, K: np.ndarray, drag_t: float, drag_r: float, has_head: bool, spin: bool,
                     printed: bool) -> tuple[np.ndarray, int]:
    """R V (nv,) (minus the hydrodynamic generalised force: N on the nodes, N m on the head spin) for the
    generalised velocities V (nv,) m/s, rad/s, with ``ResistanceOperator.apply``'s arithmetic: the LSBT solve
    C b by the kept inverse (``use_inv``, NumPy's dgemv) or the upper Cholesky factor (dpotrs); the head's flow H
    (3M, 3), spin flow g (3M,), force map K (3, 3M; printed head) and drags N s/m, N m s. Returns (R V, dpotrs
    info)."""
    nv = V.shape[0]
    if not has_head:
        if use_inv:
            return numpy_matvec(inv, V), 0
        return potrs_upper(chol, V)
    m3 = H.shape[0]
    U = V[0:3]
    HU = numpy_matvec(H, U)
    bv = np.empty(m3)
    for i in range(m3):
        bv[i] = V[3 + i] - HU[i]
    if spin:
        s = V[nv - 1]
        for i in range(m3):
            bv[i] = bv[i] - g[i] * s
    if use_inv:
        y = numpy_matvec(inv, bv)
    else:
        y, info = potrs_upper(chol, bv)
        if info != 0:
            return y, info
    out = np.empty(nv)
    if printed:
        Ky = numpy_matvec(K, y)
        for k in range(3):
            out[k] = drag_t * U[k] + Ky[k]
    else:
        Hy = numpy_matvec(H.T, y)
        for k in range(3):
            out[k] = drag_t * U[k] - Hy[k]
    out[3:3 + m3] = y
    if spin:
        out[nv - 1] = drag_r * V[nv - 1] - numpy_dot(g, y)
    return out, 0


def _is(t: Any, cls: type) -> bool:
    """Is the Numba type t that of an instance of the named tuple ``cls``?"""
    return isinstance(t, types.BaseNamedTuple) and t.instance_class is cls


def hydro_force(hydro: Any, V: np.ndarray, use_inv: bool) -> tuple[np.ndarray, int]:
    """R V (nv,) (minus the hydrodynamic generalised force, N / N m) for the generalised velocities V (nv,) in the
    resistance's frame, and a LAPACK info: for ``ChordHydro`` (LSBT + head) ``resistance_apply``, for ``LocalDrag``
    (RFT) ``rft.local_drag_apply`` (info 0). Compiled code only: Numba picks the implementation by the type of
    ``hydro`` when it compiles the caller (``numba.extending.overload``)."""
    raise NotImplementedError("hydro_force is called from compiled code only (chord_residual)")


@overload(hydro_force)
def _hydro_force(hydro, V, use_inv):
    if _is(hydro, LocalDrag):
        def local(hydro, V, use_inv):
            return local_drag_apply(V, hydro.blocks, hydro.first, hydro.drag_t, hydro.drag_r, hydro.spin), 0
        return local
    if _is(hydro, ChordHydro):
        def lsbt(hydro, V, use_inv):
            return resistance_apply(V, hydro.inv, hydro.chol, use_inv, hydro.H, hydro.g, hydro.K, hydro.drag_t,
                                    hydro.drag_r, hydro.has_head, hydro.spin, hydro.printed)
        return lsbt
    return None


def newton_increment(lin: Any, r: np.ndarray, q: np.ndarray, frames: tuple, rest: tuple, prescribed: np.ndarray,
                     nodes_c: np.ndarray, blocks_c: np.ndarray) -> tuple[np.ndarray, int]:
    """The correction z = J^{-1} r (ndof,) of the iterate q (ndof,) with residual r (ndof,), and a LAPACK info. For
    ``ChordLinear`` (LSBT): dgetrs on the kept LU between the rotations by Qj; for ``BandedNewtonTerms`` (RFT): the
    exact banded Jacobian at q (``banded_newton_matrix`` with the frames (t, d1, d2, ref_twist, m1, m2) of q, the
    rest arrays, the Dirichlet DOFs and the active contacts nodes_c (A, 4), blocks_c (A, 12, 12) N/m at q) solved by
    dgbsv (``scipy.linalg.solve_banded``'s). Compiled code only: Numba picks the implementation by the type of
    ``lin`` (``numba.extending.overload``)."""
    raise NotImplementedError("newton_increment is called from compiled code only (chord_loop)")


@overload(newton_increment)
def _newton_increment(lin, r, q, frames, rest, prescribed, nodes_c, blocks_c):
    if _is(lin, BandedNewtonTerms):
        def banded(lin, r, q, frames, rest, prescribed, nodes_c, blocks_c):
            ab = banded_newton_matrix(q, frames, rest, lin, nodes_c, blocks_c, prescribed)
            return gbsv(ab, BANDWIDTH, BANDWIDTH, r)
        return banded
    if _is(lin, ChordLinear):
        def dense(lin, r, q, frames, rest, prescribed, nodes_c, blocks_c):
            x, info = getrs(lin.lu, lin.piv1, rotate_node_blocks(r, lin.Qj, True))
            if info != 0:
                return x, info
            return rotate_node_blocks(x, lin.Qj, False), 0
        return dense
    return None


@njit(cache=True)
def chord_residual(q: np.ndarray, h: float, q_start: np.ndarray, frames_old: tuple, rest: tuple, base: SchemeBase,
                   system: StepSystem, hydro: Any, use_inv: bool, contact_on: bool, model: tuple, cstate: tuple,
                   first_step: bool):
    """The residual of eqn (6) at the iterate of a chord step (the scene's, ``force_terms``, fused): (r, grad, f,
    inertia (ndof,) N / N m, frames, contact state,
    contact energy J, active contacts' nodes (A, 4) and Hessian blocks (A, 12, 12) N/m, LAPACK info of the
    resistance). ``hydro``: ``ChordHydro`` or ``LocalDrag``; other arguments as in ``chord_loop``."""
    grad, fr, cstate, e_c, nodes_c, blocks_c = internal_forces_at(q, frames_old, rest, contact_on, model, cstate,
                                                                  q_start, system.pos, first_step)
    V = generalised_velocity(q, base.q_hat, h, system.vdofs, system.head_spins, system.omega, hydro.Qh)
    RV, info = hydro_force(hydro, V, use_inv)
    r, f, inertia = assemble_residual(q, base.q_hat, base.v_hat, base.h_eff, system.mass, grad, -RV, hydro.Qh,
                                      system.vdofs, system.head_spins, system.prescribed)
    return r, grad, f, inertia, fr, cstate, e_c, nodes_c, blocks_c, info


@njit(cache=True)
def chord_loop(q: np.ndarray, h: float, it: int, phase: int, hist: ResidualHistory, carried: Carried,
               q_start: np.ndarray, frames_old: tuple, rest: tuple, base: SchemeBase, system: StepSystem,
               hydro: Any, inverse_state: InverseState, contact_on: bool, model: tuple, cstate: tuple,
               first_step: bool, lin: Any, tols: ChordTols, rate: RateState):
    """The chord iteration of one step (module doc), compiled, from iteration ``it`` at ``phase``
    (AT_RESIDUAL, or after a return: AT_INCREMENT with ``carried`` = (r, grad, f, frames, contact energy,
    count) of the iterate, AT_FINAL_RESIDUAL).

    q (ndof,) the iterate, h the effective step s; frames_old = (d1, t, ref_twist) of the step's start; rest = the
    7 rest arrays; cstate as in ``internal_forces_at``; the other arguments: the named tuples above, with
    (hydro, lin) = (``ChordHydro``, ``ChordLinear``) for LSBT or (``LocalDrag``, ``BandedNewtonTerms``) for RFT
    (module doc; RFT passes an ``InverseState`` with use_inv true: it has no Cholesky solves to count).

    Returns (code, q, it, phase, ``ResidualHistory``, ``Carried``, cstate, ``RateState``, Cholesky solves,
    residuals evaluated, increments solved, value): value = the max force residual (NEWTON_FAILED) or a LAPACK
    info (HYDRO_FAILED: dpotrs, LINEAR_FAILED: dgetrs or dgbsv). STALL (LSBT): the caller refactorises the
    Jacobian and resumes at ``phase``; NEED_INVERSE (LSBT): the caller forms the inverse and resumes."""
    pos, twist = system.pos, system.twist
    use_inv, applies = inverse_state.use_inv, inverse_state.applies
    newton_tol, max_iter, step_tol, r0 = tols.newton_tol, tols.max_iter, tols.step_tol, tols.r0
    rho, prev, age = rate.rho, rate.prev, rate.age
    h1, h2 = hist.newest, hist.previous
    r, grad, f, fr, e_c, count = carried.r, carried.grad, carried.f, carried.frames, carried.energy, carried.count
    adaptive = step_tol > 0.0
    evaluated = 0
    solves = 0
    nodes_c = np.zeros((0, 4), dtype=np.int64)  # the active contacts at the iterate (the banded increment's)
    blocks_c = np.zeros((0, 12, 12))
    norm = 0.0
    while it < 2 * max_iter:
        if phase != AT_INCREMENT:
            if not use_inv:
                if applies + 1 > inverse_state.applies_max:
                    return (NEED_INVERSE, q, it, phase, ResidualHistory(h1, h2),
                            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                            solves, 0.0)
                applies += 1
            r, grad, f, inertia, fr, cstate, e_c, nodes_c, blocks_c, info = chord_residual(
                q, h, q_start, frames_old, rest, base, system, hydro, use_inv, contact_on, model, cstate, first_step)
            count = nodes_c.shape[0]
            if info != 0:
                return (HYDRO_FAILED, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        solves, float(info))
            evaluated += 1
            if phase == AT_FINAL_RESIDUAL:  # the forces at the accepted iterate
                return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        solves, 0.0)
            if not np.all(np.isfinite(r)):
                return (NONFINITE_RESIDUAL, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        solves, 0.0)
            if forces_converged(r, grad, f, inertia, pos, system.free_twist, newton_tol, tols.f_floor, r0):
                return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        solves, 0.0)
            norm = np.abs(r).max()
            if it >= max_iter or (it >= 8 and norm > 0.5 * h2):
                if not lin.jac_fresh:  # the caller refactorises at q (``on_stall``) and resumes at the increment
                    return (STALL, q, it, AT_INCREMENT, ResidualHistory(h1, h2),
                            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                            solves, 0.0)
                if it >= max_iter:
                    return (NEWTON_FAILED, q, it, phase, ResidualHistory(h1, h2),
                            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                            solves, norm)
        else:
            norm = np.abs(r).max()
            phase = AT_RESIDUAL
        h2 = h1
        h1 = norm
        solves += 1
        z, info = newton_increment(lin, r, q, fr, rest, system.prescribed, nodes_c, blocks_c)
        if info != 0:
            return (LINEAR_FAILED, q, it, phase, ResidualHistory(h1, h2),
                    Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                    solves, float(info))
        q = q - z
        if tols.single:  # linearly implicit: the forces are those of the predictor
            return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                    Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                    solves, 0.0)
        # increment criterion: the iteration contracts, so an increment far below the step's own displacement
        # (and the twist resolution) means the residual is at tolerance
        dz = block_max_abs(z, pos)
        if (it >= 1 and dz <= max(newton_tol * tols.step_scale, 1e-10 * r0)
                and block_max_abs(z, twist) <= max(newton_tol, 1e-10)):
            return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                    Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                    solves, 0.0)
        if adaptive:  # ContractionRate.converged
            converged, rho, prev, age = contraction_update(np.max(np.abs(z) * system.weights) / step_tol, rho,
                                                           prev, age)
            if converged:
                phase = AT_FINAL_RESIDUAL
                continue
        it += 1
    return (NEWTON_FAILED, q, it - 1, phase, ResidualHistory(h1, h2),
            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
            solves, np.abs(r).max())


def chord_solve(sim: Any, q: np.ndarray, h: float):
    """The chord iteration of a step from the predictor q (ndof,) at the effective step h (s), compiled
    (``chord_loop``), Python entering only at a stall or when the resistance forms its inverse (LSBT). Returns
    (q, r, grad, f, (t, d1, ref_twist)) at convergence (with ``single_iteration``: the solve's q, the rest at the
    predictor); raises ``StepFailed``. ``sim``: the stepped object; it gives its ``system``
    (``step_context.SystemDescription``), the step (``step_context(h)``), its solver (``step_solvers``: dense chord
    or banded Newton, ``banded`` tells), contraction rate and counters, and keeps the contact state the loop
    returns."""
    system = sim.system
    nm, p = system.numerics, system.params
    solver = sim.solver
    banded = solver.banded
    hyd = None if banded else solver.hyd
    ctx = sim.step_context(h)
    if not banded and hyd.inv is None and hyd.chol is None:  # what the first solve would do (a lazy operator)
        try:
            hyd.factorize()
        except HydroError as exc:
            raise StepFailed("hydrodynamic mobility", str(exc)) from None
    step_scale = max(block_max_abs(q - ctx.q_start, system.pos), 1e-6 * p.rod_radius)
    rate = sim.contraction
    if nm.step_tol > 0.0:
        rate.start()
    rstate = RateState(rho=rate.rho, prev=-1.0 if rate.prev is None else rate.prev, age=rate.age)
    contact_on, model, cstate = compiled_contact_args(q, ctx, system)
    base = SchemeBase(q_hat=ctx.q_hat, v_hat=ctx.v_hat, h_eff=ctx.h)
    arrays = step_system(system, ctx.omega)
    frames_old = ctx.frames
    tols = ChordTols(newton_tol=nm.newton_tol, max_iter=nm.newton_max_iter, step_tol=nm.step_tol,
                     f_floor=system.f_floor, r0=p.rod_radius, step_scale=step_scale, single=nm.single_iteration)
    if banded:  # RFT: the step's drag and Jacobian terms, fixed through the step (no return to Python midway)
        local = solver.local
        hydro = LocalDrag(blocks=local.blocks, first=local.first, drag_t=local.drag_t, drag_r=local.drag_r,
                          spin=local.spin, Qh=_EYE)
        lin = solver.newton_terms(h)
        inverse_state = InverseState(use_inv=True, applies=0, applies_max=0)
    elif hyd.has_head:  # K only for the printed head (a C-contiguous placeholder otherwise: one compiled variant)
        H, g, K, drag_t = hyd.H, hyd.g, (hyd.K if hyd.printed else _NO_K), hyd.drag_t
        drag_r = hyd.drag_r if hyd.spin else 0.0
    else:
        H, g, K, drag_t, drag_r = _NO_HEAD_H, _NO_HEAD_G, _NO_K, 0.0, 0.0
    # placeholders of the types the loop's residual returns (read only when resuming at an increment)
    d1_old, t_old, rt_old = ctx.frames
    carried = Carried(r=q, grad=q, f=q, frames=(t_old, d1_old, d1_old, rt_old, d1_old, d1_old), energy=0.0, count=0)
    it, phase, hist = 0, AT_RESIDUAL, ResidualHistory(newest=np.inf, previous=np.inf)
    while True:
        if not banded:  # the LSBT resistance and the kept LU as they are now (changed by a return to Python)
            use_inv = hyd.inv is not None
            hydro = ChordHydro(inv=hyd.inv if use_inv else _NO_MATRIX, chol=_NO_MATRIX if use_inv else hyd.chol[0],
                               H=H, g=g, K=K, drag_t=drag_t, drag_r=drag_r, has_head=hyd.has_head, spin=hyd.spin,
                               printed=hyd.printed, Qh=np.ascontiguousarray(solver.Qh))
            lin = ChordLinear(lu=solver.lu[0], piv1=solver.piv1, Qj=np.ascontiguousarray(solver.Qj),
                              jac_fresh=solver.jac_fresh)
            inverse_state = InverseState(use_inv=use_inv, applies=hyd.applies, applies_max=INVERSE_AFTER_SOLVES)
        (code, q, it, phase, hist, carried, cstate, rstate, applies, evaluated, solves, value) = chord_loop(
            q, h, it, phase, hist, carried, ctx.q_start, frames_old, system.rest, base, arrays, hydro, inverse_state,
            contact_on, model, cstate, ctx.first_step, lin, tols, rstate)
        sim.stats.newton_iterations += evaluated
        if banded:
            sim.stats.jacobian_factorisations += solves  # one banded factorisation per increment
        else:
            hyd.applies = applies
        sim.keep_contact_state(cstate, carried.energy, carried.count)
        rate.rho, rate.age = rstate.rho, rstate.age
        rate.prev = None if rstate.prev < 0.0 else rstate.prev
        if code == CONVERGED:
            t, d1, d2, rt, m1, m2 = carried.frames
            return q, carried.r, carried.grad, carried.f, (t, d1, rt)
        if code == STALL:
            solver.on_stall(q, h)  # refactorises (the loop returns only when the Jacobian is not fresh)
        elif code == NEED_INVERSE:  # ResistanceOperator.solve's switch to the explicit inverse
            hyd.applies += 1
            try:
                hyd.inverse()
            except HydroError as exc:
                raise StepFailed("hydrodynamic mobility", str(exc)) from None
        elif code == NONFINITE_RESIDUAL:
            raise StepFailed("residual", "non-finite (NaN/inf) force residual")
        elif code == HYDRO_FAILED:
            raise StepFailed("hydrodynamic mobility", f"LSBT mobility solve failed (potrs info {int(value)})")
        elif code == LINEAR_FAILED and banded:  # scipy.linalg.solve_banded's messages
            why = ("singular matrix" if value > 0
                   else f"illegal value in {-int(value)}-th argument of internal gbsv/gtsv")
            raise StepFailed("Jacobian", f"banded Newton system is singular ({why})")
        elif code == LINEAR_FAILED:
            raise StepFailed("Jacobian", f"LU back-substitution failed (getrs info {int(value)})")
        else:
            raise StepFailed("Newton", f"Newton did not converge after {it + 1} iterations "
                                       f"(max force residual {value:.3e})")


_EYE = np.eye(3)
_NO_HEAD_H = np.zeros((0, 3))
_NO_HEAD_G = np.zeros(0)
_NO_K = np.zeros((3, 0))
