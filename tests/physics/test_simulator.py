"""Whole-swimmer behaviour of the simulator (Sec. 2.5 of Huang & Jawed 2020)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.errors import SimulationError
from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams
from physics.simulator import Simulator

W10 = 10 * RPM_TO_RAD_S


def _swim(omega_rpm: float, duration: float, dt: float = 5e-3, **params) -> Simulator:
    sim = Simulator(SwimmerParams(**params), NumericsConfig(dt=dt))
    sim.set_motor_speed(omega_rpm * RPM_TO_RAD_S)
    sim.advance(duration)
    return sim


@pytest.fixture(scope="module")
def steady10() -> Simulator:
    """Paper swimmer (b = 1.2 cm) with a torque-free head (eqn 13) after 15 s at 10 rpm; head positions kept at t = 3 s
    and 15 s."""
    sim = _swim(10.0, 3.0, head_rotation="torque_free")
    sim.x_at_3s = sim.head_position
    sim.advance(12.0)
    return sim


def test_swims_head_first_along_x_at_positive_motor_speed(steady10):
    x = steady10.head_position
    assert x[0] > 0.005  # ~0.28 cm per motor turn, 2.5 turns in 15 s
    assert steady10.head_velocity[0] > 0


def test_ten_rpm_swims_straight_with_slightly_stretched_helix(steady10):
    # over two whole motor turns (t = 3 s ... 15 s) the head's wobble cancels: the net motion
    # must point along the initial axis
    d = steady10.head_position - steady10.x_at_3s
    assert math.degrees(math.acos(d[0] / np.linalg.norm(d))) < 3.0
    ratio = steady10.end_to_end_ratio()
    assert 1.0 < ratio < 1.05
    assert abs(steady10.head_orientation[0, 0]) > 0.99  # body axis still along x


def test_swimmer_is_force_and_torque_free_in_steady_swimming(steady10):
    f = steady10.node_forces  # hydrodynamic force on each node, N
    total = f.sum(axis=0)
    assert np.linalg.norm(total) < 1e-3 * np.abs(f).sum()
    r = steady10.nodes - steady10.head_position
    torque = np.cross(r, f).sum(axis=0)
    axis = steady10.nodes[1] - steady10.nodes[0]
    torque += steady10.head_axial_torque * axis / np.linalg.norm(axis)
    scale = (np.linalg.norm(r, axis=1) * np.linalg.norm(f, axis=1)).sum()
    assert np.linalg.norm(torque) < 1e-3 * scale


def test_torque_free_head_counter_rotates_and_balances_the_motor_torque(steady10):
    sim = steady10
    assert sim.motor_torque > 0
    # the head's hydrodynamic axial torque balances the torque the motor passes to it
    assert sim.head_axial_torque == pytest.approx(sim.motor_torque, rel=1e-2)
    spin = sim.v[3] - sim.omega  # head spin rate about t0 (= -X_b), rad/s
    assert -sim.omega < spin < 0


def test_swim_speed_converges_with_time_step():
    d = [_swim(10.0, 2.0, dt=h).head_position[0] for h in (20e-3, 10e-3, 5e-3)]
    e1, e2 = abs(d[0] - d[1]), abs(d[1] - d[2])
    assert e2 < e1  # errors shrink as h shrinks (implicit Euler: first order)
    assert e2 < 2e-3 * abs(d[2])


def test_no_head_swims_with_base_turning_at_omega():
    sim = _swim(10.0, 3.0, head_radius=0.0)
    assert sim.layout.n == 122
    assert sim.head_position[0] > 0
    assert sim.motor_angle == pytest.approx(3.0 * W10)
    assert sim.q[3] == pytest.approx(3.0 * W10)


def test_fixed_head_does_not_spin():
    sim = _swim(10.0, 1.0, head_rotation="fixed")
    assert sim.q[3] == pytest.approx(sim.motor_angle)
    assert sim.head_axial_torque == 0.0


def test_failing_newton_raises_simulation_error_and_keeps_the_last_good_state():
    sim = Simulator(SwimmerParams(), NumericsConfig(dt=5e-3, newton_max_iter=2, newton_tol=1e-12, max_substeps=0))
    sim.set_motor_speed(60 * RPM_TO_RAD_S)
    q_before = sim.q.copy()
    with pytest.raises(SimulationError) as err:
        for _ in range(5):
            q_before = sim.q.copy()
            sim.step()
    assert "Newton" in str(err.value) and "step" in str(err.value)
    assert err.value.quantity == "Newton"
    np.testing.assert_array_equal(sim.q, q_before)
    assert np.all(np.isfinite(sim.q))


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_motor_speed_is_rejected(bad):
    sim = Simulator(SwimmerParams(n_nodes=20))
    with pytest.raises(ValueError, match="motor speed"):
        sim.set_motor_speed(bad)


def test_sixty_rpm_for_100_s_buckles_the_flagellum_when_the_head_does_not_spin():
    # Paper Sec. 2.5: above omega_b the helix buckles (L'/L drops well below its ~1.005 at 10 rpm).
    # Under eqn (13) (torque-free head, our default) this model's omega_b for b = 1.2 cm lies
    # above 60 rpm (see docs/validation.md), so the buckling at 60 rpm is checked in the
    # documented "fixed head" reading, on a coarse grid (N = 60, h = 5 ms) to keep it short.
    sim = Simulator(SwimmerParams(head_rotation="fixed", n_nodes=60),
                    NumericsConfig(dt=5e-3, hydro_refresh_tol=0.1))
    sim.set_motor_speed(60 * RPM_TO_RAD_S)
    sim.advance(100.0)
    assert sim.end_to_end_ratio() < 0.9
    axis = sim.head_orientation[:, 0]
    assert axis[0] < 0.9  # the body axis has turned away from x


def test_single_iteration_mode_swims_like_newton_and_refreshes_its_resistance():
    """The linearly implicit option (one Newton iteration per step, LSBT) must rebuild the resistance
    on the same rules as full Newton (here: at least every 5 steps) and stay close to it at 10 rpm."""
    def run(**numerics) -> Simulator:
        sim = Simulator(SwimmerParams(n_nodes=30), NumericsConfig(dt=0.02, **numerics))
        sim.set_motor_speed(W10)
        sim.advance(2.0)
        return sim

    newton = run(hydro_refresh_max_steps=5)
    single = run(hydro_refresh_max_steps=5, single_iteration=True)
    assert single.stats.resistance_refreshes >= 100 // 5
    assert single.stats.newton_iterations == 100
    d_newton, d_single = newton.head_position[0], single.head_position[0]
    assert abs(d_single - d_newton) < 0.05 * abs(d_newton)


def test_end_to_end_ratio_is_the_norm_quotient_bit_for_bit():
    """The shortcut (the end nodes read from q, the undeformed span kept) returns what the definition gives."""
    from physics import advance, configure

    sim = Simulator(*configure("faithful", {"n_nodes": 25}))
    sim.set_motor_speed(150 * RPM_TO_RAD_S)
    x0 = sim.nodes
    for _ in range(3):
        advance(sim, steps=5)
        x = sim.nodes
        assert sim.end_to_end_ratio() == float(np.linalg.norm(x[-1] - x[0]) / np.linalg.norm(x0[-1] - x0[0]))


def test_literal_head_counter_rotates_at_the_rate_of_eqn_13_while_the_flagellum_turns_at_omega():
    """head_rotation=literal: the motor twist is omega t in the lab frame, and the head spins against the flagellum at
    the rate eqn (13) gives (between 0 and omega: the flagellum's torque is shared by the head's rotational drag)."""
    sim = _swim(10.0, 3.0, head_rotation="literal", n_nodes=60)
    assert sim.q[3] == pytest.approx(sim.omega * sim.time, rel=1e-12)
    assert -sim.omega < sim.head_spin_rate < -0.05 * sim.omega
    fixed = _swim(10.0, 3.0, head_rotation="fixed", n_nodes=60)
    assert fixed.head_spin_rate == 0.0
