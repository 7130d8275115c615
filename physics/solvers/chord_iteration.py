"""The chord iteration of a steady step, compiled end to end (one Numba call per step attempt).

While the hydrodynamic resistance is reused through a rigid rotation (steady swimming, ``step_solvers``), each
step solves the implicit residual of eqn (6) (Huang & Jawed 2020; ``implicit_residual``) by the chord
iteration q <- q - J_old^{-1} r(q) on the reused dense LU of J = M/h^2 + K + P^T R P / h, its node blocks rotated
by the best-fit rotation Qj (``rigid_alignment``). ``Simulator._chord_python`` is that iteration written in
Python, one kernel call per piece; it stays the reference. ``chord_loop`` is the same iteration in one compiled
call, with the same operations in the same order, so its iterates are bit-identical:

* the residual: frames, elastic and contact forces with the contact broad-phase redo (``internal_forces_at``),
  the hydrodynamic force -R V in the resistance's reference frame (``resistance_apply``, the arithmetic of
  ``ResistanceOperator.apply``: NumPy's own dgemv / ddot and SciPy's dpotrs, ``compiled_lapack``), the residual
  (``assemble_residual``);
* the tests: the force residual (``forces_converged``), the stall test, the increment criterion, CVODE's
  contraction-rate test (``time_integrator.ContractionRate``);
* the increment: LAPACK dgetrs on the kept LU (``compiled_lapack.getrs``) between the rotations by Qj.

Python acts only where the Python iteration does something other than arithmetic: a stall (the Jacobian is
refactorised, ``DenseChordSolver.on_stall``) and the moment the resistance operator forms its explicit inverse
(``ResistanceOperator.inverse``, after ``_INVERSE_AFTER_SOLVES`` Cholesky solves); the loop returns there and
``chord_solve`` resumes it where it stopped (``phase``). Anderson mixing (``anderson_depth`` > 0), a single
iteration per step and a NumPy without its bundled OpenBLAS keep the Python iteration.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

from physics.linalg.compiled_lapack import NUMPY_BLAS, getrs, numpy_dot, numpy_matvec, potrs_upper
from physics.errors import StepFailed
from physics.hydro.hydrodynamics import _INVERSE_AFTER_SOLVES, HydroError
from physics.solvers.implicit_residual import (assemble_residual, block_max_abs, forces_converged, generalised_velocity,
                                       internal_forces_at, rotate_node_blocks)
from physics.forces.step_context import StepSystem, compiled_contact_args, step_system
from physics.integrate.time_integrator import contraction_update

#: outcome codes of ``chord_loop``
CONVERGED, NONFINITE_RESIDUAL, NEWTON_FAILED, STALL, NEED_INVERSE, HYDRO_FAILED, GETRS_FAILED = range(7)
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
    (N), r0 (m) and the step's own displacement (m, the increment criterion's scale)."""

    newton_tol: float
    max_iter: int
    step_tol: float
    f_floor: float
    r0: float
    step_scale: float


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


@njit(cache=True)
def chord_residual(q: np.ndarray, h: float, q_start: np.ndarray, frames_old: tuple, rest: tuple, base: SchemeBase,
                   system: StepSystem, hydro: ChordHydro, use_inv: bool, contact_on: bool, model: tuple,
                   cstate: tuple, first_step: bool):
    """``Simulator._residual`` of a chord step: (r, grad, f, inertia (ndof,) N / N m, frames, contact state,
    contact energy J, active contacts, dpotrs info). Arguments as in ``chord_loop``."""
    grad, fr, cstate, e_c, nodes_c, _ = internal_forces_at(q, frames_old, rest, contact_on, model, cstate, q_start,
                                                           system.pos, first_step)
    V = generalised_velocity(q, base.q_hat, h, system.vdofs, system.head_spins, system.omega, hydro.Qh)
    RV, info = resistance_apply(V, hydro.inv, hydro.chol, use_inv, hydro.H, hydro.g, hydro.K, hydro.drag_t,
                                hydro.drag_r, hydro.has_head, hydro.spin, hydro.printed)
    r, f, inertia = assemble_residual(q, base.q_hat, base.v_hat, base.h_eff, system.mass, grad, -RV, hydro.Qh,
                                      system.vdofs, system.head_spins, system.prescribed)
    return r, grad, f, inertia, fr, cstate, e_c, nodes_c.shape[0], info


