"""Consecutive Newton-Krylov steps in one compiled call: while the flagellum buckles, Python enters once per span.

While the swimmer's shape changes (a burst, the relaxation after it) every step rebuilds the LSBT resistance and is
solved by Newton-Krylov (``newton_krylov``); ``Simulator._adaptive`` then spends ~15 % of a step in Python around
the compiled kernels (the step's base, the contact broad phase, the resistance and preconditioner set-up, the error
estimate, the controller, the commit). ``krylov_span`` runs those steps in one compiled call. Its step is the Python
step's (``Simulator._adaptive``, ``_step_start``, ``DenseChordSolver.begin_step``, ``MobilityStep.begin`` /
``solve``, ``_commit``) made of the same compiled parts: the base (``time_integrator.base_kernel``), the start, error
estimate, controller and commit (``integrate.adaptive_step``), the broad phase
(``implicit_residual.contact_candidates``), the choice of a Newton-Krylov step (``step_solvers.krylov_begins``) and
the iteration (``newton_krylov.newton_krylov_loop``); only the loop around them is written twice (Python and
compiled), so the trajectory is bit-identical (tests/physics/test_krylov_span.py).

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
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from physics.model.body_frame import transported_body_frame
from physics.linalg.compiled_lapack import NUMPY_BLAS, numpy_dot
from physics.forces.contact import ContactParams, ContactState, contact_kernel
from physics.model.geometry import edge_stretch_extremes, nodes_array
from physics.hydro.higdon_head import head_flow_operators
from physics.hydro.hydrodynamics import ResistanceOperator
from physics.solvers.implicit_residual import contact_candidates
from physics.hydro.lsbt import lsbt_mobility, node_tangents
from physics.solvers.newton_krylov import (CONVERGED, GMRES_MAX_ITER, GMRES_RTOL, KrylovRate, KrylovTols,
                                           MobilityHydro, Preconditioner, newton_krylov_loop,
                                           preconditioner_factors)
from physics.model.rigid_alignment import best_fit_rotation
from physics.forces.step_context import NO_BLOCKS, NO_NODES, StepSystem
from physics.solvers.step_solvers import krylov_begins
from physics.integrate.adaptive_step import accepted_step, commit_point, local_error, rejected_step, step_start
from physics.integrate.time_integrator import (COLLAPSED_STEPS, MAX_STEPS_PER_SPAN, SCHEME_ORDER, base_kernel,
                                              extrapolate_kernel, order_after, split_remaining)

#: how ``krylov_span`` returned (module doc)
SPAN_DONE, SPAN_CHORD, SPAN_FAILED, SPAN_AFTER_ACCEPT = range(4)
#: the counters a span advances, in this order (``StepStats`` fields)
SPAN_COUNTERS = ("substeps", "newton_iterations", "krylov_iterations", "krylov_steps", "resistance_refreshes",
                 "preconditioner_factorisations", "rejected_steps")


class SpanStatic(NamedTuple):
    """What a span does not change: the system (``step_context.SystemDescription``) and the motor."""

    rest: tuple  # (l_bar, l_vor, kappa_bar, twist_bar, EA, EI, GJ): the rest arrays of eqns (5a)-(5c)
    mass: np.ndarray  # (ndof,) lumped masses, kg / kg m^2
    vdofs: np.ndarray  # (nv,) the DOFs of the generalised velocities
    prescribed: np.ndarray  # Dirichlet DOFs (the motor's twist when the head does not spin)
    head_spins: bool  # the head's spin rate is the last generalised velocity
    pos: np.ndarray  # position DOFs
    twist: np.ndarray  # twist DOFs
    free_twist: np.ndarray  # twist DOFs that are not prescribed
    weights: np.ndarray  # (ndof,) 1/r0 on positions, 1 on twists
    contact_on: bool  # contact is modelled
    model: ContactParams  # ``contact.ContactModel.model`` (or ``NO_CONTACT_MODEL``)
    first_step: bool  # the run's first step (the broad phase pads by nothing then)
    omega: float  # motor speed, rad/s


class SpanConsts(NamedTuple):
    """The constants of a span's steps: the LSBT resistance (``lsbt``, ``higdon_head``), the preconditioner
    (``MobilityStep``), the controller and the iteration's tolerances (``NumericsConfig``)."""

    mu: float  # viscosity, Pa s
    delta: float  # LSBT cutoff length, m
    head_radius: float  # b, m
    smoothing: float  # ``NumericsConfig.lsbt_smoothing``
    near_radius: float  # LSBT near-field radius, m
    drag_t: float  # head translational drag, N s/m
    drag_r: float  # head rotational drag, N m s (0 unless the head spins)
    sigma: float  # scale of the mobility rows, Pa s m (``MobilityStep.sigma``)
    zeta_perp: float  # local resistance coefficients of the preconditioner, N s/m^2
    zeta_par: float
    abw: int  # half bandwidth of the preconditioner's mobility band
    step_tol: float  # ``NumericsConfig.step_tol`` (r0 or rad)
    h_min: float  # smallest step, s
    refresh_dev: float  # non-rigid shape change that rebuilds the resistance, m
    refresh_steps: int  # steps after which the resistance is rebuilt anyway
    newton_tol: float
    newton_max_iter: int
    f_floor: float  # N: force scale below which the convergence test counts a block as zero
    r0: float  # rod radius, m
    top_order: int  # the scheme's largest order (2 while capped)
    gmres_rtol: float
    gmres_max_iter: int
    has_head: bool
    first: int  # 1 with a head (the flagellum's first node), else 0
    keep_h: bool  # ``next_step``'s band in which h is kept (False for Newton-Krylov steps)


