"""The near-field kernel of the LSBT mobility (physics/hydro/lsbt.py) and the head forms as printed
(physics/hydro/higdon_head.py): positive definite wherever contact lets the rod go, unchanged where
strands stay apart."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.model.geometry import initial_nodes
from physics.hydro.higdon_head import head_flow_operators, head_operators_as_printed
from physics.hydro.hydrodynamics import resistance_matrix
from physics.hydro.lsbt import mobility_for, near_field_weight, rpy_coefficients
from physics.params import SwimmerParams

P = SwimmerParams()
MU, DELTA, R0, B = P.viscosity, P.cutoff_length, P.rod_radius, P.head_radius
A_NEAR = 1.5 * R0
SMOOTHING = 20.0


def _compressed_coil(pitch: float, radius: float, turns: float, rng) -> np.ndarray:
    """A helix whose turns nearly touch (axial pitch ~ 2 r0): every turn is near its neighbours."""
    ds = 2 * DELTA
    c = pitch / (2 * math.pi)
    dphi = ds / math.hypot(radius, c)
    phi = np.arange(0.0, 2 * math.pi * turns, dphi)
    x = np.stack([c * phi, radius * np.cos(phi), radius * np.sin(phi)], axis=1)
    return x + 0.05 * R0 * rng.standard_normal(x.shape)


def _hairpin(gap: float, bend_radius: float, arm: int, rng) -> np.ndarray:
    """Two straight arms `gap` apart joined by a U-turn (a teardrop when the U is wider)."""
    ds = 2 * DELTA
    arm1 = np.stack([-ds * np.arange(arm), np.zeros(arm), np.zeros(arm)], axis=1)
    n_arc = max(int(math.pi * bend_radius / ds), 2)
    ang = np.linspace(0, math.pi, n_arc + 1)[1:-1]
    centre = arm1[-1] + np.array([0.0, gap / 2, 0.0])
    arc = np.stack([centre[0] - bend_radius * np.sin(ang), centre[1] - (gap / 2) * np.cos(ang),
                    np.zeros_like(ang) + (bend_radius - gap / 2) * np.sin(ang)], axis=1)
    arm2 = np.stack([arm1[-1, 0] + ds * np.arange(arm), np.full(arm, gap), np.zeros(arm)], axis=1)
    x = np.vstack([arm1, arc, arm2])
    return x + 0.05 * R0 * rng.standard_normal(x.shape)


def _near_touching_configurations():
    rng = np.random.default_rng(2024)
    configs = []
    for _ in range(6):
        configs.append(_compressed_coil(rng.uniform(1.8, 2.4) * R0, rng.uniform(3, 7) * R0,
                                        rng.uniform(3, 5), rng))
        configs.append(_hairpin(rng.uniform(1.8, 2.4) * R0, rng.uniform(1.5, 4) * R0, 40, rng))
    return configs


def _min_eig(x: np.ndarray, near: float) -> float:
    return float(np.linalg.eigvalsh(mobility_for(x, MU, DELTA, SMOOTHING, near))[0])


def test_mobility_stays_positive_definite_on_near_touching_configurations():
    """Strands 1.8-2.4 r0 apart (contact keeps them >= 2 r0 up to its tolerance)."""
    configs = _near_touching_configurations()
    eigs_near = [_min_eig(x, A_NEAR) for x in configs]
    assert min(eigs_near) > 0
    # the same shapes with eqn (8)'s Stokeslet for every pair: several are indefinite (the failure
    # "LSBT mobility is not positive definite" of buckled runs)
    eigs_plain = [_min_eig(x, 0.0) for x in configs]
    assert sum(e <= 0 for e in eigs_plain) >= 3


def test_near_field_leaves_the_undeformed_swimmer_unchanged():
    x = initial_nodes(P)[1:]
    a0 = mobility_for(x, MU, DELTA, SMOOTHING, 0.0)
    a1 = mobility_for(x, MU, DELTA, SMOOTHING, A_NEAR)
    assert np.abs(a1 - a0).max() <= 1e-3 * np.abs(a0).max()


def _propulsion(x: np.ndarray, near: float) -> np.ndarray:
    """Axial force and torque for unit axial translation and rotation of the rigid helix (no head)."""
    R = resistance_matrix(x, MU, DELTA, 0.0, False, SMOOTHING, near_radius=near)
    ex = np.array([1.0, 0.0, 0.0])
    out = np.zeros((2, 2))
    for j, v in enumerate([np.tile(ex, (len(x), 1)), np.cross(ex, x)]):
        f = -(R @ v.ravel()).reshape(-1, 3)
        out[0, j] = f[:, 0].sum()
        out[1, j] = np.cross(x, f)[:, 0].sum()
    return out


def test_rigid_helix_propulsion_matrix_moves_by_less_than_one_percent():
    x = initial_nodes(P.replace(head_radius=0.0))
    p0, p1 = _propulsion(x, 0.0), _propulsion(x, A_NEAR)
    assert np.abs(p1 - p0).max() / np.abs(p0).max() < 0.01
    assert np.all(np.abs(p1 - p0) <= 0.01 * np.abs(p0))


def test_rpy_kernel_is_the_stokeslet_far_away_and_bounded_near():
    d = 50 * R0
    c_iso, c_rr = rpy_coefficients(d, A_NEAR, MU)
    assert c_iso == pytest.approx(1 / (8 * math.pi * MU * d), rel=1e-3)
    assert c_rr == pytest.approx(1 / (8 * math.pi * MU * d), rel=1e-2)
    assert rpy_coefficients(1e-9, A_NEAR, MU)[0] == pytest.approx(1 / (6 * math.pi * MU * A_NEAR), rel=1e-6)
    # continuous where the overlapping form takes over
    lo, hi = rpy_coefficients(2 * A_NEAR * (1 - 1e-9), A_NEAR, MU), rpy_coefficients(2 * A_NEAR, A_NEAR, MU)
    assert lo == pytest.approx(hi, rel=1e-6)


def test_near_field_weight_spares_neighbours_along_the_rod_and_distant_pairs():
    assert near_field_weight(1.0 * R0, 3.0 * R0, A_NEAR) == 0.0  # neighbours along the rod: eqn (8)
    assert near_field_weight(6.0 * R0, 50 * R0, A_NEAR) == 0.0  # far apart in space: eqn (8)
    assert near_field_weight(2.0 * R0, 50 * R0, A_NEAR) == 1.0  # a fold: RPY


def test_head_forms_as_printed_are_eqns_10_and_11():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(4, 3))
    x *= (rng.uniform(1.5, 5.0, size=4) * B / np.linalg.norm(x, axis=1))[:, None]
    H, K = head_operators_as_printed(x, np.zeros(3), B)
    for j, r in enumerate(x):
        d = np.linalg.norm(r)
        rr = np.outer(r, r)
        H_eq10 = 0.75 * B * ((np.eye(3) / d + rr / d**3) + B**2 / 3 * (np.eye(3) / d**3 - rr / d**5))
        f = rng.normal(size=3)
        f_eq11 = (-1.5 * B / d + 0.5 * B**3 / d**3) * f + (f @ r) / d**2 * (-0.75 * B / d + 0.75 * B**3 / d**3) * r
        np.testing.assert_allclose(H[3 * j:3 * j + 3], H_eq10, rtol=1e-12)
        np.testing.assert_allclose(K[:, 3 * j:3 * j + 3] @ f, f_eq11, rtol=1e-12)
    # the printed forms differ from the reciprocal (Faxen) ones: K != -H^T
    H_rec, _ = head_flow_operators(x, np.zeros(3), np.array([1.0, 0, 0]), B)
    assert np.abs(K + H_rec.T).max() > 0.1


def test_head_flow_is_never_evaluated_inside_the_head():
    """A node inside the sphere sees the flow of the surface point in its direction (the first
    node, x1, sits on the surface by construction and is evaluated where it is)."""
    x1 = np.array([-B, 0.0, 0.0])
    r = np.array([x1, [0.3 * B, 0.2 * B, 0.0]])
    on_surface = np.array([x1, r[1] / np.linalg.norm(r[1]) * B])
    axis = np.array([1.0, 0.0, 0.0])
    for op in (lambda y: head_flow_operators(y, np.zeros(3), axis, B)[0],
               lambda y: head_operators_as_printed(y, np.zeros(3), B)[0]):
        np.testing.assert_allclose(op(r), op(on_surface), rtol=1e-12)
        assert np.abs(op(r)[3:6]).max() < 2.0  # bounded: the surface value, not the inside one


def test_resistance_with_printed_head_forms_is_not_symmetric():
    x = initial_nodes(P)
    R = resistance_matrix(x, MU, DELTA, B, False, SMOOTHING, printed_head=True)
    R_rec = resistance_matrix(x, MU, DELTA, B, False, SMOOTHING)
    np.testing.assert_allclose(R_rec, R_rec.T, atol=1e-12 * np.abs(R_rec).max())
    assert np.abs(R - R.T).max() > 1e-3 * np.abs(R).max()
    # the flagellum rows are the same operator (only the head's flow and force forms differ)
    assert np.abs(R[3:, 3:] - R_rec[3:, 3:]).max() <= 1e-12 * np.abs(R).max()
