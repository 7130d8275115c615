"""The chord iteration of a step written in Python, one kernel call per piece: the reference oracle of the compiled
``chord_iteration.chord_solve`` (both solvers: the dense chord iteration of LSBT and the banded Newton one of RFT; one
solve from the predictor with ``single_iteration``), which must give the same bits.

``chord_python(sim, q, h)`` takes a step set up as ``Simulator._try_step`` sets it up; ``PythonChordSimulator`` is a
``Simulator`` whose chord steps run it (whole runs against the compiled ones). Its pieces: ``scene_residual`` (the
residual through the scene, ``physics.forces.force_terms``), ``increment`` (dgetrs on the kept LU between the rotations
by Qj, or ``scipy.linalg.solve_banded`` on the exact banded Jacobian), ``converged`` and ``correction_size``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack, solve_banded

from physics.elastic import BANDWIDTH
from physics.errors import StepFailed
from physics.forces.step_context import active_contacts, frames_at
from physics.hydro.hydrodynamics import HydroError
from physics.simulator import Simulator
from physics.solvers.implicit_residual import (banded_newton_matrix, block_max_abs, forces_converged,
                                               rotate_node_blocks)


def scene_residual(sim: Simulator, q: np.ndarray, h: float):
    """The residual of eqn (6) at q (ndof,) through the scene's force terms: (r, grad of the elastic and contact
    energies, hydrodynamic generalised force f, inertia term (all (ndof,), N / N m), frames (t, d1, ref_twist) at
    q). Keeps the contact state; h is the effective step h_e (s)."""
    try:
        r, forces, byproducts, _ = sim.scene.evaluate(q, sim.step_context(h))
    except HydroError as exc:
        raise StepFailed("hydrodynamic mobility", str(exc)) from None
    grad = forces["elastic"]
    if sim.contact is not None:
        grad = grad + forces["contact"]  # the fused kernels' grad, bit for bit (zero on the twists)
        cstate, e_c, nodes_c, _ = byproducts["contact"]
        sim.keep_contact_state(cstate, e_c, nodes_c.shape[0])
    t, d1, d2, rt, m1, m2 = byproducts["elastic"]
    return r, grad, -forces["hydrodynamics"], forces["inertia"], (t, d1, rt)


def converged(sim: Simulator, r, grad, f, inertia) -> bool:
    """The force test of the iteration (``implicit_residual.forces_converged``) at the numerics' Newton tolerance."""
    system = sim.system
    return forces_converged(r, grad, f, inertia, system.pos, system.free_twist, sim.numerics.newton_tol,
                            system.f_floor, sim.params.rod_radius)


def correction_size(sim: Simulator, z: np.ndarray) -> float:
    """The weighted max norm of a correction of q (ndof,): positions in r0, twists in rad (the error estimate's
    units, ``adaptive_step.local_error``)."""
    return float(np.max(np.abs(z) * sim.system.weights))


def increment(sim: Simulator, r: np.ndarray, q: np.ndarray, h: float) -> np.ndarray:
    """The correction J^{-1} r (ndof,) for the residual r (ndof,) at q, effective step h (s): LSBT: LAPACK dgetrs on
    the kept LU between the rotations by Qj; RFT: the exact banded Jacobian at q
    (``implicit_residual.banded_newton_matrix``) solved by ``scipy.linalg.solve_banded`` (one factorisation
    counted)."""
    solver = sim.solver
    if not solver.banded:
        x, info = lapack.dgetrs(solver.lu[0], solver.lu[1], rotate_node_blocks(r, solver.Qj, True))
        if info != 0:
            raise StepFailed("Jacobian", f"LU back-substitution failed (getrs info {info})")
        return rotate_node_blocks(x, solver.Qj, False)
    system, ctx = sim.system, sim.step_context(h)
    nodes_c, blocks_c = active_contacts(q, ctx, system)  # none without contact
    ab = banded_newton_matrix(q, frames_at(q, ctx), system.rest, solver.newton_terms(h), nodes_c, blocks_c,
                              system.prescribed)
    sim.stats.jacobian_factorisations += 1
    try:
        return solve_banded((BANDWIDTH, BANDWIDTH), ab, r, check_finite=False)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise StepFailed("Jacobian", f"banded Newton system is singular ({exc})") from None


def chord_python(sim: Simulator, q: np.ndarray, h: float, residual=scene_residual):
    """The chord iteration of a step from the predictor q (ndof,) at the effective step h (s), in Python. Returns
    (q, r, grad, f, (t, d1, ref_twist)) at convergence; raises ``StepFailed``. ``residual(sim, q, h)``: the residual
    (``scene_residual``, or one with extra forces)."""
    nm, p, system, solver = sim.numerics, sim.params, sim.system, sim.solver
    hist = [math.inf, math.inf]
    step_scale = max(block_max_abs(q - sim.q, system.pos), 1e-6 * p.rod_radius)
    rate = sim.contraction if nm.step_tol > 0.0 else None
    if rate is not None:
        rate.start()
    for it in range(nm.newton_max_iter * 2):
        r, grad, f, inertia, frames = residual(sim, q, h)
        sim.stats.newton_iterations += 1
        if not np.all(np.isfinite(r)):
            raise StepFailed("residual", "non-finite (NaN/inf) force residual")
        if converged(sim, r, grad, f, inertia):
            return q, r, grad, f, frames
        norm = float(np.abs(r).max())
        # stalled: a refactorisation costs ~20 iterations, so only after many iterations or
        # when two iterations together reduce the residual by less than 2x (RFT: exact Jacobian, no refactorisation)
        if it >= nm.newton_max_iter or (it >= 8 and norm > 0.5 * hist[-2]):
            refactorised = not solver.banded and solver.on_stall(q, h)
            if not refactorised and it >= nm.newton_max_iter:
                break
        hist.append(norm)
        z = increment(sim, r, q, h)
        q = q - z
        if nm.single_iteration:  # linearly implicit Euler: one solve from the predictor
            return q, r, grad, f, frames
        # increment criterion: the iteration contracts, so an increment far below the step's
        # own displacement (and the twist resolution) means the residual is at tolerance
        dz = block_max_abs(z, system.pos)
        if (it >= 1 and dz <= max(nm.newton_tol * step_scale, 1e-10 * p.rod_radius)
                and block_max_abs(z, system.twist) <= max(nm.newton_tol, 1e-10)):
            return q, r, grad, f, frames
        if rate is not None and rate.converged(correction_size(sim, z) / nm.step_tol):
            r, grad, f, inertia, frames = residual(sim, q, h)  # the forces at the accepted iterate
            sim.stats.newton_iterations += 1
            return q, r, grad, f, frames
    raise StepFailed("Newton", f"Newton did not converge after {it + 1} iterations "
                               f"(max force residual {np.abs(r).max():.3e})")


class PythonChordSimulator(Simulator):
    """A ``Simulator`` whose chord steps run ``chord_python`` with the residual ``residual`` (``scene_residual``;
    a subclass may add forces to it) instead of the compiled loop."""

    def residual(self, q: np.ndarray, h: float):
        return scene_residual(self, q, h)

    def _chord_step(self, q: np.ndarray, h: float):
        return chord_python(self, q, h, lambda sim, q, h: sim.residual(q, h))