class ContactPlaceholders(NamedTuple):
    """No active contacts: node quadruples (0, 4) and Hessian blocks (0, 12, 12) (``step_context``)."""

    nodes: np.ndarray
    blocks: np.ndarray


class SpanClock(NamedTuple):
    """The controller's clock: time and the span's end t_end (s), the span dt (s), the next step h (s), the last
    attempt rejected, steps accepted in this dt, the last accepted step h_prev (s, -1: none)."""

    time: float
    t_end: float
    dt: float
    h: float
    rejected: bool
    accepted: int
    h_prev: float


class RodState(NamedTuple):
    """The rod's state (``Simulator``): q, v (ndof,) m / rad and per s, the frames d1, tangent (n-1, 3),
    ref_twist (n-2,) rad, the head's body frame (3, 3) and the motor angle (rad)."""

    q: np.ndarray
    v: np.ndarray
    d1: np.ndarray
    tangent: np.ndarray
    ref_twist: np.ndarray
    body_frame: np.ndarray
    motor_angle: float


class SpanHistory(NamedTuple):
    """The accepted points (``AdaptiveState``'s arrays, advanced in place), oldest first: t (HISTORY_POINTS,) s, q
    and v (HISTORY_POINTS, ndof); the first ``count`` rows are used."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    count: int


class ForcePoints(NamedTuple):
    """The flagellum's node forces at the last accepted points (``AdaptiveState``'s force arrays, advanced in
    place): t (EXTRAPOLATION_POINTS,) s, y (EXTRAPOLATION_POINTS, 3n) N, the first ``count`` rows used; and the
    last step's node forces (n, 3) N."""

    t: np.ndarray
    y: np.ndarray
    count: int
    node_forces: np.ndarray


class SpanSolver(NamedTuple):
    """The solvers' state a span starts from: the geometry of the resistance x_hyd (M+1, 3) m and the steps since
    it was built; the Newton-Krylov contraction rate (rho, age); the resistance's parts (a, H, g)
    (``_mobility_parts``) and the preconditioner (ab, lu, piv, alu, apiv, h_e); the calm attempts; the kept chord
    LU's h_e (s, -1: none) and whether a rebuilt resistance makes it stale (``DenseChordSolver.begin_step``)."""

    x_hyd: np.ndarray
    since_hydro: int
    rho: float
    age: int
    parts: tuple
    pre: tuple
    calm: int
    lu_h: float
    lu_after_rebuild: bool


