"""The swimmer simulator: a thin stateful shell around the pure physics functions.

Time stepping discretises eqn (6) of Huang & Jawed 2020 implicitly,

    M (q_{k+1} - q^ - h_e v^) / h_e^2 + grad E(q_{k+1}) + P^T R (P (q_{k+1} - q^)/h_e - omega e_s) = 0,

with the hydrodynamic force *implicit in the velocity* (the paper lags it, eqn 7, which is
unstable at h = 1 ms for this rod: h * drag / mass ~ 8 > 2). The base values q^, v^ and the
effective step h_e come from the scheme (``physics.integrate.time_integrator``): implicit Euler (the paper's,
``integrator="euler"``) or variable-step BDF of order up to 2, 3 or 4 (``bdf2``, ``bdf3``, ``bdf4``;
the presets ``faithful`` and ``fast`` use BDF3), with error-controlled steps inside each ``dt`` when
``step_tol`` > 0. R is the generalised resistance (``hydrodynamics`` for LSBT + head, ``rft`` for
local drag) evaluated at the predicted geometry. The nonlinear system is solved by Newton-type
iterations on the full residual, so a converged step solves eqn (6) up to the resistance's geometry
lag. With RFT every step is a Newton iteration on the exact banded Jacobian; with LSBT two regimes
(``step_solvers``): while the resistance is reused through a rigid rotation (steady swimming), the chord iteration
on the reused dense factorisation; both run as one compiled call per step attempt (``chord_iteration``); when the
LSBT resistance is rebuilt (the shape has changed: buckling, relaxation) and ``newton_krylov`` is on, Newton-Krylov
in the mobility form (``newton_krylov``: GMRES with a banded preconditioner, no dense factorisation). A failing
fixed step is halved up to ``max_substeps`` times, a failing adaptive step retried at a quarter, before a
``SimulationError`` names the step, time and quantity.

Contact (``physics.forces.contact``, on unless ``numerics.contact`` is false): head-rod and rod-rod
penalty energies join the elastic energy in eqn (6): their gradient is in the residual, their
Hessian in every Jacobian the solvers factorise. Their broad phase runs once per step, padded by the step's
predicted motion, and is redone within the step if an iterate leaves its boxes.

Motor (Sec. 2.5): the twist angle theta^0 of the first edge is the motor shaft.
* ``head_rotation="fixed"`` (default): the head does not spin; theta^0 = omega t (Dirichlet): omega is the flagellum's
  rate in the lab frame, as in the paper's figures (docs/validation.md).
* ``head_rotation="torque_free"`` (eqn 13): theta^0 = psi + omega t where psi is the
  head's spin angle; theta^0 is a free DOF whose generalised force includes the head's
  hydrodynamic axial torque at spin rate s = d(theta^0)/dt - omega. The elastic moment on
  theta^0 is the torque the motor passes from flagellum to head, so the head spins until
  the axial torques balance, as in eqn (13).
* ``head_rotation="literal"``: theta^0 = omega t (Dirichlet, the flagellum's rate in the lab frame) and the head
  spins at the rate eqn (13) gives for the flagellum's forces; its rotlet (eqn 10) acts on the flagellum
  (``hydrodynamics``: the mobility A + g w^T). ``head_spin_rate`` is that rate after each step.
* ``head_rotation="paper"``: as ``fixed``, with the head flow and force of eqns (10)-(11) as printed
  (``higdon_head.head_operators_as_printed``). ``numerics.head_model="stokes"`` keeps the head's own drag
  and drops its flow coupling with the flagellum (any reading).
* no head (b = 0): the first edge is a 2-delta motor shaft along the axis (``geometry``) with
  the Dirichlet twist theta = omega t; the base node translates freely.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from physics.elastic import rest_from_configuration, rod_frames
from physics.errors import SimulationError, StepFailed
from physics.model.geometry import edge_stretch_extremes, initial_nodes, layout_for, nodes_of, pack_q
from physics.model.body_frame import transported_body_frame
from physics.solvers.chord_iteration import chord_solve
from physics.forces.contact import NO_CONTACT_MODEL, NO_EDGES, NO_PAIRS, ContactModel, ContactParams, ContactState
from physics.forces.force_terms import scene_for
from physics.hydro.higdon_head import head_spin_map
from physics.solvers.implicit_residual import contact_candidates
from physics.solvers.krylov_span import SPAN_AFTER_ACCEPT, SPAN_DONE, krylov_span_applies, run_krylov_span
from physics.params import NumericsConfig, SwimmerParams, check_combination
from physics.forces.step_context import StepContext, SystemDescription
from physics.solvers.step_solvers import BandedNewtonSolver, DenseChordSolver
from physics.threads import one_blas_thread
from physics.integrate.adaptive_state import AdaptiveState
from physics.integrate.adaptive_step import accepted_step, commit_point, local_error, rejected_step, step_start
from physics.integrate.time_integrator import (COLLAPSED_STEPS, MAX_STEPS_PER_SPAN, SCHEME_ORDER, ContractionRate,
                                              StepBase, split_remaining, step_spans)


@dataclass
class StepStats:
    """Counters for benchmarks: Newton iterations, resistance refreshes, Jacobian factorisations."""

    steps: int = 0
    newton_iterations: int = 0
    resistance_refreshes: int = 0
    jacobian_factorisations: int = 0  # dense LUs (direct solver) or banded Newton solves (rft)
    preconditioner_factorisations: int = 0  # set-ups of the Newton-Krylov preconditioner (two banded factorisations)
    krylov_iterations: int = 0  # GMRES iterations of the Newton-Krylov steps
    krylov_steps: int = 0  # steps solved by Newton-Krylov (the rest by the chord iteration)
    halvings: int = 0
    substeps: int = 0  # accepted integration steps (= steps with fixed steps and no halving)
    rejected_steps: int = 0  # adaptive steps retried smaller (error too large or Newton failure)
    order_reductions: int = 0  # times the order was held at 2 after its steps collapsed (``time_integrator``)
    # wall seconds spent in the refreshes (the compiled chord and Newton-Krylov iterations are not split into parts)
    time_resistance_refresh: float = 0.0  # LSBT mobility + Cholesky
    time_jacobian_refresh: float = 0.0  # elastic Hessian, dense R, LU


def lumped_masses(params: SwimmerParams, l_bar: np.ndarray, ndof: int, head_spins: bool) -> np.ndarray:
    """Diagonal of the lumped mass matrix M of eqn (6): kg for positions, kg m^2 for twists."""
    rho, A, r0 = params.density, params.area, params.rod_radius
    n = (ndof + 1) // 4
    m = np.zeros(ndof)
    rod_len = l_bar.copy()
    if params.has_head:
        rod_len[0] = 0.0  # edge e0 lies inside the head
    node_len = np.zeros(n)
    node_len[:-1] += rod_len / 2
    node_len[1:] += rod_len / 2
    node_m = rho * A * node_len
    twist_i = rho * math.pi * r0**4 / 2.0 * np.maximum(rod_len, 0.0)
    if params.has_head:
        m_head = rho * 4.0 / 3.0 * math.pi * params.head_radius**3
        node_m[0] = m_head
        twist_i[0] = 0.4 * m_head * params.head_radius**2 if head_spins else 1.0
    for k in range(3):
        m[k::4] = node_m
    m[3::4] = twist_i
    return m


from physics.params import RPM_TO_RAD_S  # noqa: E402  (kept apart: the motor-speed rule of the command line)
from physics.schedule import MAX_RPM  # noqa: E402


class Simulator:
    """Head + flagellum swimmer (Huang & Jawed 2020). SI units throughout.

    The equations of motion are eqn (6) with the hydrodynamic force implicit in the velocity (module doc). Its
    terms are the scene's (``self.scene``, ``physics.forces.force_terms``): elastic (eqns 5a-5c), contact (when
    ``numerics.contact``), inertia, and LSBT + head (eqns 8-13) or local RFT drag; the solvers read the static
    ``self.system`` (``physics.forces.step_context.SystemDescription``) and each step's ``step_context(h)``.

    Integrator (``physics.integrate.time_integrator``): ``numerics.integrator`` = implicit Euler (the paper's) or
    variable-step BDF of order up to 2, 3 or 4 (``faithful``: BDF3). With ``step_tol`` > 0 every ``dt`` is
    covered by error-controlled steps (Milne's estimate, node positions in r0 and twists in rad; the order
    ramps up from implicit Euler at ``h_start`` after each start or motor-speed change; a step is retried at a
    smaller h when the estimate or the solve fails); with ``step_tol`` = 0 by one step of dt, halved up to
    ``max_substeps`` times. Each step solves the residual at the scheme's base values q^, v^ and effective step
    h_e, by one of two solvers (``physics.solvers.step_solvers``):

    * while the LSBT resistance is reused through a rigid rotation (steady swimming): the chord iteration on
      the reused dense LU of M/h^2 + K + P^T R P / h, rotated with the swimmer, compiled end to end
      (``chord_iteration``);
    * with RFT (``hydro_model="rft"``): Newton on the exact banded Jacobian, refactorised at every iteration,
      compiled end to end by the same loop (``chord_iteration``);
    * when the resistance is rebuilt (the shape changed non-rigidly by more than ``hydro_refresh_tol`` r0:
      buckling, relaxation) and ``newton_krylov`` is on: Newton-Krylov in the mobility form, the flagellum's
      forces unknowns beside q, GMRES with a banded preconditioner, no dense factorisation (``newton_krylov``);
      a run of such steps is one compiled call (``krylov_span``: base, broad phase, resistance, preconditioner,
      iteration, error estimate, controller and commit; bit-identical to the Python step, which it hands every
      other attempt back to).

    >>> sim = Simulator(SwimmerParams(), NumericsConfig())
    >>> sim.set_motor_speed(10 * RPM_TO_RAD_S); sim.advance(1.0)
    """

    def __init__(self, params: SwimmerParams | None = None, numerics: NumericsConfig | None = None) -> None:
        for name, value, cls in (("params", params, SwimmerParams), ("numerics", numerics, NumericsConfig)):
            if value is not None and not isinstance(value, cls):
                raise ValueError(f"{name}={value!r} is not allowed; allowed: a {cls.__name__} (physics.configure "
                                 "gives one from a preset and overrides) or None for the defaults")
        self.params = params or SwimmerParams()
        self.numerics = numerics or NumericsConfig()
        p = self.params
        self.layout = layout_for(p)
        n = self.layout.n
        q0 = pack_q(initial_nodes(p), np.zeros(n - 1))
        ea = np.full(n - 1, p.stretching_stiffness)
        ei = np.full(n - 2, p.bending_stiffness)
        gj = np.full(n - 2, p.twisting_stiffness)
        self.rest, d1, _, ref_twist = rest_from_configuration(q0, ea, ei, gj)
        check_combination(p, self.numerics)
        self.head_spins = p.has_head and p.head_rotation == "torque_free"
        #: the literal reading: the head spins per eqn (13) without being a DOF (module doc)
        self.head_spins_from_balance = p.has_head and p.head_rotation == "literal"
        self.mass = lumped_masses(p, self.rest.l_bar, self.layout.ndof, self.head_spins)
        self._pos = self.layout.position_dofs()
        self.vdofs = np.concatenate([self._pos, [3]]) if self.head_spins else self._pos
        self.prescribed = np.array([], dtype=np.int64) if self.head_spins else np.array([3])
        self._twist = np.arange(3, self.layout.ndof, 4)
        self._free_twist = np.setdiff1d(self._twist, self.prescribed)
        # the error norm's weights: positions in units of r0, twists in radians
        self._weights = np.where(np.arange(self.layout.ndof) % 4 == 3, 1.0, 1.0 / p.rod_radius)
        self.rest_arrays = (self.rest.l_bar, self.rest.l_vor, self.rest.kappa_bar, self.rest.twist_bar,
                             self.rest.EA, self.rest.EI, self.rest.GJ)
        # state
        self.q = q0
        self.v = np.zeros_like(q0)
        self.d1 = d1
        self.tangent = self._tangents(q0)
        self.ref_twist = ref_twist
        self.time = 0.0
        self.step_count = 0
        self.omega = 0.0
        self.motor_angle = 0.0
        self.body_frame = np.eye(3)  # columns X_b, Y_b, Z_b in the lab frame
        self.stats = StepStats()
        #: the step-size controller's state between steps (``physics.integrate.adaptive_state``): the accepted
        #: points for BDF and the error estimate, restarted at every kink of the motion, the next step, the force
        #: points; read and written by the Python step and by the compiled span (``krylov_span``)
        self.adaptive = AdaptiveState.empty(self.numerics.h_start, self.layout.ndof, n)
        self._base: StepBase | None = None
        self.contraction = ContractionRate()  # the nonlinear iteration's convergence test (adaptive steps)
        # observables of the last step
        self.node_forces = np.zeros((n, 3))  # hydrodynamic force on each node, N
        self.head_axial_torque = 0.0
        self.head_spin_rate = 0.0  # rad/s about the head axis t^0 (torque_free, literal; 0 for a head held still)
        self.motor_torque = 0.0
        self.contact = (ContactModel(self.rest.l_bar, p.rod_radius, p.head_radius, self.numerics.contact_margin,
                                     self.numerics.contact_stiffness) if self.numerics.contact else None)
        self.contact_energy = 0.0  # J, at the last step
        self.contact_count = 0  # active contact interactions at the last step
        self.last_contact = (0.0, 0)  # (J, count) of the last evaluation (``contact_energy``: the last step's)
        #: this step's contact broad phase (``implicit_residual.contact_candidates``), none before the first step
        self._contact = ContactState(q0, 0.0, NO_PAIRS, NO_EDGES, True)
        self._f_floor = 1e-9 * p.bending_stiffness / p.axial_length**2
        #: the static description of the system that the force terms and the solvers read
        self.system = SystemDescription(
            params=p, numerics=self.numerics, mass=self.mass, vdofs=self.vdofs, prescribed=self.prescribed,
            head_spins=self.head_spins, pos=self._pos, twist=self._twist, free_twist=self._free_twist,
            weights=self._weights, rest=self.rest_arrays, f_floor=self._f_floor,
            contact_model=self.contact.model if self.contact is not None else None)
        #: the force terms of eqn (6) this configuration needs (``physics.forces.force_terms``)
        self.scene = scene_for(self.system)
        #: the step's solver (``step_solvers``): the chord iteration's caches, the resistance, Newton-Krylov's step
        solver = DenseChordSolver if self.numerics.hydro_model == "lsbt" else BandedNewtonSolver
        self.solver = solver(self.system, self, self.scene.term("hydrodynamics"))
        #: runs of Newton-Krylov steps in one compiled call where it applies (False: always the Python step)
        self.compiled_span = True
        self._initial_nodes = nodes_of(q0)
        self._initial_span = float(np.linalg.norm(self._initial_nodes[-1] - self._initial_nodes[0]))  # L, m

    # --- public API -----------------------------------------------------------------
    def set_motor_speed(self, omega_rad_s: float) -> None:
        """Set the motor speed omega (rad/s, the flagellum's rate relative to the head, which is its lab rate unless
        ``head_rotation="torque_free"``): finite, >= 0 and at most
        ``physics.schedule.MAX_RPM`` (the rule of the command line and of motor schedules)."""
        if (isinstance(omega_rad_s, bool) or not isinstance(omega_rad_s, numbers.Real)
                or not 0.0 <= omega_rad_s <= MAX_RPM * RPM_TO_RAD_S):
            raise ValueError(f"motor speed {omega_rad_s!r} rad/s is not allowed; allowed: a finite speed >= 0 and "
                             f"<= {MAX_RPM * RPM_TO_RAD_S:.6g} rad/s ({MAX_RPM:g} rpm)")
        if float(omega_rad_s) != self.omega:
            self.adaptive.kink()  # the motion has a kink here: no multistep formula may cross it
        self.omega = float(omega_rad_s)

    @one_blas_thread
    def step(self, duration_s: float | None = None) -> None:
        """Advance by ``numerics.dt``: one step (halved on Newton failure), or with ``step_tol`` > 0 as many
        error-controlled steps as that takes, the last one ending exactly at the end of dt.

        ``duration_s`` (adaptive stepping only): advance by this span (s, 0 < span <= dt) instead of dt."""
        if self.numerics.step_tol > 0.0:
            span = self.numerics.dt if duration_s is None else float(duration_s)
            if not 0.0 < span <= self.numerics.dt * (1.0 + 1e-12):
                raise ValueError(f"step duration {duration_s!r} s is not allowed; allowed: > 0 and <= dt = "
                                 f"{self.numerics.dt:g} s")
            self._adaptive(span)
        elif duration_s is not None and duration_s != self.numerics.dt:
            raise ValueError(f"step duration {duration_s!r} s is not allowed with fixed steps; allowed: dt = "
                             f"{self.numerics.dt:g} s (or set step_tol > 0)")
        else:
            self._advance(self.numerics.dt, 0)
        self.step_count += 1
        self.stats.steps += 1

    @one_blas_thread
    def advance(self, duration_s: float) -> None:
        """Advance by ``duration_s`` seconds: rounded to whole steps of dt with fixed steps, exactly with
        adaptive ones (whole steps of dt, then the rest). ``duration_s``: a finite time >= 0 s."""
        if (isinstance(duration_s, bool) or not isinstance(duration_s, numbers.Real) or not math.isfinite(duration_s)
                or duration_s < 0.0):
            raise ValueError(f"duration_s={duration_s!r} is not allowed; allowed: a finite time >= 0 s")
        for span in step_spans(duration_s, self.numerics):
            self.step(span)

    _STATE_FIELDS = ("q", "v", "d1", "tangent", "ref_twist", "time", "step_count", "omega", "motor_angle",
                     "body_frame")

    def get_state(self) -> dict:
        """A copy of the dynamic state (arrays and scalars); restore it with ``set_state``."""
        return {k: (getattr(self, k).copy() if isinstance(getattr(self, k), np.ndarray) else getattr(self, k))
                for k in self._STATE_FIELDS}

    def set_state(self, state: dict) -> None:
        """Restore a state from ``get_state`` (of a simulator with the same parameters)."""
        missing = [k for k in self._STATE_FIELDS if k not in state]
        if missing:
            raise ValueError(f"state is missing {missing}")
        if np.shape(state["q"]) != self.q.shape:
            raise ValueError(f"state has {np.shape(state['q'])} DOFs, this simulator {self.q.shape}")
        for k in self._STATE_FIELDS:
            v = state[k]
            setattr(self, k, np.array(v, dtype=float) if isinstance(v, np.ndarray) else v)
        self.step_count = int(self.step_count)
        self.solver.reset()  # factorisations are rebuilt at the next step
        self.adaptive.reset(self.numerics.h_start)

    @property
    def nodes(self) -> np.ndarray:
        """Node positions (n,3), m (head centre first when there is a head)."""
        return nodes_of(self.q)

    @property
    def head_position(self) -> np.ndarray:
        """Head centre (or base node if b = 0), (3,), m."""
        return self.q[0:3].copy()

    @property
    def head_velocity(self) -> np.ndarray:
        """Head (base node) velocity in the lab frame, (3,), m/s."""
        return self.v[0:3].copy()

    @property
    def head_orientation(self) -> np.ndarray:
        """Rotation matrix (3,3) whose columns are the body axes X_b, Y_b, Z_b in the lab frame."""
        return self.body_frame.copy()

    def end_to_end_ratio(self) -> float:
        """L'/L: first-to-last node distance over its undeformed value (Sec. 2.5). The end nodes are q's first and
        last three entries; sqrt of the dot product is what ``np.linalg.norm`` computes for a vector."""
        d = self.q[-3:] - self.q[0:3]
        return math.sqrt(float(d @ d)) / self._initial_span

    def displacement(self) -> float:
        """||s||: distance of the head (base node) from its initial position, m."""
        return float(np.linalg.norm(self.q[0:3] - self._initial_nodes[0]))

    @property
    def motor_power(self) -> float:
        """Motor power T * omega, W."""
        return self.motor_torque * self.omega

    def reynolds_number(self) -> float:
        """rho * max node speed * r0 / mu (reduces to the paper's rho omega R r0 / mu)."""
        p = self.params
        v = np.stack([self.v[0::4], self.v[1::4], self.v[2::4]], axis=1)
        return float(p.density * np.sqrt((v**2).sum(axis=1)).max() * p.rod_radius / p.viscosity)

    # --- internals ------------------------------------------------------------------
    @staticmethod
    def _tangents(q: np.ndarray) -> np.ndarray:
        e = np.diff(nodes_of(q), axis=0)
        return e / np.linalg.norm(e, axis=1)[:, None]

    def frames_at(self, q: np.ndarray):
        """(t, d1, d2, ref_twist, m1, m2) of q, transported from the start-of-step frames."""
        return rod_frames(q, self.d1, self.tangent, self.ref_twist)

    def min_gaps(self) -> tuple[float, float]:
        """(smallest rod-rod gap d - 2 r0 over non-adjacent edges, smallest head gap d - b - r0), m,
        of the current shape (a diagnostic over all pairs; see ``physics.forces.contact``)."""
        model = self.contact or ContactModel(self.rest.l_bar, self.params.rod_radius, self.params.head_radius,
                                             self.numerics.contact_margin, self.numerics.contact_stiffness)
        return model.gaps(self.nodes)

    def contact_state(self, q: np.ndarray) -> tuple[ContactParams, ContactState]:
        """(contact model, contact state) as the compiled kernels take them (``internal_forces_at``); placeholders
        without contact (q: the iterate)."""
        if self.contact is None:
            return NO_CONTACT_MODEL, ContactState(q, 0.0, NO_PAIRS, NO_EDGES, True)
        return self.contact.model, self._contact

    def keep_contact_state(self, cstate: ContactState, energy: float, count: int) -> None:
        """Store the contact state a compiled kernel returns and the last evaluation's contact energy (J) and
        number of active interactions (no-op without contact)."""
        if self.contact is not None:
            self._contact = cstate
            self.last_contact = (energy, count)

    nodes_at = staticmethod(nodes_of)

    def step_context(self, h: float) -> StepContext:
        """The step being taken as the force terms see it (``physics.forces.force_terms``), at the effective step h (s):
        the scheme's base values, the frames and configuration of the step's start, the current contact state and
        the solver's resistance for this step."""
        b = self._base
        return StepContext(b.q_hat, b.v_hat, h, self.omega, (self.d1, self.tangent, self.ref_twist), self.q,
                           self.step_count == 0, self.contact_state(self.q)[1] if self.contact is not None else None,
                           self.solver.resistance())

    def _euler_base(self, h: float) -> StepBase:
        """Implicit Euler from the current state, started from the constant-acceleration predictor of the
        last two steps (first step: constant velocity)."""
        v_prev = self.adaptive.v_prev
        q = self.q + h * (2.0 * self.v - v_prev) if v_prev is not None else self.q + h * self.v
        return StepBase(h, h, self.q, self.v, q, 1, None)

    def _step_start(self, base: StepBase) -> np.ndarray:
        """Begin a step from ``base``: the iteration's start (ndof,), the predictor with the motor's prescribed twist
        at the step's end, and this step's contact broad phase around it."""
        self._base = base
        q = step_start(base.q_pred, self.q, self.prescribed, base.h, self.omega)
        if self.contact is not None:  # its iterates stay within twice the predicted motion of any node
            self._contact = contact_candidates(q, self.contact.model, self.q, self._pos, self.step_count == 0)
        return q

    def _try_step(self, base: StepBase):
        p = self.params
        q = self._step_start(base)
        h = base.h_eff  # the solvers see the effective step of the scheme (physics.integrate.time_integrator)
        self.solver.begin_step(q, h)
        if self.solver.krylov:  # the resistance was rebuilt: Newton-Krylov in the mobility form
            self.stats.krylov_steps += 1
            first = 1 if p.has_head else 0
            forces = self.adaptive.force_start(self.time + base.h)
            if forces is None:  # the last forces where no accepted point since the restart
                forces = self.node_forces.ravel()
            return self.solver.mobility.solve(q, -forces[3 * first:], h)
        return self._chord_step(q, h)

    def _chord_step(self, q: np.ndarray, h: float):
        """The chord iteration of a step from the predictor q (ndof,) at the effective step h (s), compiled
        (``chord_iteration.chord_solve``: LSBT's dense chord iteration or RFT's banded Newton one; one solve from
        the predictor with ``single_iteration``). Returns (q, r, grad, f, (t, d1, ref_twist)); raises
        ``StepFailed``. Its Python reference, bit for bit: tests/physics/chord_reference.py."""
        return chord_solve(self, q, h)

    def _base_for(self, h: float) -> StepBase:
        if self.adaptive.restart:
            self.adaptive.restart_at(self.time, self.q, self.v)
        top = SCHEME_ORDER[self.numerics.integrator]
        return self.adaptive.base(h, min(top, 2) if self.adaptive.order_capped else top)

    def _advance(self, h: float, level: int) -> None:
        """Fixed steps: one step of h, halved (recursively) on failure."""
        try:
            base = self._euler_base(h) if self.numerics.integrator == "euler" else self._base_for(h)
            q, r, grad, f, (t, d1, rt) = self._try_step(base)
            self._check_state(q, t)
        except StepFailed as exc:
            if level >= self.numerics.max_substeps:
                raise SimulationError(str(exc) + f" (after {level} halvings of the time step)",
                                      self.step_count, self.time, exc.quantity) from None
            self.stats.halvings += 1
            self._advance(h / 2, level + 1)
            self._advance(h / 2, level + 1)
            return
        self._commit(q, base, grad, f, t, d1, rt)

    def _adaptive(self, dt: float) -> None:
        """Error-controlled steps (physics.integrate.time_integrator) that end exactly at time + dt. Runs of
        Newton-Krylov steps go to one compiled call (``krylov_span``, bit-identical), which hands any other attempt
        back here."""
        nm = self.numerics
        t_end = self.time + dt
        rejected = False
        accepted = 0
        while t_end - self.time > 1e-9 * dt:
            if krylov_span_applies(self):
                code, accepted, rejected, (h, err, order) = run_krylov_span(self, t_end, dt, accepted, rejected)
                if code == SPAN_AFTER_ACCEPT:
                    self._after_accept(h, err, order, accepted, dt, t_end)
                if code in (SPAN_DONE, SPAN_AFTER_ACCEPT):
                    continue
            if self.adaptive.restart:
                self.adaptive.h = min(nm.h_start, dt)
            h = split_remaining(self.adaptive.h, t_end - self.time, stretch=not rejected)
            rejected = True  # until the step is accepted
            last = h == t_end - self.time
            base = self._base_for(h)
            try:
                q, r, grad, f, (t, d1, rt) = self._try_step(base)
                self._check_state(q, t)
                err = local_error(q, base.q_pred, -1.0 if base.error_ratio is None else base.error_ratio,
                                  self._weights, nm.step_tol)
            except StepFailed as exc:
                self._reject(h / 4.0, exc.quantity, str(exc))
                continue
            if err > 1.0:
                self._reject(rejected_step(h, err, base.order), "local error",
                             f"estimated local error {err * nm.step_tol:.3g} (r0 or rad) above step_tol")
                continue
            rejected = False
            self._commit(q, base, grad, f, t, d1, rt, t_new=t_end if last else None)
            accepted += 1
            self._after_accept(h, err, base.order, accepted, dt, t_end)

    def _after_accept(self, h: float, err: float, order: int, accepted: int, dt: float, t_end: float) -> None:
        """After the ``accepted``-th step of the span ending at t_end (s), of length h (s), error ratio err at
        ``order``: the collapse and work limits, then the next step's length."""
        nm = self.numerics
        if accepted == COLLAPSED_STEPS and order > 2:
            # BDF3/4 are not A-stable (``COLLAPSED_STEPS``): restart (implicit Euler at h_start damps what the
            # collapse excited) and go on with BDF2, A-stable, until the motor speed changes
            self.adaptive.order_capped = self.adaptive.restart = True
            self.adaptive.h = nm.h_start
            self.adaptive.force_count = 0
            self.stats.order_reductions += 1
        elif accepted >= MAX_STEPS_PER_SPAN:
            raise SimulationError(f"too much work: {accepted} steps in {self.time - (t_end - dt):.3g} s of a "
                                  f"{dt:g} s span (last step {h:.3g} s)", self.step_count, self.time, "step size")
        self.adaptive.h = accepted_step(h, err, order, self.adaptive.h, dt, not self.solver.krylov)

    def _reject(self, h_new: float, quantity: str, why: str) -> None:
        self.stats.rejected_steps += 1
        if h_new < self.numerics.h_min:
            raise SimulationError(f"{why}; the step would fall below h_min = {self.numerics.h_min:g} s",
                                  self.step_count, self.time, quantity)
        self.adaptive.h = h_new

    def _spin_from_balance(self, q: np.ndarray) -> float:
        """The head's spin rate (rad/s) of eqn (13) at the accepted q for the flagellum's hydrodynamic forces of the
        step (``node_forces``): s = w . y with y = -F (``higdon_head.head_spin_map``)."""
        x = nodes_of(q)
        e0 = x[1] - x[0]
        w = head_spin_map(np.ascontiguousarray(x[1:]), x[0].copy(), e0 / math.sqrt(e0 @ e0), self.params.head_radius,
                          self.params.viscosity)
        return float(-w @ self.node_forces[1:].ravel())

    def _check_state(self, q: np.ndarray, t: np.ndarray) -> None:
        finite, i_min, r_min, i_max, r_max = edge_stretch_extremes(q, self.rest.l_bar)
        if not finite:
            raise StepFailed("positions", "non-finite node positions")
        if r_min < 0.2 or r_max > 5.0:
            i, ratio = (i_min, r_min) if r_min < 0.2 else (i_max, r_max)
            raise StepFailed("edge length", f"edge {i} has {ratio:.3g} x its rest length")

    def _commit(self, q, base: StepBase, grad, f, t, d1, rt, t_new: float | None = None) -> None:
        h = base.h
        st = self.adaptive
        dq3 = q[3] - self.q[3]  # the motor's DOF: the head's or the flagellum's first twist
        st.v_prev = self.v if h == st.h_prev else None
        st.h_prev = h
        self.time = self.time + h if t_new is None else t_new
        self.node_forces = nodes_of(f)  # the (n, 3) node blocks of f
        self.v, st.count, st.force_count = commit_point(
            q, self.q, base.q_hat, h, base.h_eff, base.order, self.time,
            self.numerics.integrator != "euler" or self.numerics.step_tol > 0.0, st.times, st.qs, st.vs, st.count,
            self.node_forces.ravel(), st.force_times, st.force_values, st.force_count)
        self.q = q
        self.tangent, self.d1, self.ref_twist = t, d1, rt
        self.stats.substeps += 1
        self.motor_angle += h * self.omega
        self.solver.end_step()
        self.head_axial_torque = float(f[3]) if self.head_spins else 0.0
        self.motor_torque = float(grad[3])
        if self.head_spins_from_balance:
            self.head_spin_rate = self._spin_from_balance(q)
            dpsi = h * self.head_spin_rate
        else:
            dpsi = dq3 - h * self.omega
            self.head_spin_rate = dpsi / h if self.head_spins else 0.0
        self.body_frame = transported_body_frame(self.body_frame, q[0:3], q[4:7], dpsi,
                                                 self.head_spins or self.head_spins_from_balance)
        if self.contact is not None:
            self.contact_energy, self.contact_count = self.last_contact
