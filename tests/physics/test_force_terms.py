"""The force terms of eqn (6) behind one interface (physics/forces/force_terms.py): each term's Jacobian action against
central differences of its force on bent, buckled configurations; the scene's residual against the fused compiled
kernels the solvers run (bit for bit) with and without contact, head, LSBT and RFT; the scene's Jacobian action
against the direct solver's assembled dense Jacobian, the mobility form's Jacobian-vector product and the RFT
solver's banded Newton matrix."""

from __future__ import annotations

import numpy as np
import pytest

from physics import Simulator, advance, configure
from physics.forces.force_terms import Contact, Elastic, Hydrodynamics, Inertia, Scene, StepResistance, scene_for
from physics.solvers.implicit_residual import (assemble_residual, generalised_velocity, internal_forces_at,
                                       rotate_dense_blocks)
from physics.solvers.newton_krylov import head_flow_apply
from physics.params import RPM_TO_RAD_S
from physics.forces.step_context import compiled_contact_args
from tests.physics.chord_reference import increment, scene_residual

CASES = {
    # name: (overrides, rpm, seconds); N = 40 nodes, the faithful preset (BDF3, Newton-Krylov where the shape changes)
    "torque-free head, contact": ({"head_rotation": "torque_free"}, 150, 1.0),
    "fixed head 300 rpm, contact active": ({"head_rotation": "fixed"}, 300, 1.8),
    "no contact": ({"contact": False, "head_rotation": "torque_free"}, 150, 1.0),
    "no head": ({"head_radius": 0.0}, 150, 1.0),
    "head as printed": ({"head_rotation": "paper"}, 150, 1.0),
    "literal head (spin from eqn 13)": ({"head_rotation": "literal"}, 150, 1.0),
    "rft, torque-free head": ({"hydro_model": "rft", "head_rotation": "torque_free"}, 150, 1.0),
    "rft, fixed head 300 rpm, contact active": ({"hydro_model": "rft", "head_rotation": "fixed"}, 300, 2.6),
    "rft, no head, no contact": ({"hydro_model": "rft", "head_radius": 0.0, "contact": False}, 150, 1.0),
}
_SIMS: dict[str, Simulator] = {}


def _sim(name: str) -> Simulator:
    """A simulator of the case after its run from rest (cached: each test opens a step of its own)."""
    if name not in _SIMS:
        overrides, rpm, seconds = CASES[name]
        p, n = configure("faithful", {"n_nodes": 40, **overrides})
        sim = Simulator(p, n)
        sim.set_motor_speed(rpm * RPM_TO_RAD_S)
        advance(sim, seconds)
        _SIMS[name] = sim
    return _SIMS[name]


def _open_step(sim: Simulator, h: float = 0.01):
    """Set up a step of h from the current state as ``Simulator._try_step`` does; returns (q_pred, context)."""
    base = sim._base_for(h)
    q = sim._step_start(base)
    sim.solver.begin_step(q, base.h_eff)
    return q, sim.step_context(base.h_eff)


def _direction(sim: Simulator, seed: int) -> np.ndarray:
    """A random direction (ndof,): r0-sized on positions, 1 rad on twists, zero on the prescribed DOFs."""
    rng = np.random.default_rng(seed)
    v = rng.normal(size=sim.q.size) * np.where(np.arange(sim.q.size) % 4 == 3, 1.0, sim.params.rod_radius)
    v[sim.prescribed] = 0.0
    return v


