"""Newton-Krylov in the mobility form (physics/solvers/newton_krylov.py): the matrix-free Jacobian against the
assembled direct-solver Jacobian and against central differences of the residual, GMRES on buckled
snapshots with and without contact, the step it takes against the direct step, the compiled banded LU
against LAPACK, and a diverging run still ending in SimulationError."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import lapack

from physics import Simulator, SimulationError, advance, configure
from physics.linalg.banded_lu import banded_lu, banded_solve
from physics.elastic import elastic_gradient_kernel, elastic_hessian_banded_kernel
from physics.solvers.newton_krylov import banded_matvec_add, head_flow_apply
from physics.params import RPM_TO_RAD_S
from tests.physics.chord_reference import converged as converged_forces, correction_size


def _buckled(contact: bool, n_nodes: int = 40, seconds: float = 1.8) -> Simulator:
    """A fixed-head swimmer at 300 rpm (the stress corner), buckled and (with contact) touching itself."""
    p, n = configure("faithful", {"n_nodes": n_nodes, "head_rotation": "fixed", "integrator": "bdf3",
                                  "newton_krylov": True, "contact": contact})
    sim = Simulator(p, n)
    sim.set_motor_speed(300 * RPM_TO_RAD_S)
    advance(sim, seconds)
    return sim


def _torque_free(n_nodes: int = 24) -> Simulator:
    p, n = configure("faithful", {"n_nodes": n_nodes, "integrator": "bdf3", "newton_krylov": True,
                                  "head_rotation": "torque_free"})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    advance(sim, 0.5)
    return sim


def _open_step(sim: Simulator, h: float = 0.01):
    """Set up the mobility system of a step of h from the current state, as the simulator does."""
    base = sim._base_for(h)
    q = sim._step_start(base)
    solver = sim.solver
    solver._refresh_hydro(q, lazy=True)
    solver.Qh = np.eye(3)
    ms = solver.mobility
    ms.begin(solver.hyd, q, base.h_eff)
    first = 1 if sim.params.has_head else 0
    y = -sim.node_forces[first:].ravel()
    return ms, q, y, base.h_eff


@pytest.mark.parametrize("make", [_torque_free, lambda: _buckled(True)], ids=["torque-free head", "buckled, contact"])
def test_jacobian_vector_product_matches_the_assembled_jacobian(make):
    """With w = C B P v / h (the forces the velocity v/h induces), J (v, w) = (J_direct v, 0): the mobility form
    is the direct solver's Newton system with the forces eliminated."""
    sim = make()
    ms, q, y, h = _open_step(sim)
    J = sim.solver.dense_jacobian(q, h, sim.solver.hyd.dense())
    rng = np.random.default_rng(1)
    v = rng.normal(size=q.size) * np.where(np.arange(q.size) % 4 == 3, 1.0, sim.params.rod_radius)
    v[sim.prescribed] = 0.0
    V = v[sim.vdofs] / h
    w = sim.solver.hyd.solve(head_flow_apply(V, ms.H, ms.g, sim.solver.hyd.has_head, sim.solver.hyd.spin))
    out = ms.jacobian_vector(q, h, np.concatenate([v, w]))
    ref = J @ v
    assert np.abs(out[:q.size] - ref).max() < 1e-9 * np.abs(ref).max()
    assert np.abs(out[q.size:]).max() < 1e-9 * ms.sigma * np.abs(sim.solver.hyd.a @ w).max()


