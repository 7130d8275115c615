"""Time integration (physics/integrate/time_integrator.py and the simulator's adaptive steps): the BDF2 formulas,
the error estimate and controller, the order of each scheme on a burst, exact switch times, the Newton
Jacobian against finite differences, and SimulationError when the step cannot be made small enough."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.elastic import banded_to_dense, elastic_hessian_banded_kernel
from physics import MotorSchedule, Simulator, SimulationError, advance, configure, run_simulation
from physics.params import RPM_TO_RAD_S
from tests.physics.chord_reference import scene_residual
from physics.integrate.adaptive_state import AdaptiveState
from physics.integrate.adaptive_step import commit_point, local_error, push_point
from physics.integrate.time_integrator import (GROW_MAX, SCHEME_ORDER, extrapolate_kernel, next_step, split_remaining,
                                              step_spans)


def _quadratic(t):
    return np.array([1.0 + 2.0 * t - 3.0 * t * t, 0.5 * t * t, -t])


def _history(times, f):
    """The controller's points at ``times`` on the curve f (zero velocities), as the simulator keeps them."""
    nd = len(f(times[0]))
    st = AdaptiveState.empty(0.1, nd, 1)
    st.restart_at(times[0], f(times[0]), np.zeros(nd))
    for t in times[1:]:
        st.count = push_point(st.times, st.qs, st.vs, st.count, t, f(t), np.zeros(nd))
    return st


def step_base(st, h, scheme):
    return st.base(h, SCHEME_ORDER[scheme])


def velocity_of(q_new, base):
    """The velocity the commit gives the point q_new of the step ``base`` (``adaptive_step.commit_point``)."""
    times, qs, vs = np.zeros(5), np.zeros((5, q_new.size)), np.zeros((5, q_new.size))
    v, _, _ = commit_point(q_new, base.q_hat, base.q_hat, base.h, base.h_eff, base.order, 1.0, True, times, qs, vs,
                           0, np.zeros(3), np.zeros(4), np.zeros((4, 3)), 0)
    return v


def error_norm(q_new, base, weights, tol):
    return local_error(q_new, base.q_pred, -1.0 if base.error_ratio is None else base.error_ratio, weights, tol)


def test_bdf2_is_exact_for_quadratics_with_variable_steps():
    hist = _history([0.0, 0.3, 0.4], _quadratic)  # steps 0.3, 0.1, then 0.25
    base = step_base(hist, 0.25, "bdf2")
    assert base.order == 2
    t = 0.65
    v = velocity_of(_quadratic(t), base)
    np.testing.assert_allclose(v, [2.0 - 6.0 * t, t, -1.0], rtol=1e-12, atol=1e-12)
    # and the predictor (quadratic through three points) is exact too, so the estimate is zero
    np.testing.assert_allclose(base.q_pred, _quadratic(t), atol=1e-12)
    assert error_norm(_quadratic(t), base, np.ones(3), 1e-6) == pytest.approx(0.0, abs=1e-6)


def test_error_ratios_of_the_estimate_are_the_classic_constants_at_constant_steps():
    cubic = lambda t: np.array([t**3, 0.0, 0.0])  # noqa: E731
    hist = _history([0.0, 0.1, 0.2], cubic)
    base = step_base(hist, 0.1, "bdf2")
    assert base.error_ratio == pytest.approx(2.0 / 9.0)
    assert step_base(_history([0.0, 0.1], cubic), 0.1, "euler").error_ratio == pytest.approx(0.5)
    # right after a restart there is no estimate (the motion may have a kink there)
    assert step_base(_history([0.2], cubic), 0.1, "bdf2").error_ratio is None


def test_estimate_matches_the_true_local_error_of_bdf2_on_a_cubic():
    """For q = t^3 the BDF2 step's true local error and the Milne estimate agree (constant steps)."""
    h = 0.01
    cubic = lambda t: np.array([t**3])  # noqa: E731
    hist = _history([0.0, h, 2 * h], lambda t: np.array([t**3]))
    base = step_base(hist, h, "bdf2")
    # solve the BDF2 step for q' = 3 t^2 exactly: (q - q^) / h_e = 3 t^2
    t = 3 * h
    q_new = base.q_hat + base.h_eff * 3.0 * t * t
    true_err = abs(q_new[0] - cubic(t)[0])
    est = error_norm(q_new, base, np.ones(1), 1.0)
    assert est == pytest.approx(true_err, rel=1e-6)


