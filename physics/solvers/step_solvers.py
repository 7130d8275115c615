"""Linear algebra of one implicit step: the hydrodynamic resistance and the Newton solve.

A scene pays only for what it uses:

* ``DenseChordSolver`` (hydro_model="lsbt"): nonlocal LSBT + head. The resistance is dense;
  it is factorised (Cholesky of the mobility) only when the shape has changed non-rigidly by
  more than ``hydro_refresh_tol`` * r0 since the last time, and the dense Jacobian
  M/h^2 + K + R/h when the chord iteration stops contracting or once the residuals it took beyond two per step
  since the last factorisation cost as much as a new one (``LU_REFRESH_BUDGET``). In between both are reused
  through the best-fit rigid rotation of the configuration (exact for a rigid motion, see
  ``rigid_alignment``), which makes a steadily rotating flagellum cheap. The chord iteration on them runs
  compiled (``chord_iteration.chord_solve``), which hands a stall back to ``on_stall``.
* ``BandedNewtonSolver`` (hydro_model="rft"): local drag, so R is block-diagonal, the Jacobian
  stays banded (half-bandwidth 10) and each Newton iteration is an O(N) banded solve with the
  exact Jacobian (``implicit_residual.banded_newton_matrix``). No dense matrix anywhere. The iteration runs
  compiled (``chord_iteration.chord_solve``, the same loop as the dense chord iteration, with LAPACK dgbsv).

Both evaluate the resistance at the predicted geometry q_k + h v_k (linearly implicit in the
velocity, lagged in the geometry within a step), built by the scene's hydrodynamic term
(``force_terms.Hydrodynamics.resistance_at``).

The solvers read the system through a ``step_context.SystemDescription`` (masses, DOF sets, rest arrays, the
parameters: nothing that changes) and the step through a ``step_context.StepContext`` that the stepped object gives
them (``StepState``: the base values, the frames and configuration of the step's start, the contact state).
"""

from __future__ import annotations

import time
from typing import Any, Protocol

import numpy as np
from numba import njit
from scipy.linalg import lu_factor

from physics.forces.contact import ContactState, add_blocks_to_dense
from physics.elastic import elastic_hessian_banded_kernel
from physics.forces.force_terms import Hydrodynamics, LocalResistance
from physics.model.geometry import nodes_of
from physics.hydro.hydrodynamics import HydroError, ResistanceOperator
from physics.errors import StepFailed
from physics.solvers.newton_krylov import KrylovFailed, MobilityStep
from physics.solvers.implicit_residual import BandedNewtonTerms, assemble_dense_jacobian, rotate_dense_blocks
from physics.hydro.rft import rft_coefficients
from physics.model.rigid_alignment import best_fit_rotation
from physics.forces.step_context import StepContext, StepResistance, SystemDescription, active_contacts, frames_at


class StepState(Protocol):
    """What the solvers take of the object being stepped (``physics.simulator.Simulator`` is one) besides its
    ``SystemDescription``: the step being taken, a place to keep the contact state the compiled kernels return,
    and the counters."""

    stats: Any  # physics.simulator.StepStats

    def step_context(self, h: float) -> StepContext: ...

    def keep_contact_state(self, cstate: ContactState, energy: float, count: int) -> None: ...


_EYE = np.eye(3)
# A Jacobian factorised at step h_J is reused for steps h with h / h_J in this band (the chord
# iteration still contracts: the hydrodynamic part R/h is off by at most 25 %); outside it, or
# after a halving, it is refactorised at the new h.
H_REUSE = (0.8, 1.25)
# The kept LU is refactorised (at the predictor, the resistance rotated to it) once the residuals the chord
# iteration needed beyond two per step (one correction and the forces at the accepted iterate) since the last
# factorisation add up to what a refactorisation costs: ~3.4 ms against ~0.1 ms per extra residual and solve
# (N = 122): ski rental, never more than twice the better choice. An LU goes stale as the flagellum turns
# (the contraction rate of settled 10 rpm steps grows from 0.007 to ~0.1 in 60 steps) and at once when a
# Newton-Krylov step rebuilds the resistance (the shape changed): ~0.5, 4.9 residuals per step.
LU_REFRESH_BUDGET = 30
# With Newton-Krylov on, a chord step that would need a new dense factorisation at its start (no LU, a step
# outside the H_REUSE band of the LU's, or a resistance rebuilt by an attempt that was not accepted) is taken
# by Newton-Krylov instead (~1 ms against ~5-7 ms for the resistance, its inverse and the LU of 487 unknowns),
# until the shape has stayed within hydro_refresh_tol of the kept resistance for this many attempts in a row:
# then the swimmer is cruising and the LU pays for itself over the chord steps that follow.
CALM_STEPS_FOR_LU = 4