@pytest.mark.parametrize("contact", [True, False], ids=["contact", "no contact"])
def test_jacobian_vector_product_matches_central_differences_of_the_residual(contact):
    """J z against (r(q + e z) - r(q - e z)) / 2e for the stacked residual (r_q, r_y) of a buckled snapshot:
    exactly for everything but the elastic Hessian K, which is the symmetric part of the gradient's derivative
    (checked against finite differences in tests/physics/test_time_integrator.py and test_rod_energy.py)."""
    sim = _buckled(contact)
    ms, q, y, h = _open_step(sim)
    rng = np.random.default_rng(2)
    dq = rng.normal(size=q.size) * np.where(np.arange(q.size) % 4 == 3, 1.0, sim.params.rod_radius)
    dq[sim.prescribed] = 0.0
    dy = rng.normal(size=y.size) * np.abs(y).max()
    z = np.concatenate([dq, dy])
    eps = 1e-6

    def stacked_without_elastic(qq, yy):
        r, r_y, grad, *_ = ms.residual(qq, yy, h)
        t, d1, d2, rt, m1, m2 = sim.frames_at(qq)
        return np.concatenate([r - elastic_gradient_kernel(qq, d1, d2, rt, m1, m2, *sim.rest_arrays), r_y])

    fd = (stacked_without_elastic(q + eps * dq, y + eps * dy)
          - stacked_without_elastic(q - eps * dq, y - eps * dy)) / (2 * eps)
    t, d1, d2, rt, m1, m2 = sim.frames_at(q)
    kv = np.zeros(z.size)
    banded_matvec_add(elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, *sim.rest_arrays), dq, kv[:q.size])
    jz = ms.jacobian_vector(q, h, z) - kv
    free = np.setdiff1d(np.arange(z.size), sim.prescribed)
    np.testing.assert_allclose(jz[free], fd[free], atol=1e-7 * np.abs(fd).max())
    if contact:
        assert sim.contact_count > 0


@pytest.mark.parametrize("contact", [True, False], ids=["contact", "no contact"])
def test_gmres_converges_on_a_buckled_snapshot(contact):
    sim = _buckled(contact)
    if contact:
        assert sim.contact_count > 0  # the snapshot has the rod touching itself
    assert sim.end_to_end_ratio() < 0.8  # and it is buckled
    ms, q, y, h = _open_step(sim)
    r, r_y, *_ = ms.residual(q, y, h)
    b = np.concatenate([r, r_y])
    for rtol in (1e-3, 1e-8):
        z, its, reached = ms.direction(q, h, b, rtol, 120)
        assert 0 < its <= 60, (rtol, its, reached)
        true = np.linalg.norm(ms.jacobian_vector(q, h, z) - b) / np.linalg.norm(b)
        assert true <= 1.01 * rtol and reached <= rtol
    assert ms.direction(q, h, b, 1e-4, 120)[1] <= 20  # the preconditioner keeps the count small


def _python_iteration(ms, q, y, h):
    """The Newton-Krylov iteration as it was written in Python before it was compiled (one direction per
    ``ms.direction`` call, the residual by ``ms.residual``): the reference of the compiled loop."""
    from physics.solvers.implicit_residual import block_max_abs
    from physics.solvers.newton_krylov import GMRES_RTOL

    sim = ms.state  # the simulator (MobilityStep.state)
    nm, p = sim.numerics, sim.params
    nd = q.size
    step_scale = max(block_max_abs(q - sim.q, sim._pos), 1e-6 * p.rod_radius)
    rate = ms.contraction
    rate.start()
    for it in range(nm.newton_max_iter):
        r, r_y, grad, f, inertia, frames = ms.residual(q, y, h)
        y_scale = max(float(np.abs(f).max()), sim._f_floor)
        if converged_forces(sim, r, grad, f, inertia) and float(np.abs(r_y).max()) <= nm.newton_tol * y_scale:
            return q, r, grad, f, frames, it + 1
        z, its, _ = ms.direction(q, h, np.concatenate([r, r_y]), GMRES_RTOL)
        assert its > 0
        q = q - z[:nd]
        y = y - z[nd:]
        dz = block_max_abs(z[:nd], sim._pos)
        converged = (it >= 1 and dz <= max(nm.newton_tol * step_scale, 1e-10 * p.rod_radius)
                     and block_max_abs(z[:nd], sim._twist) <= max(nm.newton_tol, 1e-10))
        if not converged:
            converged = rate.converged(correction_size(sim, z[:nd]) / nm.step_tol)
        if converged:
            r, r_y, grad, f, inertia, frames = ms.residual(q, y, h)
            return q, r, grad, f, frames, it + 1
    raise AssertionError("the Python iteration did not converge")