def test_controller_and_end_of_step_splitting():
    assert next_step(0.1, 0.0, 2) == pytest.approx(GROW_MAX * 0.1)
    assert next_step(0.1, 1.1, 2) < 0.1
    assert next_step(0.1, 0.5, 2) == 0.1  # a small growth keeps h (the factorisation stays valid)
    assert split_remaining(0.1, 0.12) == 0.12
    assert split_remaining(0.1, 0.15) == pytest.approx(0.075)
    assert split_remaining(0.1, 0.5) == 0.1
    n = configure("faithful")[1]
    spans = step_spans(0.25, n)
    assert spans == [None, None, pytest.approx(0.05)]
    assert len(step_spans(0.25, configure("paper")[1])) == 250


def _burst_end(integrator: str, dt: float, step_tol: float = 0.0) -> np.ndarray:
    """Node positions after a 0.4 s burst at 150 rpm from rest (a rod of 24 nodes, so the test is cheap; the parameter
    defaults otherwise). The resistance is rebuilt at every step, so every step is solved by Newton-Krylov, the
    presets' solver where the shape changes (the chord iteration fails at some of the large steps and would shrink
    them: the error would then not be the scheme's)."""
    p, n = configure(None, {"n_nodes": 24, "integrator": integrator, "dt": dt, "step_tol": step_tol,
                            "newton_tol": 1e-9, "jacobian_refresh": "resistance", "hydro_refresh_tol": 0.0,
                            "newton_krylov": True})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    advance(sim, 0.4)
    assert sim.time == pytest.approx(0.4)
    return sim.nodes


@pytest.fixture(scope="module")
def burst_reference():
    return _burst_end("bdf2", 0.4 / 512)


def test_fixed_step_orders_on_a_burst(burst_reference):
    """Halving h divides the error by ~2 with implicit Euler and by ~4 with BDF2."""
    errs = {}
    for scheme in ("euler", "bdf2"):
        errs[scheme] = [float(np.abs(_burst_end(scheme, h) - burst_reference).max()) for h in (0.4 / 32, 0.4 / 64)]
    euler_ratio = errs["euler"][0] / errs["euler"][1]
    bdf2_ratio = errs["bdf2"][0] / errs["bdf2"][1]
    assert 1.6 < euler_ratio < 2.6, errs
    assert bdf2_ratio > 3.0, errs
    assert errs["bdf2"][1] < 0.2 * errs["euler"][1]


def test_adaptive_error_falls_with_the_tolerance_at_the_schemes_order(burst_reference):
    """With the local error per step held at tol, the global error of a p-th order scheme goes as
    tol^(p/(p+1)): dividing tol by 8 divides BDF2's error by ~4 (at least 2.5 here)."""
    e1 = float(np.abs(_burst_end("bdf2", 0.1, 8e-3) - burst_reference).max())
    e2 = float(np.abs(_burst_end("bdf2", 0.1, 1e-3) - burst_reference).max())
    assert e1 / e2 > 2.5, (e1, e2)


def test_a_schedule_switch_is_a_step_boundary_and_restarts_the_history():
    """A switch at 0.35 s inside a 0.1 s control step: one accepted step ends exactly there and the next one
    starts afresh (implicit Euler at h_start)."""
    p, n = configure("faithful", {"n_nodes": 24})
    sim = Simulator(p, n)
    sim.compiled_span = False  # the Python step, whose commits the spy sees (the span is it, bit for bit)
    ends, orders = [], []
    commit = sim._commit

    def spy(q, base, *args, **kwargs):
        commit(q, base, *args, **kwargs)
        ends.append(sim.time)
        orders.append((base.order, base.h, sim.omega))

    sim._commit = spy
    result = run_simulation(p, n, MotorSchedule(((0.0, 10.0), (0.35, 150.0))), 0.6, record_interval_s=0.1,
                            progress=False, simulator=sim)
    assert result.error is None and sim.time == pytest.approx(0.6)
    i = int(np.argmin(np.abs(np.array(ends) - 0.35)))
    assert ends[i] == pytest.approx(0.35, abs=1e-12)
    order, h, omega = orders[i + 1]
    assert order == 1 and h == pytest.approx(n.h_start) and omega == pytest.approx(150 * RPM_TO_RAD_S)
    assert all(o[2] == pytest.approx(10 * RPM_TO_RAD_S) for o in orders[: i + 1])