def _central(f, q: np.ndarray, v: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    return (f(q + eps * v) - f(q - eps * v)) / (2.0 * eps)


def test_the_scene_has_the_terms_the_configuration_needs():
    for name, expected in (("torque-free head, contact", ("elastic", "contact", "inertia", "hydrodynamics")),
                           ("no contact", ("elastic", "inertia", "hydrodynamics"))):
        assert _sim(name).scene.names == expected
    assert _sim("rft, torque-free head").scene.term("hydrodynamics").model == "rft"
    assert _sim("torque-free head, contact").scene.term("hydrodynamics").model == "lsbt"
    with pytest.raises(KeyError):
        _sim("no contact").scene.term("contact")


@pytest.mark.parametrize("name", ["torque-free head, contact", "fixed head 300 rpm, contact active", "no head",
                                  "head as printed", "literal head (spin from eqn 13)", "rft, torque-free head", "rft, fixed head 300 rpm, contact active"])
def test_each_term_s_jacobian_action_matches_central_differences_of_its_force(name):
    """At the configuration of the step's start (bent after a burst; where the frames were last updated, so the DER
    Hessian is the symmetric part of the gradient's derivative) each term's action along random directions against
    central differences of its force: exact (to round-off) for inertia, hydrodynamics and contact; for the elastic
    term against the symmetric part of the finite-difference Jacobian."""
    sim = _sim(name)
    assert abs(sim.end_to_end_ratio() - 1.0) > 0.04  # deformed (stretched by the burst, or buckled), not the helix
    _, ctx = _open_step(sim)
    q = sim.q.copy()
    free = np.setdiff1d(np.arange(q.size), sim.prescribed)
    for term in sim.scene.terms:
        if isinstance(term, Elastic):
            continue
        for seed in (1, 2):
            v = _direction(sim, seed)
            fd = _central(lambda x: term.force(x, ctx), q, v)
            got = term.jacobian_action(q, ctx, v)
            scale = max(np.abs(fd).max(), 1e-300)
            assert np.abs(got - fd)[free].max() <= 1e-7 * scale, (term.name, np.abs(got - fd).max() / scale)
            if isinstance(term, Contact) and "active" in name:
                assert np.abs(got).max() > 0.0  # the contact term acts here
    elastic = sim.scene.term("elastic")
    eps = 1e-6
    steps = np.where(np.arange(q.size) % 4 == 3, 1.0, sim.params.rod_radius) * eps
    J = np.zeros((q.size, q.size))
    for j in free:
        e = np.zeros(q.size)
        e[j] = steps[j]
        J[:, j] = (elastic.force(q + e, ctx) - elastic.force(q - e, ctx)) / (2.0 * steps[j])
    sym = 0.5 * (J + J.T)
    for seed in (1, 2):
        v = _direction(sim, seed)
        got = elastic.jacobian_action(q, ctx, v)
        ref = sym @ v
        assert np.abs(got - ref)[free].max() <= 1e-8 * np.abs(ref).max()


def test_contact_is_active_in_the_contact_cases():
    for name in ("fixed head 300 rpm, contact active", "rft, fixed head 300 rpm, contact active"):
        sim = _sim(name)
        q, ctx = _open_step(sim)
        _, (cstate, energy, nodes, blocks) = sim.scene.term("contact").evaluate(sim.q, ctx)
        assert nodes.shape[0] > 0 and energy > 0.0, name


def _fused_residual(sim: Simulator, q: np.ndarray, ctx):
    """r, grad, f, inertia (ndof,) and the contact state at q by the fused compiled kernels the chord iteration runs
    (``chord_iteration.chord_residual``: ``internal_forces_at`` then ``assemble_residual``)."""
    system = sim.system
    contact_on, model, cstate = compiled_contact_args(q, ctx, system)
    grad, fr, cstate, e_c, nodes_c, _ = internal_forces_at(q, ctx.frames, system.rest, contact_on, model, cstate,
                                                           ctx.q_start, system.pos, ctx.first_step)
    res = ctx.resistance
    V = generalised_velocity(q, ctx.q_hat, ctx.h, system.vdofs, system.head_spins, ctx.omega, res.Q)
    r, f, inertia = assemble_residual(q, ctx.q_hat, ctx.v_hat, ctx.h, system.mass, grad, -res.operator.apply(V),
                                      res.Q, system.vdofs, system.head_spins, system.prescribed)
    return r, grad, f, inertia, cstate, fr


@pytest.mark.parametrize("name", list(CASES))
def test_scene_residual_is_the_fused_kernels_residual_bit_for_bit(name):
    """The scene's sum (elastic, contact, inertia, hydrodynamics, left to right) against the fused kernels at the
    predictor, at an iterate off it, and at a configuration moved out of the contact broad phase's boxes (both redo
    the broad phase the same way); ``chord_reference.scene_residual`` (the Python chord iteration's residual) is the
    scene's."""
    sim = _sim(name)
    q_pred, ctx = _open_step(sim)
    shift = np.zeros(q_pred.size)
    shift[sim._pos[0::3]] = 3.0 * sim.params.rod_radius  # a rigid translation by 3 r0: out of the padded boxes
    for q in (q_pred, q_pred + 0.3 * _direction(sim, 3), q_pred + shift):
        r, grad, f, inertia, cstate, fr = _fused_residual(sim, q, ctx)
        ev = sim.scene.evaluate(q, ctx)
        assert np.array_equal(ev.r, r)
        assert np.array_equal(ev.forces["inertia"], inertia)
        assert np.array_equal(-ev.forces["hydrodynamics"], f)
        g = ev.forces["elastic"] + (ev.forces["contact"] if "contact" in ev.forces else 0.0)
        assert np.array_equal(g, grad)
        for a, b in zip(ev.byproducts["elastic"], fr):
            assert np.array_equal(a, b)
        if "contact" in ev.forces:
            got = ev.byproducts["contact"][0]
            assert got[1] == cstate[1] and got[4] == cstate[4] and np.array_equal(got[0], cstate[0])
            assert np.array_equal(got[2], cstate[2]) and np.array_equal(got[3], cstate[3])
    moved = ev.byproducts["contact"][0] if "contact" in ev.forces else None
    if moved is not None:
        assert moved[0] is not ctx.contact[0]  # the last configuration did redo the broad phase
    rs, grads, fs, inertias, _ = scene_residual(sim, q_pred, ctx.h)
    r, grad, f, inertia, *_ = _fused_residual(sim, q_pred, sim.step_context(ctx.h))
    assert np.array_equal(rs, r) and np.array_equal(grads, grad) and np.array_equal(fs, f)


@pytest.mark.parametrize("name", ["torque-free head, contact", "fixed head 300 rpm, contact active", "no contact",
                                  "no head", "head as printed", "literal head (spin from eqn 13)"])
def test_scene_jacobian_action_is_the_assembled_dense_jacobian_times_v(name):
    """dr/dq v against the direct solver's J = M/h^2 + K + P^T R P / h + contact blocks (prescribed DOFs as identity
    rows and columns: compared with v zero there, on the free rows), for the step's resistance, rotated or not."""
    sim = _sim(name)
    q, ctx = _open_step(sim)
    solver = sim.solver
    R = rotate_dense_blocks(solver.hyd.dense(), np.ascontiguousarray(solver.Qh), solver.hyd.spin)
    J = solver.dense_jacobian(q, ctx.h, R)
    free = np.setdiff1d(np.arange(q.size), sim.prescribed)
    for seed in (4, 5):
        v = _direction(sim, seed)
        ref = J @ v
        got = sim.scene.jacobian_action(q, ctx, v)
        assert np.abs(got - ref)[free].max() <= 1e-12 * np.abs(ref).max()
        assert np.all(got[sim.prescribed] == 0.0)


@pytest.mark.parametrize("name", ["torque-free head, contact", "fixed head 300 rpm, contact active", "no head",
                                  "head as printed", "literal head (spin from eqn 13)"])
def test_scene_jacobian_action_is_the_mobility_form_s_q_part(name):
    """The mobility form (``newton_krylov``) has the flagellum's forces y as unknowns: with dy = C B P v / h (the
    forces the velocity v / h induces) its J (v, dy) is (dr/dq v, 0), the scene's action with the resistance the
    Newton-Krylov step built at the predictor."""
    sim = _sim(name)
    q, ctx = _open_step(sim)
    solver = sim.solver
    solver._refresh_hydro(q, lazy=True)
    solver.Qh = np.eye(3)
    ms = solver.mobility
    ms.begin(solver.hyd, q, ctx.h)
    ctx = sim.step_context(ctx.h)  # now with the resistance at q_pred
    assert ctx.resistance.operator is solver.hyd
    hyd = solver.hyd
    for seed in (6, 7):
        v = _direction(sim, seed)
        V = v[sim.vdofs] / ctx.h
        dy = hyd.solve(head_flow_apply(V, ms.H, ms.g, hyd.has_head, hyd.spin))
        out = ms.jacobian_vector(q, ctx.h, np.concatenate([v, dy]))
        got = sim.scene.jacobian_action(q, ctx, v)
        free = np.setdiff1d(np.arange(q.size), sim.prescribed)
        assert np.abs(out[:q.size] - got)[free].max() <= 1e-9 * np.abs(got).max()


@pytest.mark.parametrize("name", ["rft, torque-free head", "rft, no head, no contact"])
def test_scene_jacobian_action_is_the_rft_banded_newton_matrix(name):
    """The banded Newton solver of RFT factorises the exact Jacobian (its contact blocks within the band): its
    increment undoes the scene's action, J^{-1} (J v) = v, where no contact block falls outside the band."""
    sim = _sim(name)
    q, ctx = _open_step(sim)
    for seed in (8, 9):
        v = _direction(sim, seed)
        back = increment(sim, sim.scene.jacobian_action(q, ctx, v), q, ctx.h)
        assert np.abs(back - v).max() <= 1e-9 * np.abs(v).max()


def test_a_scene_is_any_list_of_terms():
    """A scene sums what it is given: elastic + inertia alone is the residual of the rod in vacuum, and a term is
    anything with force / jacobian_action (here a linear spring pulling every DOF to zero)."""
    sim = _sim("no contact")
    _, ctx = _open_step(sim)

    class Spring:
        name = "spring"

        def force(self, q, ctx):
            return 2.0 * q

        def jacobian_action(self, q, ctx, v):
            return 2.0 * v

    scene = Scene((Elastic(sim.system.rest), Inertia(sim.system.mass), Spring()), sim.prescribed)
    q = sim.q.copy()
    expected = Elastic(sim.system.rest).force(q, ctx) + Inertia(sim.system.mass).force(q, ctx) + 2.0 * q
    expected[sim.prescribed] = 0.0
    assert np.array_equal(scene.residual(q, ctx), expected)
    v = _direction(sim, 10)
    fd = _central(lambda x: scene.residual(x, ctx) - scene.term("elastic").force(x, ctx), q, v)
    got = scene.jacobian_action(q, ctx, v) - Elastic(sim.system.rest).jacobian_action(q, ctx, v)
    assert np.abs(got - fd).max() <= 1e-7 * np.abs(fd).max()
    full = scene_for(sim.system)
    assert full.names == sim.scene.names
    assert isinstance(full.term("hydrodynamics"), Hydrodynamics)
    assert StepResistance(None).Q.shape == (3, 3)
