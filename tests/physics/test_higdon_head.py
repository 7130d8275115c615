"""Head hydrodynamics (eqns 10-13) and the assembled generalised resistance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics.model.geometry import initial_nodes
from physics.hydro.higdon_head import head_flow_operators, head_spin_map
from physics.hydro.hydrodynamics import resistance_matrix
from physics.params import SwimmerParams

P = SwimmerParams()
MU, DELTA, B = P.viscosity, P.cutoff_length, P.head_radius


def test_head_flow_is_no_slip_on_the_sphere_surface():
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(5, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    axis = np.array([0.0, 0.0, 1.0])
    H, g = head_flow_operators(B * dirs, np.zeros(3), axis, B)
    for j in range(5):
        np.testing.assert_allclose(H[3 * j:3 * j + 3], np.eye(3), atol=1e-12)
        np.testing.assert_allclose(g[3 * j:3 * j + 3], np.cross(axis, B * dirs[j]), atol=1e-15)


def test_head_flow_decays_like_a_stokeslet_far_away():
    x = np.array([[100 * B, 0.0, 0.0]])
    H, g = head_flow_operators(x, np.zeros(3), np.array([1.0, 0, 0]), B)
    assert H[0, 0] == pytest.approx(1.5 * B / (100 * B), rel=1e-3)
    assert H[1, 1] == pytest.approx(0.75 * B / (100 * B), rel=1e-3)


def _far_flagellum(distance: float) -> np.ndarray:
    x = initial_nodes(P)
    x[1:] += np.array([-distance, 0.0, 0.0])
    return x


def test_sphere_alone_feels_stokes_drag_and_torque():
    x = _far_flagellum(1000 * B)  # flagellum far away: the head is effectively alone
    R = resistance_matrix(x, MU, DELTA, B, True, 20.0)
    n = len(x)
    V = np.zeros(3 * n + 1)
    V[0:3] = [1e-3, -2e-3, 5e-4]
    G = -R @ V
    np.testing.assert_allclose(G[0:3], -6 * math.pi * MU * B * V[0:3], rtol=2e-3)
    V = np.zeros(3 * n + 1)
    V[-1] = 0.7
    G = -R @ V
    assert G[-1] == pytest.approx(-8 * math.pi * MU * B**3 * 0.7, rel=1e-3)


def test_generalised_resistance_is_symmetric_positive_definite():
    R = resistance_matrix(initial_nodes(P), MU, DELTA, B, True, 20.0)
    np.testing.assert_allclose(R, R.T, rtol=1e-10, atol=1e-12 * np.abs(R).max())
    assert np.linalg.eigvalsh(R)[0] > 0


def test_resistance_rotates_covariantly_with_the_configuration():
    x = initial_nodes(P)
    Q = Rotation.from_rotvec([0.3, -0.2, 0.9]).as_matrix()
    R0 = resistance_matrix(x, MU, DELTA, B, True, 20.0)
    R1 = resistance_matrix(x @ Q.T + 0.01, MU, DELTA, B, True, 20.0)
    n = len(x)
    Qt = np.eye(3 * n + 1)
    for i in range(n):
        Qt[3 * i:3 * i + 3, 3 * i:3 * i + 3] = Q
    np.testing.assert_allclose(R1, Qt @ R0 @ Qt.T, atol=1e-9 * np.abs(R0).max())


def test_literal_head_spin_balances_the_torques_of_eqn_13():
    """The literal reading (theta^0 = omega t in the lab, the head spinning at the rate of eqn 13, its rotlet acting on
    the flagellum): for random velocities of a bent swimmer, the forces of its resistance are those of the resistance
    with the head spin as a generalised velocity (``head_spins``) at the rate ``head_spin_map`` gives, and at that rate
    the axial torques of eqn (13) balance: -8 pi mu b^3 s + a . t_h + a . sum r_j x f_j = 0, t_h as eqn (11) prints
    it (-sum b^3 r_j x f_j / r_j^3)."""
    rng = np.random.default_rng(3)
    x = initial_nodes(P)
    x[2:] += 0.3 * P.rod_radius * rng.normal(size=(len(x) - 2, 3))  # bent, x1 stays on the head's surface
    n = len(x)
    V = rng.normal(size=3 * n) * 1e-3
    R_lit = resistance_matrix(x, MU, DELTA, B, False, 20.0, spin_from_balance=True)
    G = -R_lit @ V
    f = G[3:].reshape(-1, 3)  # hydrodynamic forces on the flagellum nodes, N
    r = x[1:] - x[0]
    a = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
    s = head_spin_map(np.ascontiguousarray(x[1:]), x[0].copy(), a, B, MU) @ (-G[3:])
    assert abs(s) > 1e-3 * np.abs(V).max() / B  # the head does spin
    rn = np.linalg.norm(r, axis=1)
    t_h = -np.sum((B**3 / rn**3)[:, None] * np.cross(r, f), axis=0)
    balance = -8 * math.pi * MU * B**3 * s + a @ t_h + a @ np.cross(r, f).sum(axis=0)
    scale = 8 * math.pi * MU * B**3 * abs(s)
    assert abs(balance) <= 1e-10 * scale
    # the same forces from the spin-augmented resistance at that spin rate, whose axial torque closes eqn (13)
    R_spin = resistance_matrix(x, MU, DELTA, B, True, 20.0)
    G_spin = -R_spin @ np.concatenate([V, [s]])
    np.testing.assert_allclose(G_spin[:-1], G, rtol=0, atol=1e-10 * np.abs(G).max())
    assert abs(G_spin[-1] + a @ np.cross(r, f).sum(axis=0)) <= 1e-10 * scale


def test_literal_head_needs_the_higdon_coupling():
    from physics.presets import configure

    for bad in ({"head_model": "stokes"}, {"hydro_model": "rft"}):
        with pytest.raises(ValueError, match=f"head_rotation='literal' with {next(iter(bad))}="):
            configure("faithful", {"head_rotation": "literal", **bad})
