"""The force terms of the implicit step behind one interface, and the scene that sums them.

Each step of the simulator solves the residual of eqn (6) of Huang & Jawed 2020 with the hydrodynamic force
implicit in the velocity (``physics.simulator``, ``physics.solvers.implicit_residual``), divided by h^2:

    r(q) = M (q - q^ - h v^) / h^2  +  grad E_el(q)  +  grad E_c(q)  -  P^T G(q),   G = -R V,
           inertia                    elastic           contact          hydrodynamics
    V = P (q - q^) / h - omega e_s,

with q^, v^ and the effective step h from the time integrator (``time_integrator``), E_el the stretching, bending
and twisting energies of eqns (5a)-(5c), E_c the contact penalty (``contact``; not in the paper), R the
generalised resistance (eqns 8-13: LSBT + Higdon head, ``hydrodynamics``; or local resistive-force theory,
``rft``) and P the map from DOFs to generalised velocities (node velocities, then the head spin rate).

Every term is a ``ForceTerm``: ``force(q, ctx)`` is its part of r (ndof,) (N on positions, N m on twists; minus
the generalised force the term exerts, the inertial force M a for inertia) and ``jacobian_action(q, ctx, v)`` the
derivative of that part along v (ndof,): M v / h^2, K(q) v, K_c(q) v, P^T R P v / h. ``ctx`` is a
``StepContext``: the frozen description of the step being taken. A ``Scene`` is the list of terms a configuration
needs (``scene_for``): its residual is their sum with the prescribed DOFs' rows zeroed, its Jacobian action
the sum of theirs.

The elastic Hessian K is the DER Hessian (symmetric, banded): at the configuration where the step's frames were
last updated it is the symmetric part of the gradient's derivative; elsewhere it drops the frames' transport
(``tests/physics/test_time_integrator.py``). The other three actions are the exact derivatives of their forces.

The compiled solvers evaluate the same sums fused into single kernels: ``implicit_residual.internal_forces_at``
(elastic + contact forces), ``implicit_residual.assemble_residual`` (inertia + hydrodynamics + the sum),
``chord_iteration.chord_residual`` / ``chord_loop`` (the whole residual of a chord step),
``newton_krylov.mobility_residual`` / ``jacobian_vector`` (residual and Jacobian action in the mobility form,
where the flagellum's forces are unknowns beside q) and ``implicit_residual.assemble_dense_jacobian`` (the dense
Jacobian). ``tests/physics/test_force_terms.py`` checks each term against finite differences and the scene
against these kernels.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

import numpy as np
from numba import njit

from physics.forces.contact import contact_kernel
from physics.elastic import elastic_gradient_kernel, elastic_hessian_banded_kernel, rod_frames
from physics.model.geometry import nodes_array
from physics.hydro.hydrodynamics import ResistanceOperator
from physics.solvers.implicit_residual import (block_max_abs, contact_state_at, generalised_force, generalised_velocity,
                                       inertia_force)
from physics.solvers.newton_krylov import banded_matvec_add, contact_matvec_add
from physics.params import NumericsConfig, SwimmerParams
from physics.hydro.rft import local_drag_apply, rft_blocks, rft_coefficients
from physics.forces.step_context import (NO_BLOCKS, NO_NODES, StepContext, StepResistance, SystemDescription,
                                  active_contacts, compiled_contact_args, frames_at)

_EYE = np.eye(3)


class LocalResistance:
    """Block-diagonal resistance of local RFT (``rft``) plus the head's Stokes drag: R V (nv,) by
    ``rft.local_drag_apply`` (the compiled chord iteration's kernel too). blocks (M, 3, 3) N s/m for the flagellum
    nodes from node ``first``; drag_t N s/m (head translation), drag_r N m s (head spin, 0 when the head does not
    spin)."""

    def __init__(self, blocks: np.ndarray, first: int, drag_t: float, drag_r: float, spin: bool) -> None:
        self.blocks, self.first, self.drag_t, self.drag_r, self.spin = blocks, first, drag_t, drag_r, spin

    def apply(self, V: np.ndarray) -> np.ndarray:
        """R V (nv,): minus the hydrodynamic generalised force for generalised velocities V (nv,)
        (``rft.local_drag_apply``)."""
        return local_drag_apply(np.ascontiguousarray(V, dtype=np.float64), self.blocks, self.first, self.drag_t,
                                self.drag_r, self.spin)

    def dense(self) -> np.ndarray:
        """R (nv, nv)."""
        nv = 3 * (self.first + self.blocks.shape[0]) + (1 if self.spin else 0)
        R = np.zeros((nv, nv))
        for j, b in enumerate(self.blocks):
            k = 3 * (self.first + j)
            R[k:k + 3, k:k + 3] = b
        if self.first:
            R[0:3, 0:3] = self.drag_t * _EYE
        if self.spin:
            R[-1, -1] = self.drag_r
        return R


class ForceTerm(Protocol):
    """One term of the residual r(q) of eqn (6) (module doc). ``name`` labels it in a scene's results."""

    name: str

    def force(self, q: np.ndarray, ctx: StepContext) -> np.ndarray:
        """The term's part of r at q (ndof,): N on positions, N m on twists."""
        ...

    def jacobian_action(self, q: np.ndarray, ctx: StepContext, v: np.ndarray) -> np.ndarray:
        """d force / dq at q applied to v (ndof,) (the Newton Jacobian's part of this term)."""
        ...


class _Term:
    """``force`` from ``evaluate`` (force, byproduct): what the stepping keeps of an evaluation besides the force."""

    name = "term"

    def evaluate(self, q: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, Any]:
        raise NotImplementedError

    def force(self, q: np.ndarray, ctx: StepContext) -> np.ndarray:
        return self.evaluate(q, ctx)[0]


class Inertia(_Term):
    """M (q - q^ - h v^) / h^2 (eqn 6 divided by h^2, with the scheme's base values); Jacobian M / h^2."""

    name = "inertia"

    def __init__(self, mass: np.ndarray) -> None:
        self.mass = mass

    def evaluate(self, q: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, None]:
        return inertia_force(q, ctx.q_hat, ctx.v_hat, ctx.h, self.mass), None

    def jacobian_action(self, q: np.ndarray, ctx: StepContext, v: np.ndarray) -> np.ndarray:
        return self.mass / (ctx.h * ctx.h) * v


class Elastic(_Term):
    """grad (E_s + E_b + E_t) of eqns (5a)-(5c) with the frames transported from the step's start
    (``rod_frames``); Jacobian action K(q) v with the banded DER Hessian. ``evaluate``'s byproduct: the frames
    (t, d1, d2, ref_twist, m1, m2) at q."""

    name = "elastic"

    def __init__(self, rest: tuple) -> None:
        self.rest = rest

    def evaluate(self, q: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, tuple]:
        fr = rod_frames(q, *ctx.frames)
        return elastic_gradient_kernel(q, *fr[1:], *self.rest), fr  # the kernels take (d1, d2, ref_twist, m1, m2)

    def hessian_banded(self, q: np.ndarray, ctx: StepContext) -> np.ndarray:
        """K(q) in general-banded storage (21, ndof), N/m, N, N m (``physics.elastic``)."""
        return elastic_hessian_banded_kernel(q, *rod_frames(q, *ctx.frames)[1:], *self.rest)

    def jacobian_action(self, q: np.ndarray, ctx: StepContext, v: np.ndarray) -> np.ndarray:
        out = np.zeros(q.shape[0])
        banded_matvec_add(self.hessian_banded(q, ctx), np.ascontiguousarray(v, dtype=np.float64), out)
        return out


class Contact(_Term):
    """grad E_c of the head-rod and rod-rod penalty energies (``contact``) over the step's broad-phase candidates
    (a new broad phase where q has left their boxes, as ``implicit_residual.internal_forces_at`` does); Jacobian
    action from the 12x12 Hessian blocks of the active interactions. ``evaluate``'s byproduct: (contact state
    valid at q, energy J, active nodes (A, 4), blocks (A, 12, 12) N/m)."""

    name = "contact"

    def __init__(self, model: tuple, pos: np.ndarray) -> None:
        self.model, self.pos = model, pos

    def evaluate(self, q: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, tuple]:
        m, cstate = self.model, ctx.contact
        if block_max_abs(q - cstate.q, self.pos) > 0.5 * cstate.pad:  # the test of contact_state_at, uncompiled
            cstate = contact_state_at(q, m, cstate, ctx.q_start, self.pos, ctx.first_step)  # a new broad phase
        if cstate.none:  # no candidates: no contact
            return np.zeros(q.shape[0]), (cstate, 0.0, NO_NODES, NO_BLOCKS)
        out, e_c, nodes_c, blocks_c = contact_force(q, cstate.pairs, cstate.head_edges, m.head_radius, m.r0, m.eps,
                                                    m.stiffness)
        return out, (cstate, e_c, nodes_c, blocks_c)

    def jacobian_action(self, q: np.ndarray, ctx: StepContext, v: np.ndarray) -> np.ndarray:
        _, _, nodes_c, blocks_c = self.evaluate(q, ctx)[1]
        out = np.zeros(q.shape[0])
        contact_matvec_add(nodes_c, blocks_c, np.ascontiguousarray(v, dtype=np.float64), out)
        return out


@njit(cache=True)
def contact_force(q: np.ndarray, pairs: np.ndarray, head: np.ndarray, b: float, r0: float, eps: float,
                  k: float) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """``contact.contact_kernel`` at the nodes of q (ndof,) over the candidates (pairs (P, 2), head edges (H,)), its
    gradient in the DOF layout: (grad E_c (ndof,) N, E_c J, active nodes (A, 4), blocks (A, 12, 12) N/m)."""
    e_c, g, nodes, blocks = contact_kernel(nodes_array(q), pairs, b, head, r0, eps, k)
    out = np.zeros(q.shape[0])
    for i in range(g.shape[0] // 3):
        for m in range(3):
            out[4 * i + m] = g[3 * i + m]
    return out, e_c, nodes, blocks


class Hydrodynamics(_Term):
    """-P^T G = P^T R V (eqns 8-13), V = P (q - q^) / h - omega e_s, for the step's resistance ``ctx.resistance``
    (linear in q: the resistance is held at a geometry fixed for the step); Jacobian action P^T R P v / h.
    ``resistance_at`` builds this model's R at a geometry: LSBT + Higdon head (``hydrodynamics``) or, with
    ``model="rft"``, local resistive-force theory with the head's Stokes drag (``LocalResistance``)."""

    def __init__(self, params: SwimmerParams, numerics: NumericsConfig, vdofs: np.ndarray, head_spins: bool) -> None:
        self.params, self.numerics = params, numerics
        self.model = numerics.hydro_model
        self.name = "hydrodynamics"
        self.vdofs, self.spin = vdofs, head_spins
        self.first = 1 if params.has_head else 0
        if self.model == "rft":
            zeta_perp, zeta_par = rft_coefficients(params, numerics.rft_coefficients)
            # the calibrated factors (NumericsConfig.rft_scale_perp / rft_scale_par; 1 = Lighthill / Gray-Hancock)
            self.zeta = (zeta_perp * numerics.rft_scale_perp, zeta_par * numerics.rft_scale_par)

    def resistance_at(self, x: np.ndarray, lazy: bool = False) -> Any:
        """R_ref at nodes x (n, 3), m: a ``ResistanceOperator`` (LSBT; ``lazy``: Cholesky on first solve) or a
        ``LocalResistance`` (RFT). Raises ``hydrodynamics.HydroError`` for a degenerate LSBT mobility."""
        p, nm = self.params, self.numerics
        if self.model == "rft":
            blocks = rft_blocks(np.ascontiguousarray(x[self.first:]), *self.zeta)
            # the head: a Stokes sphere (6 pi mu b, 8 pi mu b^3), its translation drag times rft_head_drag_scale
            drag_t = 6.0 * np.pi * p.viscosity * p.head_radius * nm.rft_head_drag_scale
            return LocalResistance(blocks, self.first, drag_t,
                                   8.0 * np.pi * p.viscosity * p.head_radius**3 if self.spin else 0.0, self.spin)
        return ResistanceOperator(x, p.viscosity, p.cutoff_length, p.head_radius, self.spin, nm.lsbt_smoothing,
                                  head_coupling=nm.head_model == "higdon",
                                  near_radius=nm.near_field_radius * p.rod_radius,
                                  printed_head=p.head_rotation == "paper", factorize_lazily=lazy,
                                  spin_from_balance=p.head_rotation == "literal")

    def evaluate(self, q: np.ndarray, ctx: StepContext) -> tuple[np.ndarray, None]:
        res = ctx.resistance
        V = generalised_velocity(q, ctx.q_hat, ctx.h, self.vdofs, self.spin, ctx.omega, res.Q)
        return generalised_force(res.operator.apply(V), res.Q, self.vdofs, self.spin, q.shape[0]), None

    def jacobian_action(self, q: np.ndarray, ctx: StepContext, v: np.ndarray) -> np.ndarray:
        res = ctx.resistance
        v = np.ascontiguousarray(v, dtype=np.float64)
        V = generalised_velocity(v, np.zeros_like(v), ctx.h, self.vdofs, self.spin, 0.0, res.Q)  # Q~^T P v / h
        return generalised_force(res.operator.apply(V), res.Q, self.vdofs, self.spin, q.shape[0])


class SceneForces(NamedTuple):
    """A scene evaluated at q: the residual r (ndof,) (prescribed rows zero), each term's force and byproduct by
    name, and the wall seconds each term took."""

    r: np.ndarray
    forces: dict
    byproducts: dict
    seconds: dict


@dataclass(frozen=True, eq=False)
class Scene:
    """The force terms of a configuration. The residual adds their forces in the order of ``terms`` (left to
    right; ``scene_for`` puts elastic, contact, inertia, hydrodynamics, which reproduces the fused kernels' sum
    inertia + (elastic + contact) - f bit for bit) and zeroes the prescribed DOFs' rows."""

    terms: tuple
    prescribed: np.ndarray

    def term(self, name: str) -> ForceTerm:
        for t in self.terms:
            if t.name == name:
                return t
        raise KeyError(f"no term {name!r} in this scene; it has {[t.name for t in self.terms]}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.terms)

    def evaluate(self, q: np.ndarray, ctx: StepContext) -> SceneForces:
        """Every term's force at q and the residual r (``SceneForces``)."""
        forces, byproducts, seconds = {}, {}, {}
        r = None
        t0 = time.perf_counter()
        for t in self.terms:
            evaluate = getattr(t, "evaluate", None)
            f, extra = evaluate(q, ctx) if evaluate is not None else (t.force(q, ctx), None)
            t1 = time.perf_counter()
            name = t.name
            seconds[name], forces[name], byproducts[name] = t1 - t0, f, extra
            t0 = t1
            if r is None:
                r = f.copy()
            else:
                np.add(r, f, out=r)
        if self.prescribed.shape[0]:
            r[self.prescribed] = 0.0
        return SceneForces(r, forces, byproducts, seconds)

    def residual(self, q: np.ndarray, ctx: StepContext) -> np.ndarray:
        """r(q) (ndof,), N / N m: the sum of the terms' forces, prescribed DOFs' rows zero."""
        return self.evaluate(q, ctx).r

    def jacobian_action(self, q: np.ndarray, ctx: StepContext, v: np.ndarray) -> np.ndarray:
        """dr/dq v (ndof,): the sum of the terms' actions, prescribed rows zero (their columns are kept: the
        solvers' identity rows and columns are that with v zero on the prescribed DOFs)."""
        out = None
        for t in self.terms:
            a = t.jacobian_action(q, ctx, v)
            out = a if out is None else out + a
        out[self.prescribed] = 0.0
        return out


def scene_for(system: SystemDescription) -> Scene:
    """The terms the configuration needs: elastic (eqns 5a-5c), contact (when ``numerics.contact``), inertia,
    and the hydrodynamics of ``numerics.hydro_model`` (LSBT + head, or RFT)."""
    terms: list = [Elastic(system.rest)]
    if system.contact_model is not None:
        terms.append(Contact(system.contact_model, system.pos))
    terms.append(Inertia(system.mass))
    terms.append(Hydrodynamics(system.params, system.numerics, system.vdofs, system.head_spins))
    return Scene(tuple(terms), system.prescribed)


__all__ = ["Contact", "Elastic", "ForceTerm", "Hydrodynamics", "Inertia", "LocalResistance", "Scene", "SceneForces",
           "StepContext", "StepResistance", "SystemDescription", "active_contacts", "compiled_contact_args",
           "frames_at", "scene_for"]