@njit(cache=True)
def krylov_begins(since_hydro: int, refresh_steps: int, dev: float, refresh_dev: float, calm: int, lu_h: float,
                  h: float, lu_after_rebuild: bool) -> tuple[bool, int]:
    """Is the next attempt (effective step h, s) a Newton-Krylov step, and the new count of calm attempts?

    The shape has changed when the resistance is ``refresh_steps`` accepted steps old or the predictor deviates
    from its shape by dev > refresh_dev (m, after the best rigid fit); a calm attempt is one where it has not. A
    Newton-Krylov step rebuilds the resistance where the shape has changed, or where a chord step would need a new
    dense factorisation (no LU: lu_h < 0; h outside the ``H_REUSE`` band of the LU's step lu_h; a resistance
    rebuilt by an attempt that was not accepted, with ``lu_after_rebuild``) before ``CALM_STEPS_FOR_LU`` calm
    attempts in a row. The one decision of ``DenseChordSolver.begin_step`` and the compiled span
    (``krylov_span``)."""
    changed = since_hydro >= refresh_steps or dev > refresh_dev
    calm = 0 if changed else calm + 1
    stale = (lu_h < 0.0 or not H_REUSE[0] <= h / lu_h <= H_REUSE[1] or (since_hydro == 0 and lu_after_rebuild))
    return changed or (calm < CALM_STEPS_FOR_LU and stale), calm


