"""Consecutive Newton-Krylov steps in one compiled call: while the flagellum buckles, Python enters once per span.

While the swimmer's shape changes (a burst, the relaxation after it) every step rebuilds the LSBT resistance and is
solved by Newton-Krylov (``newton_krylov``); ``Simulator._adaptive`` then spends ~15 % of a step in Python around
the compiled kernels (the step's base, the contact broad phase, the resistance and preconditioner set-up, the error
estimate, the controller, the commit). ``krylov_span`` runs those steps in one compiled call: the same operations in
the same order as the Python step (``Simulator._adaptive``, ``_step_start``, ``DenseChordSolver.begin_step``,
``MobilityStep.begin`` / ``solve``, ``_commit``), so the trajectory is bit-identical
(tests/physics/test_krylov_span.py).

The span returns to Python where the Python step does anything else:

* ``SPAN_CHORD``: the next attempt would reuse the resistance (the shape has not changed by ``hydro_refresh_tol``)
  and either the kept LU is usable or the shape has been calm for ``CALM_STEPS_FOR_LU`` attempts
  (``DenseChordSolver.begin_step``): the chord iteration takes it, in Python;
* ``SPAN_FAILED``: an attempt failed (a singular preconditioner, a failed Newton-Krylov iteration, a stretched edge,
  a step below h_min): the state is returned as it was before that attempt and Python takes it again, so its
  failure is handled (and reported) by the one Python path;
* ``SPAN_AFTER_ACCEPT``: an accepted step reached ``COLLAPSED_STEPS`` (at order > 2) or ``MAX_STEPS_PER_SPAN``:
  Python does what follows (``Simulator._after_accept``);
* ``SPAN_DONE``: the span reached t_end.

Where it applies (``krylov_span_applies``): error-controlled steps with Newton-Krylov and the LSBT resistance of a
head with the reciprocal Higdon forms (``head_model="higdon"``, ``head_rotation`` torque_free or fixed: not the
printed forms of ``paper`` nor the spin-coupled mobility of ``literal``), the previous attempt
solved by Newton-Krylov, no restart pending. The timings of ``StepStats`` (``time_*``) are not split inside a span.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from physics.model.body_frame import transported_body_frame
from physics.linalg.compiled_lapack import NUMPY_BLAS, numpy_dot
from physics.forces.contact import contact_broad_phase, contact_kernel
from physics.model.geometry import edge_stretch_extremes, nodes_array
from physics.hydro.higdon_head import head_flow_operators
from physics.hydro.hydrodynamics import ResistanceOperator
from physics.solvers.implicit_residual import block_max_abs
from physics.hydro.lsbt import lsbt_mobility, node_tangents
from physics.solvers.newton_krylov import (CONVERGED, GMRES_MAX_ITER, GMRES_RTOL, newton_krylov_loop,
                                           preconditioner_factors)
from physics.model.rigid_alignment import best_fit_rotation
from physics.forces.step_context import NO_BLOCKS, NO_NODES
from physics.solvers.step_solvers import H_REUSE, CALM_STEPS_FOR_LU
from physics.integrate.time_integrator import (COLLAPSED_STEPS, EXTRAPOLATION_POINTS, MAX_STEPS_PER_SPAN, SAFETY,
                                     SCHEME_ORDER, SHRINK_MIN, base_kernel, extrapolate_kernel, next_step,
                                     order_after, split_remaining, weighted_max_abs_diff)

#: how ``krylov_span`` returned (module doc)
SPAN_DONE, SPAN_CHORD, SPAN_FAILED, SPAN_AFTER_ACCEPT = range(4)
#: the counters a span advances, in this order (``StepStats`` fields)
SPAN_COUNTERS = ("substeps", "newton_iterations", "krylov_iterations", "krylov_steps", "resistance_refreshes",
                 "preconditioner_factorisations", "rejected_steps")
HISTORY_POINTS = 5  # ``time_integrator.History`` keeps five


@njit(cache=True)
def _mobility_parts(x: np.ndarray, mu: float, delta: float, b: float, smoothing: float, near_radius: float):
    """What ``ResistanceOperator(..., factorize_lazily=True)`` builds for a head with the reciprocal Higdon forms at
    nodes x (n, 3) (head centre first), m: the LSBT mobility a (3M, 3M) m/(N s) and the head's flow operators H
    (3M, 3) and g (3M,) m/s per rad/s (g unused unless the head spins)."""
    flag = np.ascontiguousarray(x[1:])
    a = lsbt_mobility(flag, node_tangents(flag), mu, delta, smoothing, near_radius)
    e0 = x[1] - x[0]
    axis = e0 / math.sqrt(numpy_dot(e0, e0))
    H, g = head_flow_operators(flag, x[0].copy(), axis, b)
    return a, H, g


@njit(cache=True)
def krylov_span(static: tuple, consts: tuple, placeholders: tuple, work: tuple, clock: tuple, state: tuple,
                history: tuple, forces: tuple, solver: tuple, cstate: tuple, last_contact: tuple, counters: np.ndarray):
    """Error-controlled Newton-Krylov steps from the simulator's state until t_end or a return to Python (module
    doc). ``counters`` (len(SPAN_COUNTERS),) int64 is advanced in place (restored on ``SPAN_FAILED`` and
    ``SPAN_CHORD`` to its value before the returning attempt). Argument and result tuples: ``run_krylov_span``."""
    (rest, mass, vdofs, prescribed, head_spins, pos, twist, free_twist, weights, contact_on, model, first_step,
     omega) = static
    (mu, delta, b, smoothing, near_radius, drag_t, drag_r, sigma, zeta_perp, zeta_par, abw, step_tol, h_min,
     refresh_dev, refresh_steps, newton_tol, newton_max_iter, f_floor, r0, top_order, gmres_rtol, gmres_max_iter,
     has_head, first, keep_h) = consts
    no_nodes, no_blocks = placeholders
    time, t_end, dt, h_ctl, rejected, accepted, h_prev = clock
    q_cur, v_cur, d1, tangent, ref_twist, body_frame, motor_angle = state
    ht, hq, hv, npts = history
    ft, fy, nfp, node_forces = forces
    x_hyd, since_hydro, rho, age, parts, pre, calm, lu_h, lu_after_rebuild = solver
    e_last, count_last, e_commit, count_commit = last_contact
    v_before = v_cur
    same_h = False  # the last accepted step had the length of the one before it (Simulator._v_prev)
    motor_torque = 0.0
    head_torque = 0.0
    err = 0.0
    h = 0.0
    order = 1
    code = SPAN_DONE
    rebuilt = False  # the resistance was rebuilt in this span (its parts and preconditioner are returned)
    saved = (rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm, cstate, e_last, count_last, counters.copy(),
             rejected)
    while t_end - time > 1e-9 * dt:
        saved = (rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm, cstate, e_last, count_last,
                 counters.copy(), rejected)
        h = split_remaining(h_ctl, t_end - time, not rejected)
        rejected = True  # until the step is accepted
        last = h == t_end - time
        # the step's base (Simulator._base_for; step_base)
        order = order_after(top_order, npts)
        m = min(npts, order + 1)
        q_hat, v_hat, h_eff, q_pred, ratio = base_kernel(ht[npts - m:npts].copy(), hq[npts - m:npts],
                                                         hv[npts - m:npts], h, order)
        # its start and contact broad phase (Simulator._step_start)
        q = q_pred.copy()
        for k in prescribed:
            q[k] = q_cur[k] + h * omega
        x_pred = nodes_array(q)
        if contact_on:
            move = 0.0 if first_step else block_max_abs(q - q_cur, pos)
            pad = max(0.5 * r0, 2.0 * move)
            pairs, head = contact_broad_phase(x_pred, model, pad)
            cstate = (q.copy(), pad, pairs, head, pairs.shape[0] == 0 and head.shape[0] == 0)
        else:
            cstate = (q, 0.0, cstate[2], cstate[3], True)
        # the resistance: rebuilt where the shape has changed, or where a chord step would need a new LU before
        # the swimmer cruises (DenseChordSolver.begin_step, lu_stale); else the chord step
        dev = best_fit_rotation(x_hyd, x_pred)[1]
        changed = since_hydro >= refresh_steps or dev > refresh_dev
        calm = 0 if changed else calm + 1
        stale = (lu_h < 0.0 or not H_REUSE[0] <= h_eff / lu_h <= H_REUSE[1]
                 or (since_hydro == 0 and lu_after_rebuild))
        if not (changed or (calm < CALM_STEPS_FOR_LU and stale)):
            code = SPAN_CHORD
            break
        parts = _mobility_parts(x_pred, mu, delta, b, smoothing, near_radius)
        x_hyd = x_pred
        since_hydro = 0
        rebuilt = True
        counters[4] += 1
        a, H, g = parts
        if not head_spins:  # MobilityStep.begin: no spin flow without a spinning head
            g = np.zeros(a.shape[0])
        Kh = np.ascontiguousarray(-H.T)
        # the preconditioner (MobilityStep.begin)
        nodes_c, blocks_c = no_nodes, no_blocks
        if contact_on and not cstate[4]:
            nodes_c, blocks_c = contact_kernel(x_pred, cstate[2], model[3], cstate[3], model[5], model[6],
                                               model[7])[2:]
        ab, (lu, piv, info), (alu, apiv, ainfo) = preconditioner_factors(
            q, (d1, tangent, ref_twist), rest, mass, h_eff, zeta_perp, zeta_par, first, drag_t, drag_r, nodes_c,
            blocks_c, prescribed, a, abw)
        if info != 0 or ainfo != 0:
            code = SPAN_FAILED
            break
        pre = (ab, lu, piv, alu, apiv, h_eff)
        counters[5] += 1
        counters[3] += 1
        # the forces' start (Simulator._try_step) and the Newton-Krylov iteration (MobilityStep.solve)
        if nfp > 0:
            start = extrapolate_kernel(ft[:nfp].copy(), fy[:nfp].copy(), time + h)
        else:
            start = node_forces.ravel().copy()
        y0 = -start[3:]
        (nk_code, q, y, r, grad, f, frames, cstate, (e_c, count), (evaluated, its), (rho, age), value) = (
            newton_krylov_loop(q, y0, h_eff, q_cur, (d1, tangent, ref_twist), rest, (q_hat, v_hat, h_eff),
                               (mass, vdofs, prescribed, head_spins, omega, pos, twist, free_twist, weights),
                               (a, H, g, Kh, drag_t, drag_r, has_head, head_spins, sigma), contact_on, model, cstate,
                               first_step, (lu, piv, alu, apiv, abw), ab,
                               (newton_tol, newton_max_iter, step_tol, f_floor, r0, gmres_rtol, gmres_max_iter),
                               (rho, age), work))
        counters[1] += evaluated
        counters[2] += its
        if contact_on:
            e_last, count_last = e_c, count
        if nk_code != CONVERGED:
            code = SPAN_FAILED
            break
        # Simulator._check_state
        finite, i_min, r_min, i_max, r_max = edge_stretch_extremes(q, rest[0])
        if not finite or r_min < 0.2 or r_max > 5.0:
            code = SPAN_FAILED
            break
        err = 0.0 if ratio < 0.0 else weighted_max_abs_diff(q, q_pred, weights) * (ratio / (1.0 + ratio)) / step_tol
        if err > 1.0:  # Simulator._reject
            h_new = h * max(SHRINK_MIN, SAFETY * err ** (-1.0 / (order + 1)))
            counters[6] += 1
            if h_new < h_min:
                code = SPAN_FAILED
                break
            h_ctl = h_new
            continue
        rejected = False
        # Simulator._commit
        dq = q - q_cur
        v_before = v_cur
        same_h = h == h_prev
        h_prev = h
        if order == 1 and h_eff == h:
            v_new = dq / h
        else:
            v_new = (q - q_hat) / h_eff
        q_cur, v_cur = q, v_new
        t, d1, d2, ref_twist, m1, m2 = frames
        tangent = t
        time = t_end if last else time + h
        counters[0] += 1
        if npts == HISTORY_POINTS:
            for j in range(HISTORY_POINTS - 1):
                ht[j] = ht[j + 1]
                hq[j] = hq[j + 1]
                hv[j] = hv[j + 1]
            npts -= 1
        ht[npts] = time
        hq[npts] = q_cur
        hv[npts] = v_cur
        npts += 1
        motor_angle += h * omega
        since_hydro += 1
        node_forces = nodes_array(f)
        if nfp == EXTRAPOLATION_POINTS:
            for j in range(EXTRAPOLATION_POINTS - 1):
                ft[j] = ft[j + 1]
                fy[j] = fy[j + 1]
            nfp -= 1
        ft[nfp] = time
        fy[nfp] = node_forces.ravel()
        nfp += 1
        head_torque = f[3] if head_spins else 0.0
        motor_torque = grad[3]
        body_frame = transported_body_frame(body_frame, q[0:3], q[4:7], dq[3] - h * omega, head_spins)
        e_commit, count_commit = e_last, count_last
        accepted += 1
        if (accepted == COLLAPSED_STEPS and order > 2) or accepted >= MAX_STEPS_PER_SPAN:
            code = SPAN_AFTER_ACCEPT
            break
        # Simulator._after_accept (a Newton-Krylov step: no band in which h is kept)
        proposal = next_step(h, err, order, keep_h)
        if h < h_ctl and proposal >= h:
            proposal = max(proposal, h_ctl)
        h_ctl = min(proposal, dt)
    if code == SPAN_CHORD or code == SPAN_FAILED:  # the returning attempt is Python's to take
        rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm, cstate, e_last, count_last, kept, rejected = saved
        counters[:] = kept
    return (code, (time, h_ctl, rejected, accepted, h_prev), (q_cur, v_cur, d1, tangent, ref_twist, body_frame,
            motor_angle), (npts, nfp, node_forces), (rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm), cstate,
            (e_last, count_last, e_commit, count_commit), (v_before, same_h, motor_torque, head_torque),
            (h, err, order))


def krylov_span_applies(sim: Any) -> bool:
    """Does ``krylov_span`` take the simulator's next attempt? (module doc: the configurations it covers, and the
    previous attempt solved by Newton-Krylov with no restart pending)."""
    nm, p = sim.numerics, sim.params
    solver = sim._solver
    return (sim.compiled_span and NUMPY_BLAS and nm.step_tol > 0.0 and nm.newton_krylov and not nm.single_iteration
            and nm.hydro_model == "lsbt" and nm.head_model == "higdon" and p.has_head
            and p.head_rotation in ("torque_free", "fixed")
            and not sim._restart and getattr(solver, "krylov", False) and solver.hyd is not None
            and solver.mobility.hyd is not None)


def run_krylov_span(sim: Any, t_end: float, dt: float, accepted: int, rejected: bool) -> tuple[int, int, bool, tuple]:
    """Run ``krylov_span`` from the simulator's state and write the state it returns back into the simulator, its
    solver and its counters. Returns (code, accepted steps in this dt, rejected flag, (h, err, order) of the last
    accepted step: read on ``SPAN_AFTER_ACCEPT``)."""
    nm, p, system = sim.numerics, sim.params, sim.system
    solver, mob = sim._solver, sim._solver.mobility
    hyd = solver.hyd
    contact_on = sim.contact is not None
    model, cstate = sim.contact_state(sim.q)
    static = (system.rest, system.mass, system.vdofs, system.prescribed, system.head_spins, system.pos, system.twist,
              system.free_twist, system.weights, contact_on, model, sim.step_count == 0, sim.omega)
    consts = (p.viscosity, p.cutoff_length, p.head_radius, nm.lsbt_smoothing, nm.near_field_radius * p.rod_radius,
              hyd.drag_t, hyd.drag_r if hyd.spin else 0.0, mob.sigma, *mob.zeta, mob.abw, nm.step_tol, nm.h_min,
              nm.hydro_refresh_tol * p.rod_radius, nm.hydro_refresh_max_steps, nm.newton_tol, nm.newton_max_iter,
              system.f_floor, p.rod_radius, 2 if sim._order_capped else SCHEME_ORDER[nm.integrator],
              # as values, not compile-time literals: the kernels called inside are the specialisations the Python
              # step compiled (one compile, one cache entry each)
              GMRES_RTOL, GMRES_MAX_ITER, True, 1, False)
    pts = sim._history.points
    nd = sim.q.shape[0]
    ht, hq, hv = np.zeros(HISTORY_POINTS), np.zeros((HISTORY_POINTS, nd)), np.zeros((HISTORY_POINTS, nd))
    for j, (t, q, v) in enumerate(pts):
        ht[j], hq[j], hv[j] = t, q, v
    n_nodes = sim.node_forces.shape[0]
    ft, fy = np.zeros(EXTRAPOLATION_POINTS), np.zeros((EXTRAPOLATION_POINTS, 3 * n_nodes))
    for j, (t, y) in enumerate(sim._force_points):
        ft[j], fy[j] = t, y.ravel()
    counters = np.array([getattr(sim.stats, k) for k in SPAN_COUNTERS], dtype=np.int64)
    rate = mob.contraction
    (code, (time, h_ctl, rejected, accepted, h_prev), (q, v, d1, tangent, ref_twist, body_frame, motor_angle),
     (npts, nfp, node_forces), (rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm), cstate,
     (e_last, c_last, e_commit, c_commit), (v_before, same_h, motor_torque, head_torque), last_step) = krylov_span(
        static, consts, (NO_NODES, NO_BLOCKS), mob._workspace(GMRES_MAX_ITER),
        (sim.time, t_end, dt, sim._h, rejected, accepted, sim._h_prev),
        (sim.q, sim.v, sim.d1, sim.tangent, sim.ref_twist, sim.body_frame, sim.motor_angle),
        (ht, hq, hv, len(pts)), (ft, fy, len(sim._force_points), sim.node_forces),
        (solver.x_hyd, solver.since_hydro, rate.rho, rate._age, (hyd.a, hyd.H, hyd.g),
         (mob.ab, mob.lu, mob.piv, mob.alu, mob.apiv, mob.h), solver.calm_steps,
         solver.lu_h if solver.lu is not None else -1.0, nm.jacobian_refresh == "resistance"),
        _contact_arrays(cstate), (*sim._last_contact, sim.contact_energy, sim.contact_count), counters)
    steps = counters[0] - sim.stats.substeps
    for k, value in zip(SPAN_COUNTERS, counters):
        setattr(sim.stats, k, int(value))
    sim.time, sim._h, sim._h_prev = time, h_ctl, h_prev
    if steps:
        sim._v_prev = v_before if same_h else None
        sim._history.points = [(float(ht[j]), hq[j].copy(), hv[j].copy()) for j in range(npts)]
        # the newest point holds the state's own arrays, as History.push does (q and v returned are equal to them)
        sim.q, sim.v = sim._history.points[-1][1:]
        sim.d1, sim.tangent, sim.ref_twist = d1, tangent, ref_twist
        sim.body_frame, sim.motor_angle = body_frame, motor_angle
        sim._force_points = [(float(ft[j]), fy[j].reshape(n_nodes, 3).copy()) for j in range(nfp)]
        sim.node_forces, sim.motor_torque = node_forces, float(motor_torque)
        sim.head_axial_torque = float(head_torque)
        if sim.contact is not None:
            sim.contact_energy, sim.contact_count = e_commit, int(c_commit)
    sim.keep_contact_state(cstate, e_last, int(c_last))
    if rebuilt:  # the resistance was rebuilt in the span: the operator and preconditioner it left
        a, H, g = parts
        solver.hyd = mob.hyd = ResistanceOperator.from_parts(a, H, g, hyd.drag_t, hyd.drag_r, hyd.spin,
                                                             nm.lsbt_smoothing)
        solver.x_hyd = x_hyd
        mob.H, mob.g, mob.Kh = H, (g if hyd.spin else np.zeros(a.shape[0])), np.ascontiguousarray(-H.T)
        mob.ab, mob.lu, mob.piv, mob.alu, mob.apiv, mob.h = pre
    solver.since_hydro, solver.calm_steps = since_hydro, calm
    rate.rho, rate._age = rho, age
    return code, accepted, rejected, last_step


def _contact_arrays(cstate: tuple) -> tuple:
    """The contact state with its candidate arrays C-contiguous (one compiled variant of ``krylov_span``)."""
    q, pad, pairs, head, none = cstate
    return q, float(pad), np.ascontiguousarray(pairs, dtype=np.int64), np.ascontiguousarray(head, dtype=np.int64), \
        bool(none)