@pytest.mark.parametrize("make, h", [(_torque_free, 0.03), (lambda: _buckled(True), 0.01)],
                         ids=["torque-free head", "buckled, contact"])
def test_compiled_iteration_is_the_python_iteration_bit_for_bit(make, h):
    """``MobilityStep.solve`` (one compiled call) gives exactly the iterate, forces and frames of the Python
    iteration it replaced, from the same step set-up, contact state and contraction-rate state."""
    import copy

    sim = make()
    ms, q, y, h = _open_step(sim, h)  # a step the predictor does not solve
    saved = copy.deepcopy((sim.contact_state(sim.q)[1], sim.last_contact))
    rate = (ms.contraction.rho, ms.contraction.age)
    n0 = sim.stats.newton_iterations
    ref = _python_iteration(ms, q.copy(), y.copy(), h)
    sim.keep_contact_state(saved[0], *saved[1])
    ms.contraction.rho, ms.contraction.age = rate
    got = ms.solve(q.copy(), y.copy(), h)
    assert ref[5] >= 2 and sim.stats.newton_iterations - n0 == ref[5]  # at least one GMRES direction
    for a, b in zip(got[:4], ref[:4]):
        assert np.array_equal(a, b)
    for a, b in zip(got[4], ref[4]):
        assert np.array_equal(a, b)
    if make is not _torque_free:
        assert sim.last_contact[1] > 0  # contact was active in the step compared


def test_newton_krylov_step_equals_the_direct_step():
    """The same steps (fixed BDF3 steps of 5 ms from the same state) by the direct chord iteration and by
    Newton-Krylov, both to a tight Newton tolerance: the same configuration after 0.3 s at 150 rpm."""
    ends = {}
    for nk in (False, True):
        p, n = configure("faithful", {"n_nodes": 40, "integrator": "bdf3", "newton_krylov": nk, "step_tol": 0.0,
                                      "dt": 0.005, "newton_tol": 1e-10, "hydro_refresh_tol": 0.0})
        sim = Simulator(p, n)
        sim.set_motor_speed(150 * RPM_TO_RAD_S)
        advance(sim, 0.3)
        ends[nk] = (sim.q.copy(), sim.stats.krylov_steps)
    assert ends[True][1] > 0 and ends[False][1] == 0
    dx = np.abs(ends[True][0] - ends[False][0])
    pos = np.arange(dx.size) % 4 != 3
    assert dx[pos].max() < 1e-6 * 1e-3 and dx[~pos].max() < 1e-6


def test_compiled_banded_lu_is_lapacks():
    rng = np.random.default_rng(3)
    kl = 10
    for shift in (5.0, 0.1):  # diagonally dominant, and one that pivots
        ab = np.zeros((3 * kl + 1, 200))
        ab[kl:] = rng.normal(size=(2 * kl + 1, 200))
        ab[2 * kl] += shift
        lub, piv, info = lapack.dgbtrf(ab, kl, kl)
        b = rng.normal(size=200)
        x_ref, _ = lapack.dgbtrs(lub, kl, kl, b, piv)
        s = np.ascontiguousarray(ab.T)
        p2, info2 = banded_lu(s, kl, kl)
        assert info2 == info == 0 and np.array_equal(p2, piv)
        np.testing.assert_allclose(banded_solve(s, kl, kl, p2, b), x_ref, rtol=1e-12, atol=1e-12 * np.abs(x_ref).max())


def test_compiled_banded_cholesky_is_lapacks():
    from scipy.linalg import cho_solve_banded, cholesky_banded

    from physics.linalg.banded_cholesky import banded_cholesky, banded_cholesky_solve

    rng = np.random.default_rng(5)
    n, kd = 150, 10
    lower = np.zeros((kd + 1, n))
    lower[1:] = rng.normal(size=(kd, n))
    lower[0] = 2.0 * kd + rng.random(n)  # diagonally dominant: positive definite
    for d in range(1, kd + 1):
        lower[d, n - d:] = 0.0
    ref = cholesky_banded(lower, lower=True)
    c = np.ascontiguousarray(lower.T)
    assert banded_cholesky(c, kd) == 0
    np.testing.assert_allclose(c, ref.T, rtol=1e-13, atol=1e-13)
    b = rng.normal(size=n)
    np.testing.assert_allclose(banded_cholesky_solve(c, kd, b), cho_solve_banded((ref, True), b), rtol=1e-12)