@njit(cache=True)
def chord_loop(q: np.ndarray, h: float, it: int, phase: int, hist: ResidualHistory, carried: Carried,
               q_start: np.ndarray, frames_old: tuple, rest: tuple, base: SchemeBase, system: StepSystem,
               hydro: ChordHydro, inverse_state: InverseState, contact_on: bool, model: tuple, cstate: tuple,
               first_step: bool, lin: ChordLinear, tols: ChordTols, rate: RateState):
    """The chord iteration of one step (``Simulator._chord_python``), compiled, from iteration ``it`` at ``phase``
    (AT_RESIDUAL, or after a return: AT_INCREMENT with ``carried`` = (r, grad, f, frames, contact energy,
    count) of the iterate, AT_FINAL_RESIDUAL).

    q (ndof,) the iterate, h the effective step s; frames_old = (d1, t, ref_twist) of the step's start; rest = the
    7 rest arrays; cstate as in ``internal_forces_at``; the other arguments: the named tuples above.

    Returns (code, q, it, phase, ``ResidualHistory``, ``Carried``, cstate, ``RateState``, Cholesky solves,
    residuals evaluated, value): value = the max force residual (NEWTON_FAILED) or a LAPACK
    info (HYDRO_FAILED: dpotrs, GETRS_FAILED: dgetrs). STALL: the caller refactorises the Jacobian and resumes
    at ``phase``; NEED_INVERSE: the caller forms the inverse and resumes."""
    pos, twist = system.pos, system.twist
    use_inv, applies = inverse_state.use_inv, inverse_state.applies
    newton_tol, max_iter, step_tol, r0 = tols.newton_tol, tols.max_iter, tols.step_tol, tols.r0
    rho, prev, age = rate.rho, rate.prev, rate.age
    h1, h2 = hist.newest, hist.previous
    r, grad, f, fr, e_c, count = carried.r, carried.grad, carried.f, carried.frames, carried.energy, carried.count
    adaptive = step_tol > 0.0
    evaluated = 0
    norm = 0.0
    while it < 2 * max_iter:
        if phase != AT_INCREMENT:
            if not use_inv:
                if applies + 1 > inverse_state.applies_max:
                    return (NEED_INVERSE, q, it, phase, ResidualHistory(h1, h2),
                            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                            0.0)
                applies += 1
            r, grad, f, inertia, fr, cstate, e_c, count, info = chord_residual(
                q, h, q_start, frames_old, rest, base, system, hydro, use_inv, contact_on, model, cstate, first_step)
            if info != 0:
                return (HYDRO_FAILED, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        float(info))
            evaluated += 1
            if phase == AT_FINAL_RESIDUAL:  # the forces at the accepted iterate
                return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        0.0)
            if not np.all(np.isfinite(r)):
                return (NONFINITE_RESIDUAL, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        0.0)
            if forces_converged(r, grad, f, inertia, pos, system.free_twist, newton_tol, tols.f_floor, r0):
                return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                        Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                        0.0)
            norm = np.abs(r).max()
            if it >= max_iter or (it >= 8 and norm > 0.5 * h2):
                if not lin.jac_fresh:  # the caller refactorises at q (``on_stall``) and resumes at the increment
                    return (STALL, q, it, AT_INCREMENT, ResidualHistory(h1, h2),
                            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                            0.0)
                if it >= max_iter:
                    return (NEWTON_FAILED, q, it, phase, ResidualHistory(h1, h2),
                            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                            norm)
        else:
            norm = np.abs(r).max()
            phase = AT_RESIDUAL
        h2 = h1
        h1 = norm
        x, info = getrs(lin.lu, lin.piv1, rotate_node_blocks(r, lin.Qj, True))
        if info != 0:
            return (GETRS_FAILED, q, it, phase, ResidualHistory(h1, h2),
                    Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                    float(info))
        z = rotate_node_blocks(x, lin.Qj, False)
        q = q - z
        # increment criterion: the iteration contracts, so an increment far below the step's own displacement
        # (and the twist resolution) means the residual is at tolerance
        dz = block_max_abs(z, pos)
        if (it >= 1 and dz <= max(newton_tol * tols.step_scale, 1e-10 * r0)
                and block_max_abs(z, twist) <= max(newton_tol, 1e-10)):
            return (CONVERGED, q, it, phase, ResidualHistory(h1, h2),
                    Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
                    0.0)
        if adaptive:  # ContractionRate.converged
            converged, rho, prev, age = contraction_update(np.max(np.abs(z) * system.weights) / step_tol, rho,
                                                           prev, age)
            if converged:
                phase = AT_FINAL_RESIDUAL
                continue
        it += 1
    return (NEWTON_FAILED, q, it - 1, phase, ResidualHistory(h1, h2),
            Carried(r, grad, f, fr, e_c, count), cstate, RateState(rho, prev, age), applies, evaluated,
            np.abs(r).max())