class DenseChordSolver:
    """LSBT + head resistance with reused factorisations (see module docstring)."""

    banded = False  # the chord iteration's increment: dgetrs on the kept dense LU (``chord_iteration``)

    def __init__(self, system: SystemDescription, state: StepState, hydro: Hydrodynamics) -> None:
        self.system, self.state, self.hydro = system, state, hydro
        self.mobility = MobilityStep(system, state, rft_coefficients(system.params, "lighthill"))
        self.reset()

    def reset(self) -> None:
        self.krylov = False  # this step is solved by Newton-Krylov (``newton_krylov``)
        self.calm_steps = 0  # attempts in a row whose shape stayed within hydro_refresh_tol of the resistance's
        self.hyd: ResistanceOperator | None = None
        self.x_hyd: np.ndarray | None = None
        self.since_hydro = 0
        self.lu = None
        self.piv1: np.ndarray | None = None
        self.lu_h = -1.0
        self.extra_iterations = 0  # residuals beyond two per chord step since the factorisation
        self._iterations_seen = 0
        self.x_jac: np.ndarray | None = None
        self.Qh = self.Qj = _EYE
        self.jac_fresh = False
        self.contact_set: frozenset | None = None

    def _refresh_hydro(self, q: np.ndarray, lazy: bool = False) -> None:
        stats = self.state.stats
        t0 = time.perf_counter()
        x = nodes_of(q)
        try:
            self.hyd = self.hydro.resistance_at(x, lazy)
        except HydroError as exc:
            raise StepFailed("hydrodynamic mobility", str(exc)) from None
        self.x_hyd = x
        self.since_hydro = 0
        stats.resistance_refreshes += 1
        stats.time_resistance_refresh += time.perf_counter() - t0

    def _refresh_jacobian(self, q: np.ndarray, h: float, keep_resistance: bool, rotate: bool = True) -> None:
        """Factorise J = M/h^2 + K + P^T R P / h at q (with the resistance rebuilt at q unless kept; a kept
        one is rotated to q's orientation unless ``rotate`` is false, i.e. it was built at q)."""
        stats = self.state.stats
        try:
            if keep_resistance and self.hyd is not None and not rotate:
                Rq = self.hyd.dense()
            elif keep_resistance and self.hyd is not None:
                R = self.hyd.dense()
                Q = best_fit_rotation(self.x_hyd, nodes_of(q))[0]
                Rq = rotate_dense_blocks(R, Q, self.hyd.spin)
            else:
                self._refresh_hydro(q)
                Rq = self.hyd.dense()
        except HydroError as exc:
            raise StepFailed("hydrodynamic mobility", str(exc)) from None
        t0 = time.perf_counter()
        J = self.dense_jacobian(q, h, Rq)
        if not np.all(np.isfinite(J)):
            raise StepFailed("Jacobian", "non-finite entries in the Newton Jacobian")
        self.x_jac = nodes_of(q)
        self.lu = lu_factor(J, check_finite=False)
        self.piv1 = (self.lu[1] + 1).astype(np.int32)  # LAPACK's 1-based pivots (``chord_iteration``)
        self.lu_h = h
        self.extra_iterations = 0
        stats.jacobian_factorisations += 1
        stats.time_jacobian_refresh += time.perf_counter() - t0

    def dense_jacobian(self, q: np.ndarray, h: float, R: np.ndarray) -> np.ndarray:
        """The Newton Jacobian dr/dq = M/h^2 + K(q) + P^T R P / h + contact Hessian at q, prescribed DOFs as
        identity rows and columns, for the lab-frame resistance R (nv, nv) and the (effective) step h, s."""
        system, ctx = self.system, self.state.step_context(h)
        t, d1, d2, rt, m1, m2 = frames_at(q, ctx)
        J = assemble_dense_jacobian(elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, *system.rest),
                                    system.mass, h, R, system.vdofs)
        self.contact_set = None
        if ctx.contact is not None:
            nodes_c, blocks_c = active_contacts(q, ctx, system)
            add_blocks_to_dense(J, nodes_c, blocks_c, 4)
            self.contact_set = _contact_signature(nodes_c)
        for k in system.prescribed:
            J[k, :] = 0.0
            J[:, k] = 0.0
            J[k, k] = 1.0
        return J

    def begin_step(self, q_pred: np.ndarray, h: float) -> None:
        nm, p = self.system.numerics, self.system.params
        x_pred = nodes_of(q_pred)
        seen = self.state.stats.newton_iterations
        if not self.krylov and self.lu is not None:
            self.extra_iterations += max(seen - self._iterations_seen - 2, 0)
        self._iterations_seen = seen
        self.jac_fresh = False
        self.krylov = False
        fit = None  # best_fit_rotation(x_hyd, x_pred), computed once
        if nm.newton_krylov and self.hyd is not None and not nm.single_iteration:
            Qh, dev = fit = best_fit_rotation(self.x_hyd, x_pred)
            krylov, self.calm_steps = krylov_begins(self.since_hydro, nm.hydro_refresh_max_steps, dev,
                                                    nm.hydro_refresh_tol * p.rod_radius, self.calm_steps, self.lu_h,
                                                    h, nm.jacobian_refresh == "resistance")
            if krylov:
                # the shape has changed (or the chord step would need a new LU while the swimmer is not yet
                # cruising): rebuild the resistance at x_pred and solve this step by Newton-Krylov
                self._refresh_hydro(q_pred, lazy=True)
                try:
                    self.mobility.begin(self.hyd, q_pred, h)
                except KrylovFailed as exc:
                    raise StepFailed("preconditioner", str(exc)) from None
                self.krylov = True
                self.Qh = _EYE
                return
        if self.lu is None or not H_REUSE[0] <= h / self.lu_h <= H_REUSE[1]:
            self._refresh_jacobian(q_pred, h, keep_resistance=False)  # rebuilds the resistance at x_pred
            self.jac_fresh = True
        else:
            if self.since_hydro >= nm.hydro_refresh_max_steps:
                self._refresh_hydro(q_pred)
            else:
                Qh, dev = fit if fit is not None else best_fit_rotation(self.x_hyd, x_pred)
                if dev > nm.hydro_refresh_tol * p.rod_radius:
                    self._refresh_hydro(q_pred)
            if self.since_hydro == 0 and nm.jacobian_refresh == "resistance":
                # the shape has changed: the old Jacobian's elastic and hydrodynamic parts are both stale
                self._refresh_jacobian(q_pred, h, keep_resistance=True, rotate=False)
                self.jac_fresh = True
            elif self.extra_iterations >= LU_REFRESH_BUDGET:
                self._refresh_jacobian(q_pred, h, keep_resistance=True)
                self.jac_fresh = True
            elif nm.single_iteration or self._contacts_changed(q_pred, h):
                # one linearly implicit solve per step needs the current Jacobian, and so does a
                # contact that has started since the last factorisation
                self._refresh_jacobian(q_pred, h, keep_resistance=True)
                self.jac_fresh = True
        # a resistance rebuilt this step sits at x_pred already; otherwise reuse the fit above
        self.Qh = _EYE if self.since_hydro == 0 else Qh
        self.Qj = _EYE if self.jac_fresh else best_fit_rotation(self.x_jac, x_pred)[0]

    def _contacts_changed(self, q: np.ndarray, h: float) -> bool:
        ctx = self.state.step_context(h)
        if ctx.contact is None or ctx.contact.none:  # no candidates: no contact at all (an empty signature)
            return False
        # a contact the Jacobian lacks: its stiffness would be missing from the chord iteration. One
        # that has ended only leaves extra stiffness (slower, still contracting): no refresh for that
        now = _contact_signature(active_contacts(q, ctx, self.system)[0])
        return not now <= self.contact_set if self.contact_set is not None else bool(now)

    def resistance(self) -> StepResistance:
        """The resistance of this step: the kept LSBT operator, rotated by Qh to the step's orientation."""
        return StepResistance(self.hyd, self.Qh)

    def on_stall(self, q: np.ndarray, h: float) -> bool:
        """Refactorise the Jacobian at q (keeping this step's resistance); False if it was fresh."""
        if self.jac_fresh:
            return False
        self._refresh_jacobian(q, h, keep_resistance=True)
        self.Qj, self.jac_fresh = _EYE, True
        return True

    def end_step(self) -> None:
        self.since_hydro += 1


