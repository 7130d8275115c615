"""The compiled Newton-Krylov span (physics/solvers/krylov_span.py) against the Python step it replaces, bit for bit:
whole runs with and without it (burst and relaxation, a fixed head in contact with rejected steps, collapsed BDF3 steps
handed back for the order reduction), a failing attempt handed back to Python, and where the span applies."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

import physics.simulator as simulator_module
from physics import Simulator, SimulationError, configure
from physics.linalg.compiled_lapack import NUMPY_BLAS
from physics.hydro.hydrodynamics import ResistanceOperator
from physics.solvers.krylov_span import (SPAN_AFTER_ACCEPT, SPAN_CHORD, SPAN_COUNTERS, SPAN_DONE, SPAN_FAILED,
                                 krylov_span_applies)
from physics.params import RPM_TO_RAD_S

pytestmark = pytest.mark.skipif(not NUMPY_BLAS, reason="NumPy without its bundled OpenBLAS: the Python step runs")

_COUNTERS = (*SPAN_COUNTERS, "steps", "jacobian_factorisations", "halvings", "order_reductions")


def _count_spans(monkeypatch) -> Counter:
    """Count the codes the simulator's spans return."""
    codes: Counter = Counter()
    run = simulator_module.run_krylov_span

    def counted(*args):
        out = run(*args)
        codes[out[0]] += 1
        return out

    monkeypatch.setattr(simulator_module, "run_krylov_span", counted)
    return codes


def _observed(sim: Simulator) -> list[np.ndarray]:
    return [sim.q, sim.v, sim.d1, sim.tangent, sim.ref_twist, sim.body_frame, sim.node_forces,
            np.array([sim.time, sim.motor_angle, sim.motor_torque, sim.head_axial_torque, sim.head_spin_rate,
                      sim.contact_energy, sim.contact_count, sim.adaptive.h])]


def _run(overrides: dict, phases: tuple, compiled: bool) -> tuple[list, dict, Simulator]:
    p, n = configure("faithful", overrides)
    sim = Simulator(p, n)
    sim.compiled_span = compiled
    seen = []
    for rpm, seconds in phases:
        sim.set_motor_speed(rpm * RPM_TO_RAD_S)
        for _ in range(int(round(seconds / n.dt))):
            sim.step()
            seen.append([a.copy() for a in _observed(sim)])
    return seen, {k: getattr(sim.stats, k) for k in _COUNTERS}, sim


CASES = {
    # burst and relaxation of the torque-free swimmer: Newton-Krylov runs, chord steps between them
    "burst": ({"n_nodes": 24, "head_rotation": "torque_free"}, ((10, 1.0), (150, 0.4), (10, 0.5)), {SPAN_DONE, SPAN_CHORD}),
    # a fixed head at 300 rpm, buckled into contact (from 1.8 s): contact forces and Hessians, rejected steps
    "contact": ({"n_nodes": 40, "head_rotation": "fixed"}, ((300, 2.2),), {SPAN_DONE}),
    # BDF3 at step_tol 1e-7 from rest, the resistance rebuilt at every step: 1000 collapsed steps in one span
    "collapse": ({"n_nodes": 24, "step_tol": 1e-7, "hydro_refresh_tol": 1e-12}, ((10, 0.1),), {SPAN_AFTER_ACCEPT}),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_runs_with_the_span_are_the_python_runs_bit_for_bit(case, monkeypatch):
    """The same state after every dt (q, v, frames, body frame, forces, torques, head spin, contact, time, next
    step) and the same counters, with the compiled span and with the Python step; the span's returns to Python were exercised."""
    overrides, phases, expected = CASES[case]
    codes = _count_spans(monkeypatch)
    seen, counters, sim = _run(overrides, phases, True)
    assert expected <= set(codes), codes
    ref, ref_counters, ref_sim = _run(overrides, phases, False)
    assert counters == ref_counters
    assert counters["krylov_steps"] > 0
    if case == "contact":
        assert sim.contact_count > 0
    for got, want in zip(seen, ref, strict=True):
        for a, b in zip(got, want, strict=True):
            assert np.array_equal(a, b)
    st, ref_st = sim.adaptive, ref_sim.adaptive
    assert (st.count, st.force_count) == (ref_st.count, ref_st.force_count)
    for name in ("times", "qs", "vs", "force_times", "force_values"):
        k = st.count if name in ("times", "qs", "vs") else st.force_count
        assert np.array_equal(getattr(st, name)[:k], getattr(ref_st, name)[:k])
    # the newest point is the state
    assert np.array_equal(st.qs[st.count - 1], sim.q) and np.array_equal(st.vs[st.count - 1], sim.v)


def test_a_failing_attempt_is_handed_back_to_the_python_step(monkeypatch):
    """A NaN twist after three dt of 150 rpm: every attempt fails in the span, Python takes it again and rejects it,
    down to h_min: the same SimulationError (message, step, time, quantity) and the same counters as without it."""
    codes = _count_spans(monkeypatch)
    out = []
    for compiled in (True, False):
        p, n = configure("faithful", {"n_nodes": 24, "hydro_refresh_tol": 1e-12})
        sim = Simulator(p, n)
        sim.compiled_span = compiled
        sim.set_motor_speed(150 * RPM_TO_RAD_S)
        for _ in range(3):
            sim.step()
        sim.q[7] = np.nan  # in the state and in the controller's newest point, from which the next step starts
        sim.adaptive.qs[sim.adaptive.count - 1, 7] = np.nan
        with pytest.raises(SimulationError) as info:
            sim.step()
        e = info.value
        out.append((str(e), e.step, e.time_s, e.quantity, {k: getattr(sim.stats, k) for k in _COUNTERS}))
    assert codes[SPAN_FAILED] > 0
    assert out[0] == out[1]
    assert out[0][3] == "residual"


@pytest.mark.parametrize("overrides, applies", [({}, True), ({"head_rotation": "torque_free"}, True),
                                                ({"head_rotation": "paper"}, False),
                                                ({"head_rotation": "literal"}, False),
                                                ({"head_radius": 0.0}, False), ({"hydro_model": "rft"}, False),
                                                ({"step_tol": 0.0, "dt": 0.005}, False)],
                         ids=["faithful", "torque-free head", "head as printed", "literal head", "no head", "rft",
                              "fixed steps"])
def test_where_the_span_applies(overrides, applies):
    """After 0.3 s at 150 rpm (the last attempt by Newton-Krylov where there is one): the span takes the next
    attempt only for the configurations it covers, never right after a motor-speed change, never when switched off."""
    p, n = configure("faithful", {"n_nodes": 24, **overrides})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    sim.advance(0.3)
    assert krylov_span_applies(sim) == applies
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    assert not krylov_span_applies(sim)


def test_the_operator_from_parts_is_the_operator_built():
    """``ResistanceOperator.from_parts`` (what a span leaves to the chord steps) gives the operator built from the
    nodes: the same dense resistance and the same action, bit for bit."""
    p, n = configure("faithful", {"n_nodes": 24})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    sim.advance(0.3)
    built = ResistanceOperator(sim.nodes, p.viscosity, p.cutoff_length, p.head_radius, True, n.lsbt_smoothing,
                               near_radius=n.near_field_radius * p.rod_radius, factorize_lazily=True)
    parts = ResistanceOperator.from_parts(built.a, built.H, built.g, built.drag_t, built.drag_r, True,
                                          n.lsbt_smoothing)
    V = np.random.default_rng(0).standard_normal(built.nv)
    assert np.array_equal(parts.dense(), built.dense())
    assert np.array_equal(parts.apply(V), built.apply(V))
