"""Bending element, eqns (2), (3a), (3b), (5b) of Huang & Jawed 2020, DER derivatives.

Finite differences move the nodes and then rebuild the material frames exactly as the
simulator does inside Newton: time-parallel transport of the unperturbed reference frames
(``rod_frames`` on the 3-node rod), material frames from the (perturbed) twist angles.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics.elastic.bend import bend_energy_grad_hess, material_curvatures
from physics.model.frames import tangents
from tests.physics.der_helpers import (
    RandomEdgePair,
    assert_node_forces_rotate,
    curvature_binormal,
    fd_gradient,
    fd_gradient_jacobian,
    holonomy,
    moved_nodes,
    second_difference_hessian,
    to_q,
)

L_VOR = 1.1
EI = 2.0
SEEDS = range(6)


class EdgePair(RandomEdgePair):
    """A random bent edge pair (``RandomEdgePair``) with a random rest curvature."""

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(seed)
        super().__init__(rng)
        self.kappa_bar = rng.normal(size=2) * 0.4

    def frames(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(m1, m2, ref_twist)`` of configuration ``p`` (11,)."""
        _, _, _, ref, m1, m2 = self.rod_frames(p)
        return m1, m2, ref

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        m1, m2, _ = self.frames(p)
        return bend_energy_grad_hess(
            p[0:3], p[3:6], p[6:9], m1[0], m2[0], m1[1], m2[1], self.kappa_bar, L_VOR, EI
        )


def test_material_curvatures_match_eqns_2_and_3() -> None:
    pair = EdgePair(0)
    p = pair.p0
    m1, m2, _ = pair.frames(p)
    kb = curvature_binormal(p)
    expected = [0.5 * (m2[0] + m2[1]).dot(kb), -0.5 * (m1[0] + m1[1]).dot(kb)]
    got = material_curvatures(p[0:3], p[3:6], p[6:9], m1[0], m2[0], m1[1], m2[1])
    np.testing.assert_allclose(got, expected, rtol=1e-13)


def test_bend_energy_matches_eqn_5b() -> None:
    pair = EdgePair(1)
    p = pair.p0
    m1, m2, _ = pair.frames(p)
    k = material_curvatures(p[0:3], p[3:6], p[6:9], m1[0], m2[0], m1[1], m2[1])
    expected = 0.5 * EI / L_VOR * np.sum((k - pair.kappa_bar) ** 2)
    assert pair.evaluate(p)[0] == pytest.approx(expected, rel=1e-13)


def test_bend_energy_and_gradient_vanish_at_rest_curvature() -> None:
    pair = EdgePair(2)
    p = pair.p0
    m1, m2, _ = pair.frames(p)
    pair.kappa_bar = material_curvatures(p[0:3], p[3:6], p[6:9], m1[0], m2[0], m1[1], m2[1])
    E, g, H = pair.evaluate(p)
    assert E == pytest.approx(0.0, abs=1e-28)
    np.testing.assert_allclose(g, 0.0, atol=1e-13)
    assert np.linalg.eigvalsh(H).min() > -1e-12 * np.abs(H).max()


def test_bend_theta_gradient_matches_der_formulas() -> None:
    pair = EdgePair(3)
    p = pair.p0
    m1, m2, _ = pair.frames(p)
    kb = curvature_binormal(p)
    k = material_curvatures(p[0:3], p[3:6], p[6:9], m1[0], m2[0], m1[1], m2[1]) - pair.kappa_bar
    g = pair.evaluate(p)[1]
    for j in (0, 1):
        dk1 = -0.5 * kb.dot(m1[j])
        dk2 = -0.5 * kb.dot(m2[j])
        assert g[9 + j] == pytest.approx(EI / L_VOR * (k[0] * dk1 + k[1] * dk2), rel=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_bend_gradient_matches_finite_differences(seed: int) -> None:
    pair = EdgePair(seed)
    fd = fd_gradient(pair.evaluate, pair.p0)
    g = pair.evaluate(pair.p0)[1]
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(g).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_bend_hessian_is_symmetric_part_of_gradient_finite_differences(seed: int) -> None:
    pair = EdgePair(seed)
    H = pair.evaluate(pair.p0)[2]
    J = fd_gradient_jacobian(pair.evaluate, pair.p0)
    np.testing.assert_array_equal(H, H.T)
    assert np.abs(H - 0.5 * (J + J.T)).max() <= 1e-5 * np.abs(H).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_bend_gradient_jacobian_antisymmetric_part_is_transportholonomy(seed: int) -> None:
    """Why the Hessian is the symmetric part: the rest of the FD Jacobian of the gradient
    is -C, the non-commutativity of parallel transport weighted by dE/dtheta."""
    pair = EdgePair(seed)
    _, g, _ = pair.evaluate(pair.p0)
    J = fd_gradient_jacobian(pair.evaluate, pair.p0)
    C = holonomy(pair.p0, g)
    scale = np.abs(J).max()
    assert np.abs(0.5 * (J - J.T) + C).max() <= 1e-5 * scale


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_bend_hessian_matches_second_differences_of_energy(seed: int) -> None:
    pair = EdgePair(seed)
    H = pair.evaluate(pair.p0)[2]
    H2 = second_difference_hessian(pair.evaluate, pair.p0)
    assert np.abs(H - H2).max() <= 1e-5 * np.abs(H).max()


def test_bend_energy_invariant_under_rigid_motion() -> None:
    pair = EdgePair(4)
    p = pair.p0
    m1, m2, _ = pair.frames(p)
    R = Rotation.random(random_state=5).as_matrix()
    shift = np.array([1.0, -0.4, 2.5])
    x = moved_nodes(p, R, shift)
    m1r, m2r = m1 @ R.T, m2 @ R.T
    E, g, _ = pair.evaluate(p)
    Er, gr, _ = bend_energy_grad_hess(*x, m1r[0], m2r[0], m1r[1], m2r[1], pair.kappa_bar, L_VOR, EI)
    assert Er == pytest.approx(E, rel=1e-12)
    assert_node_forces_rotate(g, gr, R)  # forces rotate with the body, moments about the tangents do not
    np.testing.assert_allclose(gr[9:], g[9:], atol=1e-12 * np.abs(g).max())


def test_edge_pair_helper_uses_time_parallel_frames() -> None:
    """Sanity check of the test fixture: perturbed frames stay adapted to the new edges."""
    pair = EdgePair(5)
    p = pair.p0 + 1e-2 * np.random.default_rng(0).normal(size=11)
    m1, m2, _ = pair.frames(p)
    t = tangents(to_q(p))
    np.testing.assert_allclose(np.einsum("ij,ij->i", m1, t), 0.0, atol=1e-13)
    np.testing.assert_allclose(np.cross(m1, m2), t, atol=1e-13)
