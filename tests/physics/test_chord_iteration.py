"""The compiled chord iteration (physics/solvers/chord_iteration.py) against its Python reference
(tests/physics/chord_reference.py), bit for bit, from the same step set-up: a steady step on the kept inverse, a step
whose resistance forms its inverse inside the iteration, a stall (refactorisation, then resumed), a stall that
ends in failure, and a buckled step with contact; and the BLAS / LAPACK calls of compiled code against NumPy's
and SciPy's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg
from scipy.linalg import lapack

from physics import Simulator, advance, configure
from physics.solvers.chord_iteration import chord_solve
from physics.linalg.compiled_lapack import NUMPY_BLAS, getrs, numpy_dot, numpy_matvec, potrs_upper
from physics.errors import StepFailed
from physics.params import RPM_TO_RAD_S
from tests.physics.chord_reference import PythonChordSimulator, chord_python

pytestmark = pytest.mark.skipif(not NUMPY_BLAS, reason="NumPy without its bundled OpenBLAS: Numba's products, not "
                                "NumPy's (the same up to rounding)")

_EYE = np.eye(3)


def _steady(n_nodes: int = 24) -> Simulator:
    """A torque-free swimmer after 1.5 s at 10 rpm from rest (its steps end on the chord iteration)."""
    p, n = configure("faithful", {"n_nodes": n_nodes, "head_rotation": "torque_free"})
    sim = Simulator(p, n)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, 1.5)
    return sim


def _buckled_with_contact() -> Simulator:
    """A fixed-head swimmer at 300 rpm, buckled and touching itself (as in test_newton_krylov)."""
    p, n = configure("faithful", {"n_nodes": 40, "head_rotation": "fixed", "contact": True})
    sim = Simulator(p, n)
    sim.set_motor_speed(300 * RPM_TO_RAD_S)
    advance(sim, 1.8)
    return sim


def _open_chord_step(sim: Simulator, h: float, fresh: bool = False):
    """Set up a chord step of h from the current state as ``_try_step`` does; ``fresh``: factorise the Jacobian
    (and rebuild the resistance) at the predictor, so the chord iteration runs wherever the step would have gone
    to Newton-Krylov. Returns (q, h_eff)."""
    base = sim._base_for(h)
    q = sim._step_start(base)
    solver = sim.solver
    solver.begin_step(q, base.h_eff)
    if fresh or solver.krylov:
        solver._refresh_jacobian(q, base.h_eff, keep_resistance=False)
        solver.krylov, solver.jac_fresh, solver.Qh, solver.Qj = False, True, _EYE, _EYE
    assert solver.lu is not None and solver.hyd is not None  # a chord step
    return q, base.h_eff


_SOLVER_FIELDS = ("lu", "piv1", "lu_h", "x_jac", "Qj", "jac_fresh", "contact_set")


def _snapshot(sim: Simulator) -> dict:
    solver, hyd, rate = sim.solver, sim.solver.hyd, sim.contraction
    return {"sim": {"contact": sim.contact_state(sim.q)[1], "last_contact": sim.last_contact},
            "solver": {k: getattr(solver, k) for k in _SOLVER_FIELDS},
            "hyd": {"inv": hyd.inv, "applies": hyd.applies},
            "rate": (rate.rho, rate.prev, rate.age), "stats": dataclasses.replace(sim.stats)}


def _restore(sim: Simulator, snap: dict) -> None:
    sim.keep_contact_state(snap["sim"]["contact"], *snap["sim"]["last_contact"])
    for k, v in snap["solver"].items():
        setattr(sim.solver, k, v)
    for k, v in snap["hyd"].items():
        setattr(sim.solver.hyd, k, v)
    sim.contraction.rho, sim.contraction.prev, sim.contraction.age = snap["rate"]
    sim.stats = dataclasses.replace(snap["stats"])


def _run(fn, *args):
    try:
        return fn(*args)
    except StepFailed as exc:
        return exc


def _both(sim: Simulator, q: np.ndarray, h: float):
    """(Python result, compiled result, Python state after, compiled state after) from the same set-up."""
    snap = _snapshot(sim)
    ref = _run(chord_python, sim, q.copy(), h)
    after_ref = _snapshot(sim)
    _restore(sim, snap)
    got = _run(chord_solve, sim, q.copy(), h)
    return ref, got, after_ref, _snapshot(sim)


def _assert_same(ref, got, after_ref, after_got) -> None:
    if isinstance(ref, StepFailed):
        assert isinstance(got, StepFailed) and str(got) == str(ref) and got.quantity == ref.quantity
    else:
        assert not isinstance(got, StepFailed), got
        for a, b in zip(got[:4], ref[:4]):
            assert np.array_equal(a, b)
        for a, b in zip(got[4], ref[4]):
            assert np.array_equal(a, b)
    assert after_got["stats"].newton_iterations == after_ref["stats"].newton_iterations
    assert after_got["stats"].jacobian_factorisations == after_ref["stats"].jacobian_factorisations
    assert after_got["rate"] == after_ref["rate"]
    assert after_got["hyd"]["applies"] == after_ref["hyd"]["applies"]
    assert (after_got["hyd"]["inv"] is None) == (after_ref["hyd"]["inv"] is None)
    for k in ("lu_h", "jac_fresh", "contact_set"):
        assert after_got["solver"][k] == after_ref["solver"][k]
    assert np.array_equal(after_got["solver"]["lu"][0], after_ref["solver"]["lu"][0])
    got_c, ref_c = after_got["sim"]["contact"], after_ref["sim"]["contact"]
    assert (got_c.pad, got_c.none, after_got["sim"]["last_contact"]) == (ref_c.pad, ref_c.none,
                                                                       after_ref["sim"]["last_contact"])


@pytest.fixture(scope="module")
def steady() -> Simulator:
    return _steady()


def test_a_steady_step_is_the_python_iteration_bit_for_bit(steady):
    sim = steady
    q, h = _open_chord_step(sim, 0.1)
    assert sim.solver.hyd.inv is not None  # the kept inverse
    n0 = sim.stats.newton_iterations
    ref, got, a_ref, a_got = _both(sim, q, h)
    assert a_ref["stats"].newton_iterations - n0 >= 2  # at least one increment
    _assert_same(ref, got, a_ref, a_got)


def test_a_step_that_forms_the_inverse_inside_the_iteration_is_the_python_iteration(steady):
    """Before the inverse exists the resistance is applied by Cholesky solves; the solve that crosses
    ``INVERSE_AFTER_SOLVES`` forms the inverse (Python enters there) and the iteration goes on with it."""
    sim = steady
    q, h = _open_chord_step(sim, 0.1)
    hyd = sim.solver.hyd
    hyd.factorize()
    hyd.inv, hyd.applies = None, 59  # two Cholesky solves left: the switch comes within the step
    ref, got, a_ref, a_got = _both(sim, q, h)
    assert a_ref["hyd"]["inv"] is not None and a_ref["hyd"]["applies"] == 61
    _assert_same(ref, got, a_ref, a_got)


@pytest.mark.parametrize("max_iter, tol, fails", [(3, 1e-8, False), (4, 1e-9, False), (2, 1e-8, True)],
                         ids=["resumed", "resumed later", "fails"])
def test_a_stall_is_refactorised_and_resumed_as_in_python(steady, max_iter, tol, fails):
    """Few iterations per Jacobian and a tight tolerance: the iteration stalls, the Jacobian is refactorised at the
    iterate (Python enters), and the compiled loop resumes at the increment; with too few iterations left both end
    in the same StepFailed."""
    sim = steady
    q, h = _open_chord_step(sim, sim.adaptive.h)
    sim.solver.jac_fresh = False  # as if factorised at an earlier step: a stall refactorises
    n0 = sim.stats.jacobian_factorisations
    nm, system = sim.numerics, sim.system
    sim.numerics = dataclasses.replace(nm, newton_max_iter=max_iter, newton_tol=tol, step_tol=0.0)
    sim.system = dataclasses.replace(system, numerics=sim.numerics)  # what the compiled iteration reads
    try:
        ref, got, a_ref, a_got = _both(sim, q, h)
    finally:
        sim.numerics, sim.system = nm, system
    assert a_ref["stats"].jacobian_factorisations == n0 + 1  # it did stall
    assert isinstance(ref, StepFailed) == fails
    _assert_same(ref, got, a_ref, a_got)


def test_a_buckled_step_with_contact_is_the_python_iteration_bit_for_bit():
    sim = _buckled_with_contact()
    q, h = _open_chord_step(sim, 0.005, fresh=True)
    ref, got, a_ref, a_got = _both(sim, q, h)
    assert not isinstance(ref, StepFailed)
    assert a_ref["sim"]["last_contact"][1] > 0  # contact was active in the step compared
    _assert_same(ref, got, a_ref, a_got)


def test_compiled_blas_and_lapack_calls_are_numpys_and_scipys():
    rng = np.random.default_rng(3)
    for m in (1, 3, 100, 363):
        A = rng.normal(size=(m, m))
        x = rng.normal(size=m)
        H = rng.normal(size=(m, 3))
        assert np.array_equal(numpy_matvec(A, x), A @ x)
        assert np.array_equal(numpy_matvec(np.asfortranarray(A), x), np.asfortranarray(A) @ x)
        assert np.array_equal(numpy_matvec(H, x[:3]), H @ x[:3]) if m >= 3 else True
        assert numpy_dot(x, A[0]) == x @ A[0]
        J = A + m * np.eye(m)
        lu, piv = scipy.linalg.lu_factor(J)
        got, info = getrs(lu, (piv + 1).astype(np.int32), x)
        assert info == 0 and np.array_equal(got, lapack.dgetrs(lu, piv, x)[0])
        c = lapack.dpotrf(A @ A.T + m * np.eye(m), lower=0, clean=1, overwrite_a=0)[0]
        got, info = potrs_upper(c, x)
        assert info == 0 and np.array_equal(got, lapack.dpotrs(c, x, lower=False)[0])


@pytest.mark.parametrize("overrides", [{"head_rotation": "torque_free"}, {"head_rotation": "paper"}, {"head_rotation": "literal"},
                                       {"head_radius": 0.0}],
                         ids=["torque-free head", "head as printed", "literal head", "no head"])
def test_runs_with_the_compiled_chord_iteration_are_the_python_runs_bit_for_bit(overrides):
    """Whole runs (N = 24, 1 s at 10 rpm, 0.3 s at 150 rpm, 0.5 s at 10 rpm: chord and Newton-Krylov steps, the
    resistance's inverse formed inside steps) with the compiled iteration and with the Python one: the same
    configuration after every dt, the same counters."""
    runs = []
    for simulator in (Simulator, PythonChordSimulator):
        p, n = configure("faithful", {"n_nodes": 24, **overrides})
        sim = simulator(p, n)
        qs = []
        for rpm, seconds in ((10, 1.0), (150, 0.3), (10, 0.5)):
            sim.set_motor_speed(rpm * RPM_TO_RAD_S)
            for _ in range(int(round(seconds / n.dt))):
                sim.step()
                qs.append(sim.q.copy())
        runs.append((np.array(qs), sim.stats.newton_iterations, sim.stats.substeps, sim.stats.krylov_steps))
    (q1, *c1), (q2, *c2) = runs
    assert c1 == c2 and c1[1] > c1[2]  # chord steps were taken (not every step by Newton-Krylov)
    assert np.array_equal(q1, q2)


@pytest.mark.parametrize("preset, overrides", [("paper", {}), ("faithful", {"head_rotation": "torque_free"}),
                                               ("paper", {"head_radius": 0.0})],
                         ids=["paper", "faithful, torque-free head", "paper, no head"])
def test_single_iteration_runs_are_the_python_runs_bit_for_bit(preset, overrides):
    """``single_iteration`` (one solve from the predictor on a Jacobian factorised at it, every step): whole runs
    (N = 24, 0.3 s at 10 rpm, 0.1 s at 150 rpm) with the compiled iteration and with the Python one: the same
    configuration after every dt, the same counters."""
    runs = []
    for simulator in (Simulator, PythonChordSimulator):
        p, n = configure(preset, {"n_nodes": 24, "single_iteration": True, **overrides})
        sim = simulator(p, n)
        qs = []
        for rpm, seconds in ((10, 0.3), (150, 0.1)):
            sim.set_motor_speed(rpm * RPM_TO_RAD_S)
            for _ in range(int(round(seconds / n.dt))):
                sim.step()
                qs.append(sim.q.copy())
        s = sim.stats
        runs.append((np.array(qs), s.newton_iterations, s.substeps, s.jacobian_factorisations, s.krylov_steps))
    (q1, *c1), (q2, *c2) = runs
    assert c1 == c2 and c1[3] == 0  # no Newton-Krylov
    assert c1[0] == c1[1] or n.step_tol > 0.0  # one residual per step (adaptive: per attempt)
    assert np.array_equal(q1, q2)
