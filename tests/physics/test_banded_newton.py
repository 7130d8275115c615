"""The compiled banded Newton iteration of the RFT model (``chord_iteration.chord_loop`` with the banded increment)
against its Python reference (tests/physics/chord_reference.py: ``scipy.linalg.solve_banded`` on the banded Jacobian),
bit for bit; the compiled LAPACK dgbsv against ``scipy.linalg.solve_banded``; and Numba's products (the chord loop's
where NumPy has no bundled OpenBLAS) against NumPy's."""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np
import pytest
from scipy.linalg import solve_banded

from physics import Simulator, advance, configure
from physics.errors import StepFailed
from physics.linalg.compiled_lapack import gbsv, numba_dot, numba_matvec
from physics.params import RPM_TO_RAD_S
from physics.solvers.chord_iteration import chord_solve
from tests.physics.chord_reference import PythonChordSimulator, chord_python


@pytest.mark.parametrize("n", [11, 40, 159, 487])
def test_compiled_gbsv_is_solve_banded_bit_for_bit(n):
    """Random diagonally heavy band matrices of the elastic Hessian's width (kl = ku = 10), and a singular one."""
    rng = np.random.default_rng(n)
    for _ in range(4):
        ab = rng.normal(size=(21, n))
        ab[10] += 30.0
        b = rng.normal(size=n)
        ab0, b0 = ab.copy(), b.copy()
        x, info = gbsv(ab, 10, 10, b)
        assert info == 0 and np.array_equal(x, solve_banded((10, 10), ab, b, check_finite=False))
        assert np.array_equal(ab, ab0) and np.array_equal(b, b0)  # inputs untouched
    x, info = gbsv(np.zeros((21, n)), 10, 10, np.ones(n))
    assert info == 1  # solve_banded: LinAlgError("singular matrix")


def test_numbas_products_are_numpys_up_to_rounding():
    """``compiled_lapack``'s fallback products (no bundled OpenBLAS): C- and F-ordered matrices, a transpose, empty
    shapes."""
    rng = np.random.default_rng(5)
    for m, n in ((363, 363), (363, 3), (3, 363), (1, 7), (0, 3), (3, 0)):
        A = rng.normal(size=(m, n))
        x, y = rng.normal(size=n), rng.normal(size=m)
        for M, v in ((A, x), (np.asfortranarray(A), x), (A.T, y)):
            np.testing.assert_allclose(numba_matvec(M, v), M @ v, rtol=1e-12, atol=1e-12 * (v.size + 1))
        assert numba_dot(x, x) == pytest.approx(x @ x, rel=1e-13, abs=0.0)


def _rft(overrides: dict, n_nodes: int = 40, simulator: type = Simulator) -> Simulator:
    """An RFT swimmer on ``faithful``'s numerics (adaptive BDF3, Newton tolerance 1e-5), on the compiled iteration
    (``Simulator``) or the Python one (``PythonChordSimulator``)."""
    p, n = configure("faithful", {"hydro_model": "rft", "n_nodes": n_nodes, **overrides})
    return simulator(p, n)


#: (overrides, burst rpm, burst seconds): each burst goes through buckling (L'/L well below 1 at its end)
RUNS = {
    "fixed head, contact": ({}, 150, 11.0),
    "fixed head, no contact": ({"contact": False}, 150, 11.0),
    "torque-free head": ({"head_rotation": "torque_free"}, 150, 11.0),
    "no head, contact": ({"head_radius": 0.0}, 300, 5.0),
    "no head, no contact": ({"head_radius": 0.0, "contact": False}, 300, 5.0),
    "implicit Euler, fixed 2 ms steps": ({"integrator": "euler", "step_tol": 0.0, "dt": 2e-3}, 150, 6.0),
    "single iteration, fixed 2 ms steps": ({"integrator": "euler", "step_tol": 0.0, "dt": 2e-3,
                                            "single_iteration": True}, 150, 6.0),
}


def _run(overrides: dict, rpm: float, seconds: float, compiled: bool):
    """0.5 s at 10 rpm from rest, then ``seconds`` at ``rpm``: the configuration after every dt, the active contacts
    after every dt, the counters and the trajectory's hash."""
    sim = _rft(overrides, simulator=Simulator if compiled else PythonChordSimulator)
    qs, contacts = [], []
    for speed, span in ((10, 0.5), (rpm, seconds)):
        sim.set_motor_speed(speed * RPM_TO_RAD_S)
        for _ in range(int(round(span / sim.numerics.dt))):
            sim.step()
            qs.append(sim.q.copy())
            contacts.append(sim.contact_count)
    s = sim.stats
    qs = np.array(qs)
    return (qs, np.array(contacts), (s.newton_iterations, s.jacobian_factorisations, s.substeps, s.rejected_steps,
                                     s.halvings), hashlib.sha256(qs.tobytes()).hexdigest()[:16])