def compiled_chord_applies(sim: Any) -> bool:
    """Whether ``chord_solve`` can take this step: the dense chord solver with a factorised Jacobian, no
    Anderson mixing, more than one iteration per step, and NumPy's own BLAS reachable from compiled code."""
    nm = sim.numerics
    solver = sim.solver
    return (NUMPY_BLAS and nm.anderson_depth == 0 and not nm.single_iteration
            and getattr(solver, "lu", None) is not None and getattr(solver, "hyd", None) is not None)


def chord_solve(sim: Any, q: np.ndarray, h: float):
    """The chord iteration of a step from the predictor q (ndof,) at the effective step h (s), compiled
    (``chord_loop``), Python entering only at a stall or when the resistance forms its inverse. Returns
    (q, r, grad, f, (t, d1, ref_twist)) as ``Simulator._chord_python`` does, bit for bit; raises ``StepFailed``
    where it does. ``sim``: the stepped object; it gives its ``system`` (``step_context.SystemDescription``), the
    step (``step_context(h)``), its dense chord solver, contraction rate and counters, and keeps the contact state
    the loop returns."""
    system = sim.system
    nm, p = system.numerics, system.params
    solver = sim.solver
    hyd = solver.hyd
    ctx = sim.step_context(h)
    if hyd.inv is None and hyd.chol is None:  # what the first solve would do (a lazily built operator)
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
                     f_floor=system.f_floor, r0=p.rod_radius, step_scale=step_scale)
    if hyd.has_head:  # K only for the printed head (a C-contiguous placeholder otherwise: one compiled variant)
        H, g, K, drag_t = hyd.H, hyd.g, (hyd.K if hyd.printed else _NO_K), hyd.drag_t
        drag_r = hyd.drag_r if hyd.spin else 0.0
    else:
        H, g, K, drag_t, drag_r = _NO_HEAD_H, _NO_HEAD_G, _NO_K, 0.0, 0.0
    # placeholders of the types the loop's residual returns (read only when resuming at an increment)
    d1_old, t_old, rt_old = ctx.frames
    carried = Carried(r=q, grad=q, f=q, frames=(t_old, d1_old, d1_old, rt_old, d1_old, d1_old), energy=0.0, count=0)
    it, phase, hist = 0, AT_RESIDUAL, ResidualHistory(newest=np.inf, previous=np.inf)
    while True:
        use_inv = hyd.inv is not None
        hydro = ChordHydro(inv=hyd.inv if use_inv else _NO_MATRIX, chol=_NO_MATRIX if use_inv else hyd.chol[0],
                           H=H, g=g, K=K, drag_t=drag_t, drag_r=drag_r, has_head=hyd.has_head, spin=hyd.spin,
                           printed=hyd.printed, Qh=np.ascontiguousarray(solver.Qh))
        lin = ChordLinear(lu=solver.lu[0], piv1=solver.piv1, Qj=np.ascontiguousarray(solver.Qj),
                          jac_fresh=solver.jac_fresh)
        (code, q, it, phase, hist, carried, cstate, rstate, applies, evaluated, value) = chord_loop(
            q, h, it, phase, hist, carried, ctx.q_start, frames_old, system.rest, base, arrays, hydro,
            InverseState(use_inv=use_inv, applies=hyd.applies, applies_max=_INVERSE_AFTER_SOLVES), contact_on,
            model, cstate, ctx.first_step, lin, tols, rstate)
        hyd.applies = applies
        sim.stats.newton_iterations += evaluated
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
        elif code == GETRS_FAILED:
            raise StepFailed("Jacobian", f"LU back-substitution failed (getrs info {int(value)})")
        else:
            raise StepFailed("Newton", f"Newton did not converge after {it + 1} iterations "
                                       f"(max force residual {value:.3e})")


_NO_HEAD_H = np.zeros((0, 3))
_NO_HEAD_G = np.zeros(0)
_NO_K = np.zeros((3, 0))