class SpanSolverOut(NamedTuple):
    """The solvers' state a span leaves (``SpanSolver``'s fields; ``rebuilt``: the resistance was rebuilt in the
    span, its parts and preconditioner are new)."""

    rebuilt: bool
    x_hyd: np.ndarray
    since_hydro: int
    rho: float
    age: int
    parts: tuple
    pre: tuple
    calm: int


class LastContact(NamedTuple):
    """Contact energy (J) and active interactions of the last evaluation and of the last accepted step."""

    e_last: float
    count_last: int
    e_commit: float
    count_commit: int


class SpanPoints(NamedTuple):
    """How many rows of ``SpanHistory`` and ``ForcePoints`` a span leaves, and the node forces (n, 3) N of its
    last accepted step."""

    history_count: int
    force_count: int
    node_forces: np.ndarray


class SpanCommit(NamedTuple):
    """What the last accepted step leaves besides the state: the velocity before it (ndof,), whether it had the
    length of the one before it (``AdaptiveState.v_prev``), the motor torque and the head's axial torque (N m), the
    head's spin rate (rad/s; 0 for a head held still)."""

    v_before: np.ndarray
    same_h: bool
    motor_torque: float
    head_torque: float
    head_spin_rate: float


class LastStep(NamedTuple):
    """The last accepted step of a span: its length h (s), error ratio and order."""

    h: float
    err: float
    order: int


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
def krylov_span(static: SpanStatic, consts: SpanConsts, placeholders: ContactPlaceholders, work: tuple,
                clock: SpanClock, state: RodState, history: SpanHistory, forces: ForcePoints, solver: SpanSolver,
                cstate: ContactState, last_contact: LastContact, counters: np.ndarray):
    """Error-controlled Newton-Krylov steps from the simulator's state until t_end or a return to Python (module
    doc). ``counters`` (len(SPAN_COUNTERS),) int64 is advanced in place (restored on ``SPAN_FAILED`` and
    ``SPAN_CHORD`` to its value before the returning attempt); ``work``: GMRES's arrays
    (``newton_krylov.krylov_workspace``); the other arguments: the named tuples above and in ``contact``.
    Returns (code, ``SpanClock``, ``RodState``, ``SpanPoints``, ``SpanSolverOut``, ``ContactState``,
    ``LastContact``, ``SpanCommit``, ``LastStep``)."""
    rest, prescribed, contact_on, model, omega = (static.rest, static.prescribed, static.contact_on, static.model,
                                                  static.omega)
    time, t_end, dt, h_ctl, rejected, accepted, h_prev = (clock.time, clock.t_end, clock.dt, clock.h, clock.rejected,
                                                          clock.accepted, clock.h_prev)
    q_cur, v_cur, d1, tangent, ref_twist, body_frame, motor_angle = (state.q, state.v, state.d1, state.tangent,
                                                                     state.ref_twist, state.body_frame,
                                                                     state.motor_angle)
    ht, hq, hv, npts = history.t, history.q, history.v, history.count
    ft, fy, nfp, node_forces = forces.t, forces.y, forces.count, forces.node_forces
    x_hyd, since_hydro, rho, age, parts, pre, calm = (solver.x_hyd, solver.since_hydro, solver.rho, solver.age,
                                                      solver.parts, solver.pre, solver.calm)
    e_last, count_last, e_commit, count_commit = (last_contact.e_last, last_contact.count_last,
                                                  last_contact.e_commit, last_contact.count_commit)
    v_before = v_cur
    same_h = False  # the last accepted step had the length of the one before it (AdaptiveState.v_prev)
    motor_torque = 0.0
    head_torque = 0.0
    spin_rate = 0.0
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
        # the step's base (Simulator._base_for; AdaptiveState.base)
        order = order_after(consts.top_order, npts)
        m = min(npts, order + 1)
        q_hat, v_hat, h_eff, q_pred, ratio = base_kernel(ht[npts - m:npts].copy(), hq[npts - m:npts],
                                                         hv[npts - m:npts], h, order)
        # its start and contact broad phase (Simulator._step_start)
        q = step_start(q_pred, q_cur, prescribed, h, omega)
        x_pred = nodes_array(q)
        if contact_on:
            cstate = contact_candidates(q, model, q_cur, static.pos, static.first_step)
        else:
            cstate = ContactState(q, 0.0, cstate.pairs, cstate.head_edges, True)
        # the resistance: rebuilt by a Newton-Krylov step (DenseChordSolver.begin_step), else the chord step
        dev = best_fit_rotation(x_hyd, x_pred)[1]
        krylov, calm = krylov_begins(since_hydro, consts.refresh_steps, dev, consts.refresh_dev, calm, solver.lu_h,
                                     h_eff, solver.lu_after_rebuild)
        if not krylov:
            code = SPAN_CHORD
            break
        parts = _mobility_parts(x_pred, consts.mu, consts.delta, consts.head_radius, consts.smoothing,
                                consts.near_radius)
        x_hyd = x_pred
        since_hydro = 0
        rebuilt = True
        counters[4] += 1
        a, H, g = parts
        if not static.head_spins:  # MobilityStep.begin: no spin flow without a spinning head
            g = np.zeros(a.shape[0])
        Kh = np.ascontiguousarray(-H.T)
        # the preconditioner (MobilityStep.begin)
        nodes_c, blocks_c = placeholders.nodes, placeholders.blocks
        if contact_on and not cstate.none:
            nodes_c, blocks_c = contact_kernel(x_pred, cstate.pairs, model.head_radius, cstate.head_edges, model.r0,
                                               model.eps, model.stiffness)[2:]
        ab, (lu, piv, info), (alu, apiv, ainfo) = preconditioner_factors(
            q, (d1, tangent, ref_twist), rest, static.mass, h_eff, consts.zeta_perp, consts.zeta_par, consts.first,
            consts.drag_t, consts.drag_r, nodes_c, blocks_c, prescribed, a, consts.abw)
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
                               StepSystem(static.mass, static.vdofs, prescribed, static.head_spins, omega,
                                          static.pos, static.twist, static.free_twist, static.weights),
                               MobilityHydro(a, H, g, Kh, consts.drag_t, consts.drag_r, consts.has_head,
                                             static.head_spins, consts.sigma), contact_on, model, cstate,
                               static.first_step, Preconditioner(lu, piv, alu, apiv, consts.abw), ab,
                               KrylovTols(consts.newton_tol, consts.newton_max_iter, consts.step_tol, consts.f_floor,
                                          consts.r0, consts.gmres_rtol, consts.gmres_max_iter),
                               KrylovRate(rho, age), work))
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
        err = local_error(q, q_pred, ratio, static.weights, consts.step_tol)
        if err > 1.0:  # Simulator._reject
            h_new = rejected_step(h, err, order)
            counters[6] += 1
            if h_new < consts.h_min:
                code = SPAN_FAILED
                break
            h_ctl = h_new
            continue
        rejected = False
        # Simulator._commit
        dpsi = q[3] - q_cur[3] - h * omega
        v_before = v_cur
        same_h = h == h_prev
        h_prev = h
        time = t_end if last else time + h
        node_forces = nodes_array(f)
        v_cur, npts, nfp = commit_point(q, q_cur, q_hat, h, h_eff, order, time, True, ht, hq, hv, npts,
                                        node_forces.ravel(), ft, fy, nfp)
        q_cur = q
        t, d1, d2, ref_twist, m1, m2 = frames
        tangent = t
        counters[0] += 1
        motor_angle += h * omega
        since_hydro += 1
        head_torque = f[3] if static.head_spins else 0.0
        spin_rate = dpsi / h if static.head_spins else 0.0
        motor_torque = grad[3]
        body_frame = transported_body_frame(body_frame, q[0:3], q[4:7], dpsi, static.head_spins)
        e_commit, count_commit = e_last, count_last
        accepted += 1
        if (accepted == COLLAPSED_STEPS and order > 2) or accepted >= MAX_STEPS_PER_SPAN:
            code = SPAN_AFTER_ACCEPT
            break
        # Simulator._after_accept (a Newton-Krylov step: no band in which h is kept)
        h_ctl = accepted_step(h, err, order, h_ctl, dt, consts.keep_h)
    if code == SPAN_CHORD or code == SPAN_FAILED:  # the returning attempt is Python's to take
        rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm, cstate, e_last, count_last, kept, rejected = saved
        counters[:] = kept
    return (code, SpanClock(time, t_end, dt, h_ctl, rejected, accepted, h_prev),
            RodState(q_cur, v_cur, d1, tangent, ref_twist, body_frame, motor_angle),
            SpanPoints(npts, nfp, node_forces), SpanSolverOut(rebuilt, x_hyd, since_hydro, rho, age, parts, pre, calm),
            cstate, LastContact(e_last, count_last, e_commit, count_commit),
            SpanCommit(v_before, same_h, motor_torque, head_torque, spin_rate), LastStep(h, err, order))