def test_in_place_banded_solves_are_the_allocating_ones_bit_for_bit():
    from physics.linalg.banded_cholesky import banded_cholesky, banded_cholesky_solve, banded_cholesky_solve_in_place
    from physics.solvers.newton_krylov import factor_solve, factor_solve_in_place, factor_symmetric_band

    rng = np.random.default_rng(7)
    n, kd = 120, 10
    c = rng.normal(size=(n, kd + 1))
    c[:, 0] = 2.0 * kd + rng.random(n)
    assert banded_cholesky(c, kd) == 0
    b = rng.normal(size=n)
    x = b.copy()
    banded_cholesky_solve_in_place(c, kd, x)
    assert np.array_equal(x, banded_cholesky_solve(c, kd, b))
    band = rng.normal(size=(2 * kd + 1, n))  # not symmetric, not definite: the LU path of factor_solve
    f, piv, info = factor_symmetric_band(band)
    assert info == 0 and piv.size == n
    x = b.copy()
    factor_solve_in_place(f, piv, kd, x)
    assert np.array_equal(x, factor_solve(f, piv, kd, b))


def test_banded_matvec_adds_in_the_order_of_a_column_by_column_product():
    """Diagonal by diagonal, each out[i] still receives its terms in the order of increasing j (bit for bit),
    and columns with v[j] = 0 add nothing (not even a signed zero)."""
    rng = np.random.default_rng(8)
    bw, n = 10, 97
    ab = rng.normal(size=(2 * bw + 1, n))
    v = rng.normal(size=n)
    v[[0, 5, n - 1]] = 0.0
    ab[:, 5] = np.inf  # skipped: v[5] = 0
    out0 = rng.normal(size=n)
    out0[3] = -0.0
    ref = out0.copy()
    for j in range(n):
        if v[j] != 0.0:
            for i in range(max(0, j - bw), min(n, j + bw + 1)):
                ref[i] += ab[bw + i - j, j] * v[j]
    out = out0.copy()
    banded_matvec_add(ab, v, out)
    assert np.array_equal(out, ref) and np.array_equal(np.signbit(out), np.signbit(ref))


def test_a_symmetric_band_that_is_not_positive_definite_is_factorised_by_lu():
    from physics.solvers.newton_krylov import factor_solve, factor_symmetric_band

    rng = np.random.default_rng(6)
    n, bw = 60, 10
    dense = np.zeros((n, n))
    for i in range(n):
        for j in range(max(0, i - bw), min(n, i + bw + 1)):
            dense[i, j] = rng.normal()
    dense = dense + dense.T
    for shift, cholesky in ((0.0, False), (60.0, True)):  # indefinite, then positive definite
        S = dense + shift * np.eye(n)
        band = np.zeros((2 * bw + 1, n))
        for j in range(n):
            for i in range(max(0, j - bw), min(n, j + bw + 1)):
                band[bw + i - j, j] = S[i, j]
        f, piv, info = factor_symmetric_band(band)
        assert info == 0 and (piv.size == 0) == cholesky
        b = rng.normal(size=n)
        np.testing.assert_allclose(factor_solve(f, piv, bw, b), np.linalg.solve(S, b), rtol=1e-9, atol=1e-12)


def test_a_run_that_cannot_meet_its_tolerance_raises_simulation_error_with_newton_krylov():
    p, n = configure("faithful", {"n_nodes": 20, "integrator": "bdf3", "newton_krylov": True, "step_tol": 1e-12,
                                  "h_start": 1e-3, "h_min": 5e-4})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    with pytest.raises(SimulationError) as info:
        advance(sim, 1.0)
    err = info.value
    assert err.quantity == "local error" and math.isfinite(err.time_s) and f"step {err.step}" in str(err)