def test_extrapolate_is_exact_for_polynomials_one_degree_below_its_points():
    rng = np.random.default_rng(3)
    for k in (1, 2, 3, 4):
        times = np.sort(rng.uniform(0.0, 0.05, k))
        t_new = times[-1] + rng.uniform(0.001, 0.02)
        coef = rng.standard_normal((k + 1, 4))

        def poly(t, degree):
            return sum(coef[j] * t ** j for j in range(degree + 1))

        exact = extrapolate_kernel(times, np.array([poly(t, k - 1) for t in times]), t_new)
        np.testing.assert_allclose(exact, poly(t_new, k - 1), rtol=1e-9, atol=1e-12)
        above = extrapolate_kernel(times, np.array([poly(t, k) for t in times]), t_new)  # one degree more: missed
        assert np.max(np.abs(above - poly(t_new, k))) > 1e-9


def test_newton_krylov_starts_the_forces_from_their_extrapolation_and_not_across_a_switch():
    """The force unknowns of a Newton-Krylov step start from the cubic through the last four accepted steps' node
    forces; a motor-speed change restarts that history (its first step starts from the last forces)."""
    p, n = configure("faithful", {"n_nodes": 24})
    sim = Simulator(p, n)
    sim.compiled_span = False  # the Python step, whose solves the spy sees (the span is it, bit for bit)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, 0.5)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    assert sim.adaptive.force_count == 0
    starts = []
    solve = sim.solver.mobility.solve

    def spy(q, y, h):
        st = sim.adaptive
        k = st.force_count
        expected = (extrapolate_kernel(st.force_times[:k].copy(), st.force_values[:k].copy(), sim.time + sim._base.h)
                    if k else sim.node_forces.ravel())
        starts.append((k, np.array_equal(y, -expected[3:])))
        return solve(q, y, h)

    sim.solver.mobility.solve = spy
    advance(sim, 1.0)
    assert starts and all(same for _, same in starts)
    assert 4 in {k for k, _ in starts}  # the cubic (the first steps after the switch reuse the resistance)
    assert sim.adaptive.force_count == 4


def test_newton_jacobian_matches_finite_differences_of_the_bdf2_residual():
    """dr/dq of the implicit step (BDF2 base, h_e; elastic + hydrodynamic + inertia + contact) against central
    differences of the residual, at a bent, twisted state after a burst."""
    p, n = configure("faithful", {"n_nodes": 20, "jacobian_refresh": "resistance"})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    advance(sim, 0.5)
    base = sim._base_for(0.02)
    q = sim._step_start(base)  # the predictor with the motor's twist, and the contact broad phase around it
    solver = sim.solver
    solver.begin_step(q, base.h_eff)
    solver._refresh_hydro(q)
    solver.Qh = np.eye(3)
    J = solver.dense_jacobian(q, base.h_eff, solver.hyd.dense())
    t, d1, d2, rt, m1, m2 = sim.frames_at(q)
    K = banded_to_dense(elastic_hessian_banded_kernel(q, d1, d2, rt, m1, m2, *sim.rest_arrays))
    free = np.setdiff1d(np.arange(q.size), sim.prescribed)
    fd_rest = np.zeros((q.size, q.size))  # inertia + hydrodynamics (+ contact, none here)
    fd_grad = np.zeros((q.size, q.size))  # elastic gradient
    for j in free:
        eps = 1e-7 * (p.rod_radius if j % 4 != 3 else 1.0)
        qp, qm = q.copy(), q.copy()
        qp[j] += eps
        qm[j] -= eps
        (rp, gp, *_), (rm, gm, *_) = scene_residual(sim, qp, base.h_eff), scene_residual(sim, qm, base.h_eff)
        fd_rest[:, j] = ((rp - gp) - (rm - gm)) / (2 * eps)
        fd_grad[:, j] = (gp - gm) / (2 * eps)
    sub = np.ix_(free, free)
    scale = np.abs(J[sub]).max()
    np.testing.assert_allclose((J - K)[sub], fd_rest[sub], atol=1e-7 * scale)
    # The elastic Hessian is exact where the frames were last updated (the step's start): there it is the
    # symmetric part of the gradient's derivative (as in tests/physics/test_rod_energy.py). Away from it (here
    # the predictor, 0.24 rad of twist later) it drops the frames' transport: ~2e-4 of its largest entry,
    # which slows the chord iteration a little and changes nothing it converges to.
    assert np.abs(K - 0.5 * (fd_grad + fd_grad.T))[sub].max() < 1e-3 * scale
    q0 = sim.q.copy()
    t, d1, d2, rt, m1, m2 = sim.frames_at(q0)
    K0 = banded_to_dense(elastic_hessian_banded_kernel(q0, d1, d2, rt, m1, m2, *sim.rest_arrays))
    for j in free:
        eps = 1e-7 * (p.rod_radius if j % 4 != 3 else 1.0)
        qp, qm = q0.copy(), q0.copy()
        qp[j] += eps
        qm[j] -= eps
        fd_grad[:, j] = (scene_residual(sim, qp, base.h_eff)[1] - scene_residual(sim, qm, base.h_eff)[1]) / (2 * eps)
    np.testing.assert_allclose(K0[sub], 0.5 * (fd_grad + fd_grad.T)[sub], atol=1e-6 * np.abs(K0).max())


