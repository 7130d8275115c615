"""The small frozen descriptions the force terms and the solvers work from (``physics.forces.force_terms``).

``SystemDescription``: the system being stepped, nothing that changes during a run (masses, DOF sets, rest arrays,
parameters). ``StepContext``: the step being taken (the time integrator's base values, the frames and configuration
of the step's start, the contact state, the step's hydrodynamic resistance). The helpers at the end give the
solvers what they take of a context: frames at an iterate, the active contacts, the compiled kernels' arguments.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from physics.forces.contact import NO_CONTACT_MODEL, NO_EDGES, NO_PAIRS, ContactParams, ContactState, contact_kernel
from physics.elastic import rod_frames
from physics.model.geometry import nodes_array
from physics.params import NumericsConfig, SwimmerParams

_EYE = np.eye(3)
NO_NODES = np.zeros((0, 4), dtype=np.int64)
NO_BLOCKS = np.zeros((0, 12, 12))


@dataclass(frozen=True, eq=False)
class SystemDescription:
    """What the terms and the solvers read of the system being stepped; nothing in it changes during a run.

    ndof = 4n - 1 DOFs (node positions m, twist angles rad, ``geometry``); nv generalised velocities."""

    params: SwimmerParams
    numerics: NumericsConfig
    mass: np.ndarray  # (ndof,) lumped masses of eqn (6), kg on positions, kg m^2 on twists
    vdofs: np.ndarray  # (nv,) the DOFs of the generalised velocities: node positions, then theta^0 if the head spins
    prescribed: np.ndarray  # Dirichlet DOFs (the motor's twist when the head does not spin)
    head_spins: bool  # the head's spin rate is the last generalised velocity
    pos: np.ndarray  # position DOFs
    twist: np.ndarray  # twist DOFs
    free_twist: np.ndarray  # twist DOFs that are not prescribed
    weights: np.ndarray  # (ndof,) 1/r0 on positions, 1 on twists: correction sizes in r0 and rad
    rest: tuple  # (l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ): the rest arrays of eqns (5a)-(5c)
    f_floor: float  # N: force scale below which the convergence test counts a force block as zero
    contact_model: ContactParams | None  # ``ContactModel.model`` when contact is on, else None

    @property
    def ndof(self) -> int:
        return int(self.mass.shape[0])

    @property
    def has_head(self) -> bool:
        return self.params.has_head


class StepResistance(NamedTuple):
    """The generalised resistance of a step, R = Q~ R_ref Q~^T: ``operator.apply(V)`` gives R_ref V (nv,) for
    velocities V in its reference frame (N s/m, N s, N m s); Q (3, 3) rotates node blocks from that frame to the
    lab (the rigid reuse of ``rigid_alignment``; the identity for a resistance built at the step's geometry)."""

    operator: Any  # ``hydrodynamics.ResistanceOperator`` or ``force_terms.LocalResistance``
    Q: np.ndarray = _EYE


class StepContext(NamedTuple):
    """The step being taken, as the force terms see it (immutable; a NamedTuple: made at every residual
    evaluation, in ~1 us). Arrays are not copied: do not change them."""

    q_hat: np.ndarray  # (ndof,) base configuration of the scheme, m / rad
    v_hat: np.ndarray  # (ndof,) base velocity, m/s / rad/s
    h: float  # effective step h_e of the scheme, s (``time_integrator``)
    omega: float  # motor speed, rad/s
    frames: tuple  # (d1 (n-1, 3), t (n-1, 3), ref_twist (n-2,)) at the step's start (``rod_frames``)
    q_start: np.ndarray  # (ndof,) configuration at the step's start
    first_step: bool  # the run's first step (the contact broad phase pads by nothing then)
    contact: ContactState | None  # the contact broad phase of the step (None: no contact)
    resistance: StepResistance | None  # the resistance of this step (None: no hydrodynamic term)


class StepSystem(NamedTuple):
    """What the compiled step kernels (``chord_iteration.chord_loop``, ``newton_krylov.newton_krylov_loop``) take of
    the ``SystemDescription``, with the motor speed of the step."""

    mass: np.ndarray  # (ndof,) lumped masses, kg / kg m^2
    vdofs: np.ndarray  # (nv,) the DOFs of the generalised velocities
    prescribed: np.ndarray  # Dirichlet DOFs
    head_spins: bool  # the head's spin rate is the last generalised velocity
    omega: float  # motor speed, rad/s
    pos: np.ndarray  # position DOFs
    twist: np.ndarray  # twist DOFs
    free_twist: np.ndarray  # twist DOFs that are not prescribed
    weights: np.ndarray  # (ndof,) 1/r0 on positions, 1 on twists


def step_system(system: SystemDescription, omega: float) -> StepSystem:
    """The ``StepSystem`` of ``system`` at the motor speed omega (rad/s)."""
    return StepSystem(mass=system.mass, vdofs=system.vdofs, prescribed=system.prescribed, head_spins=system.head_spins,
                      omega=omega, pos=system.pos, twist=system.twist, free_twist=system.free_twist,
                      weights=system.weights)


def frames_at(q: np.ndarray, ctx: StepContext) -> tuple:
    """(t, d1, d2, ref_twist, m1, m2) of q (ndof,), transported from the frames of the step's start."""
    return rod_frames(q, *ctx.frames)


def active_contacts(q: np.ndarray, ctx: StepContext, system: SystemDescription) -> tuple[np.ndarray, np.ndarray]:
    """Active contact interactions at q over the context's broad-phase candidates as they are (the caller knows
    them valid at q): node quadruples (A, 4) and Hessian blocks (A, 12, 12) N/m; none without contact or
    candidates."""
    if ctx.contact is None or ctx.contact.none:
        return NO_NODES, NO_BLOCKS
    m = system.contact_model
    return contact_kernel(nodes_array(q), ctx.contact.pairs, m.head_radius, ctx.contact.head_edges, m.r0, m.eps,
                          m.stiffness)[2:]


def compiled_contact_args(q: np.ndarray, ctx: StepContext,
                          system: SystemDescription) -> tuple[bool, ContactParams, ContactState]:
    """(contact on, model, contact state) as the compiled kernels take them (``implicit_residual.internal_forces_at``):
    placeholders without contact (the state's q: the iterate q)."""
    if ctx.contact is None:
        return False, NO_CONTACT_MODEL, ContactState(q, 0.0, NO_PAIRS, NO_EDGES, True)
    return True, system.contact_model, ctx.contact