@pytest.mark.parametrize("name", list(RUNS))
def test_rft_runs_with_the_compiled_banded_newton_iteration_are_the_python_runs_bit_for_bit(name):
    """Whole runs (N = 40: 0.5 s at 10 rpm, then a burst through buckling) with the compiled iteration and with the
    Python one (``PythonChordSimulator``): the same configuration after every dt (np.array_equal), the same
    counters (residuals, banded solves, steps, rejections, halvings), the same contacts."""
    overrides, rpm, seconds = RUNS[name]
    q1, c1, n1, h1 = _run(overrides, rpm, seconds, compiled=True)
    q2, c2, n2, h2 = _run(overrides, rpm, seconds, compiled=False)
    assert n1 == n2 and np.array_equal(c1, c2)
    assert np.array_equal(q1, q2) and h1 == h2
    span = np.linalg.norm(q1[:, -3:] - q1[:, 0:3], axis=1)
    assert span.min() < 0.9 * span[0]  # buckled (L'/L well below its cruising value)
    if name in ("fixed head, contact", "no head, contact"):
        assert c1.max() > 0  # contact was active in the runs compared


def _open_step(sim: Simulator, h: float):
    """Set up a step of h from the current state as ``_try_step`` does: (iterate start q, effective step)."""
    base = sim._base_for(h)
    q = sim._step_start(base)
    sim.solver.begin_step(q, base.h_eff)
    return q, base.h_eff


def _contact_of(sim: Simulator) -> tuple:
    """(the step's contact broad phase, the last evaluation's (energy, count)) by the simulator's public names."""
    return sim.contact_state(sim.q)[1], sim.last_contact


def _from_the_same_setup(sim: Simulator, q: np.ndarray, h: float):
    """(Python result, compiled result, Python counters, compiled counters, Python contact state, compiled contact
    state): both iterations of one step from the same set-up (a StepFailed stands for its result)."""
    saved = (_contact_of(sim), dataclasses.replace(sim.stats),
             (sim.contraction.rho, sim.contraction.prev, sim.contraction.age))
    out = []
    for fn in (chord_python, chord_solve):
        sim.keep_contact_state(saved[0][0], *saved[0][1])
        sim.stats = dataclasses.replace(saved[1])
        sim.contraction.rho, sim.contraction.prev, sim.contraction.age = saved[2]
        try:
            res = fn(sim, q.copy(), h)
        except StepFailed as exc:
            res = exc
        out.append((res, dataclasses.replace(sim.stats), (sim.contraction.rho, sim.contraction.prev,
                                                           sim.contraction.age),
                    (lambda c: (c[0].pad, c[0].none, c[1]))(_contact_of(sim))))
    return out


@pytest.mark.parametrize("max_iter, tol, h, fails", [(25, 1e-5, 0.004, False), (25, 1e-12, 0.004, False),
                                                     (2, 1e-14, 0.05, True)],
                         ids=["converges", "tight tolerance", "fails"])
def test_a_step_is_the_python_iteration_bit_for_bit(max_iter, tol, h, fails):
    """One buckled step with contact (fixed head, 150 rpm), converged or failing: the same iterate, residual,
    forces, frames, counters, contraction rate and contact state; a failure is the same StepFailed."""
    sim = _rft({})
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    advance(sim, 10.5)
    nm = dataclasses.replace(sim.numerics, newton_max_iter=max_iter, newton_tol=tol)
    sim.numerics, sim.system = nm, dataclasses.replace(sim.system, numerics=nm)  # what the compiled loop reads
    q, h = _open_step(sim, h)
    (ref, s_ref, r_ref, c_ref), (got, s_got, r_got, c_got) = _from_the_same_setup(sim, q, h)
    assert isinstance(ref, StepFailed) == fails
    if fails:
        assert isinstance(got, StepFailed) and str(got) == str(ref) and got.quantity == ref.quantity
    else:
        for a, b in zip(got[:4], ref[:4]):
            assert np.array_equal(a, b)
        for a, b in zip(got[4], ref[4]):
            assert np.array_equal(a, b)
    assert (s_got.newton_iterations, s_got.jacobian_factorisations) == (s_ref.newton_iterations,
                                                                         s_ref.jacobian_factorisations)
    assert s_ref.newton_iterations >= 2 and r_got == r_ref and c_got == c_ref
