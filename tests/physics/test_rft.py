"""Local resistive-force theory and the banded Newton solver."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams
from physics.hydro.rft import apply_blocks, rft_blocks, rft_coefficients
from physics.simulator import Simulator

P = SwimmerParams()


def test_lighthill_coefficients_for_the_paper_helix():
    zp, zt = rft_coefficients(P, "lighthill")
    lam_c = P.pitch * math.sqrt(1 + (2 * math.pi * P.helix_radius / P.pitch) ** 2)
    log = math.log(0.18 * lam_c / P.rod_radius)
    assert zp == pytest.approx(4 * math.pi * P.viscosity / (log + 0.5))
    assert zt == pytest.approx(2 * math.pi * P.viscosity / log)
    assert 1.5 < zp / zt < 2.0


def test_unknown_coefficient_set_is_rejected():
    with pytest.raises(ValueError, match="rft_coefficients"):
        rft_coefficients(P, "stokes")


def test_straight_rod_drag_is_zeta_times_length():
    n, ds = 50, 2e-3
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * ds
    zp, zt = 3.0, 2.0
    B = rft_blocks(x, zp, zt)
    length = (n - 1) * ds
    f_par = apply_blocks(B, np.tile([1.0, 0, 0], n)).reshape(-1, 3).sum(0)
    f_perp = apply_blocks(B, np.tile([0, 1.0, 0], n)).reshape(-1, 3).sum(0)
    assert f_par[0] == pytest.approx(zt * length)
    assert f_perp[1] == pytest.approx(zp * length)
    assert abs(f_par[1]) < 1e-12 and abs(f_perp[0]) < 1e-12


def test_rft_swimmer_swims_head_first_with_few_newton_iterations():
    sim = Simulator(SwimmerParams(n_nodes=40), NumericsConfig(dt=0.02, hydro_model="rft"))
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    sim.advance(3.0)
    assert sim.head_position[0] > 0.001
    assert 1.0 < sim.end_to_end_ratio() < 1.05
    assert sim.stats.newton_iterations / sim.stats.steps < 6  # exact banded Newton


def test_coarse_lsbt_keeps_the_helix_and_the_swim_speed():
    # same helix with 40 instead of 122 nodes (segments ~3x longer than 2 delta): the steady swim
    # speed over one motor turn (after one turn of start-up) agrees within 2 %
    def per_turn(n):
        sim = Simulator(SwimmerParams(n_nodes=n), NumericsConfig(dt=0.02))
        sim.set_motor_speed(10 * RPM_TO_RAD_S)
        sim.advance(6.0)
        x0 = sim.head_position
        sim.advance(6.0)
        return sim, np.linalg.norm(sim.head_position - x0)
    (fine, v_fine), (coarse, v_coarse) = per_turn(122), per_turn(40)
    assert np.linalg.norm(coarse._initial_nodes[-1] - fine._initial_nodes[-1]) < 1e-12
    assert v_coarse == pytest.approx(v_fine, rel=0.02)
