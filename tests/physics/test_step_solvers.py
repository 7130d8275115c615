"""When the dense chord solver refactorises its kept LU (physics/solvers/step_solvers.py): once the residuals its chord
iterations took beyond two per step add up to ``LU_REFRESH_BUDGET`` (the cost of a refactorisation), e.g. after a
Newton-Krylov step replaced the resistance the LU was built from, and not before."""

from __future__ import annotations

import pytest

import physics.solvers.step_solvers as step_solvers
from physics import Simulator, advance, configure
from physics.params import RPM_TO_RAD_S


def _after_a_krylov_step(n_steps: int) -> tuple[list[tuple[int, int]], list[int]]:
    """A settled 10 rpm swimmer (N = 40) whose resistance is rebuilt by a Newton-Krylov step, then ``n_steps``
    control steps: (residuals, factorisations) per step and the solver's extra-residual count at each
    refactorisation."""
    # the torque-free head: its steps at N = 40 keep h in the LU's reuse band, so every refactorisation here is
    # the budget's (the mechanism does not depend on the head's reading)
    p, n = configure("faithful", {"n_nodes": 40, "head_rotation": "torque_free"})
    sim = Simulator(p, n)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, 6.0)
    solver = sim.solver
    solver.since_hydro = n.hydro_refresh_max_steps  # the next step rebuilds the resistance by Newton-Krylov
    k0 = sim.stats.krylov_steps
    sim.step()
    assert sim.stats.krylov_steps == k0 + 1 and solver.lu is not None
    solver.extra_iterations = 0  # count only what the stale LU costs from here
    at_refresh: list[int] = []
    refresh = solver._refresh_jacobian

    def spy(*args, **kwargs):
        at_refresh.append(solver.extra_iterations)
        return refresh(*args, **kwargs)

    solver._refresh_jacobian = spy
    rows = []
    for _ in range(n_steps):
        it0, f0 = sim.stats.newton_iterations, sim.stats.jacobian_factorisations
        sim.step()
        rows.append((sim.stats.newton_iterations - it0, sim.stats.jacobian_factorisations - f0))
    return rows, at_refresh


def test_a_stale_lu_is_refactorised_once_its_extra_residuals_reach_the_budget():
    rows, at_refresh = _after_a_krylov_step(40)
    assert at_refresh and all(x >= step_solvers.LU_REFRESH_BUDGET for x in at_refresh)
    first = next(i for i, (_, f) in enumerate(rows) if f)
    before = sum(r for r, _ in rows[max(first - 10, 0):first])
    after = sum(r for r, _ in rows[first + 1:first + 11])
    assert after < before  # the new LU contracts faster


def test_without_the_budget_the_stale_lu_is_kept(monkeypatch):
    monkeypatch.setattr(step_solvers, "LU_REFRESH_BUDGET", 10**9)
    rows, at_refresh = _after_a_krylov_step(40)
    assert not at_refresh and not any(f for _, f in rows)


@pytest.mark.parametrize("budget", [5, 60])
def test_the_budget_sets_when(monkeypatch, budget):
    monkeypatch.setattr(step_solvers, "LU_REFRESH_BUDGET", budget)
    _, at_refresh = _after_a_krylov_step(40)
    assert at_refresh and all(budget <= x < budget + 4 for x in at_refresh)  # at most one step's extras late