def krylov_span_applies(sim: Any) -> bool:
    """Does ``krylov_span`` take the simulator's next attempt? (module doc: the configurations it covers, and the
    previous attempt solved by Newton-Krylov with no restart pending)."""
    nm, p = sim.numerics, sim.params
    solver = sim.solver
    return (sim.compiled_span and NUMPY_BLAS and nm.step_tol > 0.0 and nm.newton_krylov and not nm.single_iteration
            and nm.hydro_model == "lsbt" and nm.head_model == "higdon" and p.has_head
            and p.head_rotation in ("torque_free", "fixed")
            and not sim.adaptive.restart and getattr(solver, "krylov", False) and solver.hyd is not None
            and solver.mobility.hyd is not None)


def run_krylov_span(sim: Any, t_end: float, dt: float, accepted: int,
                    rejected: bool) -> tuple[int, int, bool, LastStep]:
    """Run ``krylov_span`` from the simulator's state and write the state it returns back into the simulator, its
    solver and its counters. Returns (code, accepted steps in this dt, rejected flag, the last accepted step: read
    on ``SPAN_AFTER_ACCEPT``)."""
    nm, p, system = sim.numerics, sim.params, sim.system
    solver, mob, st = sim.solver, sim.solver.mobility, sim.adaptive
    hyd = solver.hyd
    contact_on = sim.contact is not None
    model, cstate = sim.contact_state(sim.q)
    static = SpanStatic(rest=system.rest, mass=system.mass, vdofs=system.vdofs, prescribed=system.prescribed,
                        head_spins=system.head_spins, pos=system.pos, twist=system.twist,
                        free_twist=system.free_twist, weights=system.weights, contact_on=contact_on, model=model,
                        first_step=sim.step_count == 0, omega=sim.omega)
    zeta_perp, zeta_par = mob.zeta
    consts = SpanConsts(
        mu=p.viscosity, delta=p.cutoff_length, head_radius=p.head_radius, smoothing=nm.lsbt_smoothing,
        near_radius=nm.near_field_radius * p.rod_radius, drag_t=hyd.drag_t, drag_r=hyd.drag_r if hyd.spin else 0.0,
        sigma=mob.sigma, zeta_perp=zeta_perp, zeta_par=zeta_par, abw=mob.abw, step_tol=nm.step_tol, h_min=nm.h_min,
        refresh_dev=nm.hydro_refresh_tol * p.rod_radius, refresh_steps=nm.hydro_refresh_max_steps,
        newton_tol=nm.newton_tol, newton_max_iter=nm.newton_max_iter, f_floor=system.f_floor, r0=p.rod_radius,
        top_order=2 if st.order_capped else SCHEME_ORDER[nm.integrator],
        # as values, not compile-time literals: the kernels called inside are the specialisations the Python
        # step compiled (one compile, one cache entry each)
        gmres_rtol=GMRES_RTOL, gmres_max_iter=GMRES_MAX_ITER, has_head=True, first=1, keep_h=False)
    counters = np.array([getattr(sim.stats, k) for k in SPAN_COUNTERS], dtype=np.int64)
    rate = mob.contraction
    code, clock, state, points, out, cstate, contact, commit, last_step = krylov_span(
        static, consts, ContactPlaceholders(NO_NODES, NO_BLOCKS), mob.workspace(GMRES_MAX_ITER),
        SpanClock(time=sim.time, t_end=t_end, dt=dt, h=st.h, rejected=rejected, accepted=accepted,
                  h_prev=st.h_prev),
        RodState(q=sim.q, v=sim.v, d1=sim.d1, tangent=sim.tangent, ref_twist=sim.ref_twist,
                 body_frame=sim.body_frame, motor_angle=sim.motor_angle),
        SpanHistory(t=st.times, q=st.qs, v=st.vs, count=st.count),
        ForcePoints(t=st.force_times, y=st.force_values, count=st.force_count, node_forces=sim.node_forces),
        SpanSolver(x_hyd=solver.x_hyd, since_hydro=solver.since_hydro, rho=rate.rho, age=rate.age,
                   parts=(hyd.a, hyd.H, hyd.g), pre=(mob.ab, mob.lu, mob.piv, mob.alu, mob.apiv, mob.h),
                   calm=solver.calm_steps, lu_h=solver.lu_h if solver.lu is not None else -1.0,
                   lu_after_rebuild=nm.jacobian_refresh == "resistance"),
        _contact_arrays(cstate),
        LastContact(e_last=sim.last_contact[0], count_last=sim.last_contact[1], e_commit=sim.contact_energy,
                    count_commit=sim.contact_count),
        counters)
    steps = counters[0] - sim.stats.substeps
    for k, value in zip(SPAN_COUNTERS, counters):
        setattr(sim.stats, k, int(value))
    sim.time, st.h, st.h_prev = clock.time, clock.h, clock.h_prev
    if steps:
        st.v_prev = commit.v_before if commit.same_h else None
        st.count, st.force_count = points.history_count, points.force_count
        sim.q, sim.v = state.q, state.v
        sim.d1, sim.tangent, sim.ref_twist = state.d1, state.tangent, state.ref_twist
        sim.body_frame, sim.motor_angle = state.body_frame, state.motor_angle
        sim.node_forces, sim.motor_torque = points.node_forces, float(commit.motor_torque)
        sim.head_axial_torque, sim.head_spin_rate = float(commit.head_torque), float(commit.head_spin_rate)
        if sim.contact is not None:
            sim.contact_energy, sim.contact_count = contact.e_commit, int(contact.count_commit)
    sim.keep_contact_state(cstate, contact.e_last, int(contact.count_last))
    if out.rebuilt:  # the resistance was rebuilt in the span: the operator and preconditioner it left
        a, H, g = out.parts
        solver.hyd = mob.hyd = ResistanceOperator.from_parts(a, H, g, hyd.drag_t, hyd.drag_r, hyd.spin,
                                                             nm.lsbt_smoothing)
        solver.x_hyd = out.x_hyd
        mob.H, mob.g, mob.Kh = H, (g if hyd.spin else np.zeros(a.shape[0])), np.ascontiguousarray(-H.T)
        mob.ab, mob.lu, mob.piv, mob.alu, mob.apiv, mob.h = out.pre
    solver.since_hydro, solver.calm_steps = out.since_hydro, out.calm
    rate.rho, rate.age = out.rho, out.age
    return code, clock.accepted, clock.rejected, last_step


def _contact_arrays(cstate: ContactState) -> ContactState:
    """The contact state with its candidate arrays C-contiguous (one compiled variant of ``krylov_span``)."""
    return ContactState(cstate.q, float(cstate.pad), np.ascontiguousarray(cstate.pairs, dtype=np.int64),
                        np.ascontiguousarray(cstate.head_edges, dtype=np.int64), bool(cstate.none))