def _contact_signature(nodes: np.ndarray) -> frozenset:
    """The set of active contact interactions (their node quadruples)."""
    return frozenset(map(tuple, nodes.tolist()))


class BandedNewtonSolver:
    """Local RFT + Stokes head: block-diagonal resistance, exact banded Newton (O(N) per iteration). The compiled
    chord iteration (``chord_iteration.chord_solve``) takes its steps (``resistance`` and ``newton_terms``)."""

    krylov = False  # every step is a banded direct solve
    banded = True  # the chord iteration's increment is a banded Newton solve (``chord_iteration``)

    def __init__(self, system: SystemDescription, state: StepState, hydro: Hydrodynamics) -> None:
        self.system, self.state, self.hydro = system, state, hydro
        self.reset()

    def reset(self) -> None:
        self.local: LocalResistance | None = None
        self.blocks: np.ndarray | None = None
        self.terms: BandedNewtonTerms | None = None
        self.terms_h = -1.0

    def begin_step(self, q_pred: np.ndarray, h: float) -> None:
        stats = self.state.stats
        t0 = time.perf_counter()
        self.local = self.hydro.resistance_at(nodes_of(q_pred))
        self.blocks = self.local.blocks
        self.terms = None
        stats.resistance_refreshes += 1
        stats.time_resistance_refresh += time.perf_counter() - t0

    def resistance(self) -> StepResistance:
        """The resistance of this step: RFT blocks and the head's drag at the predicted geometry."""
        return StepResistance(self.local, _EYE)

    def newton_terms(self, h: float) -> BandedNewtonTerms:
        """The step's fixed parts of the banded Newton Jacobian at the effective step h (s) (made once per step)."""
        if self.terms is None or self.terms_h != h:
            local = self.local
            self.terms = BandedNewtonTerms(mass_h2=self.system.mass / h**2, blocks_h=self.blocks / h,
                                           first=local.first, head_t=local.drag_t / h, head_r=local.drag_r / h,
                                           jac_fresh=True)
            self.terms_h = h
        return self.terms

    def end_step(self) -> None:
        pass