def test_adaptive_run_that_cannot_meet_its_tolerance_raises_simulation_error():
    p, n = configure("faithful", {"n_nodes": 20, "step_tol": 1e-12, "h_start": 1e-3, "h_min": 5e-4})
    sim = Simulator(p, n)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    with pytest.raises(SimulationError) as info:
        advance(sim, 1.0)
    err = info.value
    assert err.quantity == "local error" and math.isfinite(err.time_s) and err.step >= 0
    assert "h_min" in str(err) and f"step {err.step}" in str(err)


def test_step_duration_is_checked():
    sim = Simulator(*configure("faithful", {"n_nodes": 20}))
    with pytest.raises(ValueError, match="allowed: > 0 and <= dt"):
        sim.step(0.5)
    fixed = Simulator(*configure("paper", {"n_nodes": 20}))
    with pytest.raises(ValueError, match="fixed steps"):
        fixed.step(0.005)


def test_compiled_jacobian_assembly_is_bit_identical_to_the_numpy_form():
    """``assemble_dense_jacobian`` replaced banded_to_dense + diagonal + np.ix_ (an exact rewrite), and
    ``rotate_dense_blocks`` replaced T R T^T with block-diagonal T (the same sums in another order)."""
    from physics.solvers.implicit_residual import assemble_dense_jacobian, rotate_dense_blocks
    from physics.model.rigid_alignment import best_fit_rotation

    rng = np.random.default_rng(0)
    nd = 4 * 12 - 1
    ab = rng.normal(size=(21, nd))
    mass = rng.uniform(1e-6, 1e-5, nd)
    vdofs = np.concatenate([np.array([k for k in range(nd) if k % 4 != 3]), [3]])
    R = rng.normal(size=(vdofs.size, vdofs.size))
    h = 0.0137
    J = banded_to_dense(ab)
    J[np.diag_indices_from(J)] += mass / h**2
    J[np.ix_(vdofs, vdofs)] += R / h
    np.testing.assert_array_equal(assemble_dense_jacobian(ab, mass, h, R, vdofs), J)
    x = rng.normal(size=(12, 3))
    Q = best_fit_rotation(x, x @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T)[0]
    T = np.eye(R.shape[0])
    for i in range((R.shape[0] - 1) // 3):
        T[3 * i:3 * i + 3, 3 * i:3 * i + 3] = Q
    np.testing.assert_allclose(rotate_dense_blocks(R, Q, True), T @ R @ T.T, rtol=0, atol=1e-13 * np.abs(R).max())


@pytest.mark.parametrize("scheme,order", [("bdf3", 3), ("bdf4", 4)])
def test_higher_order_bdf_is_exact_for_polynomials_of_its_order_with_variable_steps(scheme, order):
    poly = lambda t: np.array([t**order - 2.0 * t + 1.0, 0.3 * t ** (order - 1), -t])  # noqa: E731
    dpoly = lambda t: np.array([order * t ** (order - 1) - 2.0, 0.3 * (order - 1) * t ** (order - 2), -1.0])  # noqa: E731
    times = list(np.cumsum([0.0, 0.3, 0.1, 0.25, 0.15, 0.2])[: order + 2])
    hist = _history(times, poly)
    base = step_base(hist, 0.17, scheme)
    assert base.order == order
    t = times[-1] + 0.17
    np.testing.assert_allclose(velocity_of(poly(t), base), dpoly(t), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(base.q_pred, poly(t), atol=1e-10)  # the predictor is exact too


def test_error_ratios_of_higher_orders_are_the_classic_constants_and_the_order_ramps_up():
    """k = |C_{p+1}| of BDF-p over the predictor's constant: 3/22 (BDF3), 12/125 (BDF4) at constant steps; after a
    restart the order climbs 1, 2, 2, 3, 4 (an order above 2 only with its estimate)."""
    f = lambda t: np.array([t**5])  # noqa: E731
    assert step_base(_history([0.0, 0.1, 0.2, 0.3], f), 0.1, "bdf3").error_ratio == pytest.approx(3.0 / 22.0)
    assert step_base(_history([0.0, 0.1, 0.2, 0.3, 0.4], f), 0.1, "bdf4").error_ratio == pytest.approx(12.0 / 125.0)
    orders = [step_base(_history([0.1 * k for k in range(npts)], f), 0.1, "bdf4").order for npts in range(1, 6)]
    assert orders == [1, 2, 2, 3, 4]


@pytest.mark.parametrize("scheme,order", [("bdf3", 3), ("bdf4", 4)])
def test_estimate_matches_the_true_local_error_of_higher_orders(scheme, order):
    """For q = t^(p+1) the true local error of a BDF-p step and the Milne estimate agree (constant steps)."""
    h = 0.01
    f = lambda t: np.array([t ** (order + 1)])  # noqa: E731
    hist = _history([k * h for k in range(order + 1)], f)
    base = step_base(hist, h, scheme)
    t = (order + 1) * h
    q_new = base.q_hat + base.h_eff * (order + 1) * t**order  # the step solved exactly for q' = (p+1) t^p
    true_err = abs(q_new[0] - f(t)[0])
    assert error_norm(q_new, base, np.ones(1), 1.0) == pytest.approx(true_err, rel=1e-6)


@pytest.mark.parametrize("scheme,order", [("bdf3", 3), ("bdf4", 4)])
def test_adaptive_error_of_higher_orders_falls_with_the_tolerance(burst_reference, scheme, order):
    """Held at tol per step, a p-th order scheme's error goes as tol^(p/(p+1)): dividing tol by 8 must divide the
    burst's error by at least 3 (BDF3: 4.8 expected, BDF4: 5.3)."""
    e1 = float(np.abs(_burst_end(scheme, 0.1, 8e-3) - burst_reference).max())
    e2 = float(np.abs(_burst_end(scheme, 0.1, 1e-3) - burst_reference).max())
    assert e1 / e2 > 3.0, (e1, e2)


def _bdf_coefficients_python(t_new, times):
    """``bdf_coefficients`` as it was written in Python before it was compiled: the reference."""
    tau = [t_new] + list(reversed(times))
    k = len(tau) - 1
    alpha = np.empty(k + 1)
    alpha[0] = sum(1.0 / (tau[0] - tau[m]) for m in range(1, k + 1))
    for j in range(1, k + 1):
        num = 1.0
        for m in range(1, k + 1):
            if m != j:
                num *= tau[0] - tau[m]
        den = 1.0
        for m in range(k + 1):
            if m != j:
                den *= tau[j] - tau[m]
        alpha[j] = num / den
    return alpha


def _step_base_python(pts, h, scheme):
    """The step's base as it was written in Python before it was compiled (``base_kernel``), from the points
    [(t, q, v), ...] oldest first: the reference."""
    from physics.integrate.time_integrator import StepBase

    top = SCHEME_ORDER[scheme]
    order = 1 if len(pts) == 1 or top == 1 else max(2, min(top, len(pts) - 1))
    t0, q0, v0 = pts[-1]
    if order == 1:
        q_hat, v_hat, h_eff = q0, v0, h
    else:
        use = pts[-order:]
        alpha = _bdf_coefficients_python(t0 + h, [p[0] for p in use])
        q_hat = np.zeros_like(q0)
        v_hat = np.zeros_like(v0)
        for j in range(1, order + 1):
            _, qj, vj = use[-j]
            q_hat -= (alpha[j] / alpha[0]) * qj
            v_hat -= (alpha[j] / alpha[0]) * vj
        h_eff = 1.0 / alpha[0]
    if len(pts) < 2:
        return StepBase(h, h_eff, q_hat, v_hat, q0 + h * v0, order, None)
    use = pts[-(order + 1):]
    t_new = t0 + h
    q_pred = np.zeros_like(q0)
    for i, (ti, qi, _) in enumerate(use):
        w = 1.0
        for m, (tm, _, _) in enumerate(use):
            if m != i:
                w *= (t_new - tm) / (ti - tm)
        q_pred += w * qi
    if len(pts) < order + 1:
        return StepBase(h, h_eff, q_hat, v_hat, q_pred, order, None)
    s = [1.0 / (t_new - p[0]) for p in reversed(use)]
    return StepBase(h, h_eff, q_hat, v_hat, q_pred, order, sum(s) / sum(s[:-1]) - 1.0)


@pytest.mark.parametrize("scheme", ["euler", "bdf2", "bdf3", "bdf4"])
def test_compiled_step_base_is_the_python_one_bit_for_bit(scheme):
    """Random variable-step histories of every length: base values, effective step, predictor and error ratio
    exactly as the Python form computed them."""
    rng = np.random.default_rng(7)
    for trial in range(40):
        st = AdaptiveState.empty(0.1, 487, 1)
        t = float(rng.uniform(0.0, 10.0))
        pts = [(t, rng.normal(size=487), rng.normal(size=487))]
        st.restart_at(*pts[0])
        for npts in range(1, 7):
            h = float(rng.uniform(1e-3, 0.2))
            got, ref = step_base(st, h, scheme), _step_base_python(pts, h, scheme)
            assert (got.h, got.h_eff, got.order, got.error_ratio) == (ref.h, ref.h_eff, ref.order, ref.error_ratio)
            for a, b in ((got.q_hat, ref.q_hat), (got.v_hat, ref.v_hat), (got.q_pred, ref.q_pred)):
                assert np.array_equal(a, b)
            t += h
            pts = (pts + [(t, rng.normal(size=487), rng.normal(size=487))])[-5:]
            st.count = push_point(st.times, st.qs, st.vs, st.count, *pts[-1])


def test_error_norm_is_numpys_weighted_max():
    rng = np.random.default_rng(8)
    from physics.integrate.time_integrator import weighted_max_abs_diff
    a, b, w = rng.normal(size=487), rng.normal(size=487), rng.uniform(0.5, 1e3, size=487)
    assert weighted_max_abs_diff(a, b, w) == float(np.max(np.abs(a - b) * w))
    a[100] = np.nan
    assert math.isnan(weighted_max_abs_diff(a, b, w))


def _collapsing_start(monkeypatch=None, **patch):
    """BDF3 at step_tol 1e-7 from rest at 10 rpm: its steps collapse to microseconds (docs/time_integration.md)."""
    import physics.simulator as simulator_module
    from physics import Simulator, advance, configure
    from physics.params import RPM_TO_RAD_S

    for name, value in patch.items():
        monkeypatch.setattr(simulator_module, name, value)
    p, n = configure("faithful", {"step_tol": 1e-7})
    sim = Simulator(p, n)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, 0.05)
    return sim


def test_collapsed_bdf3_steps_continue_at_order_two_from_a_restart(monkeypatch):
    held = _collapsing_start()
    assert held.stats.order_reductions == 1 and held.adaptive.order_capped
    assert held.stats.substeps < 1100 and held.adaptive.h > 1e-4  # 1000 collapsed steps, then BDF2 at ~0.5 ms
    free = _collapsing_start(monkeypatch, COLLAPSED_STEPS=10**9)
    assert free.stats.order_reductions == 0 and free.stats.substeps > 3000 and free.adaptive.h < 1e-5
    held.set_motor_speed(held.omega * 1.01)  # a restart lifts the hold
    held.step(0.001)
    assert not held.adaptive.order_capped


def test_too_much_work_in_a_span_raises_simulation_error(monkeypatch):
    from physics.errors import SimulationError

    with pytest.raises(SimulationError, match="too much work: 50 steps") as info:
        _collapsing_start(monkeypatch, COLLAPSED_STEPS=10**9, MAX_STEPS_PER_SPAN=50)
    assert info.value.quantity == "step size" and info.value.step == 0 and info.value.time_s > 0.0  # the first control step
