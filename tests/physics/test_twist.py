"""Twisting element, eqns (4), (5c) of Huang & Jawed 2020, DER reference-twist derivatives.

Finite differences move the nodes and then rebuild the reference frames and the reference
twist exactly as the simulator does inside Newton (``rod_frames`` on the 3-node rod:
time-parallel transport of the unperturbed reference frames).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics.elastic.twist import twist_energy_grad_hess
from physics.model.frames import reference_twist
from tests.physics.der_helpers import (
    RandomEdgePair,
    assert_node_forces_rotate,
    curvature_binormal,
    fd_gradient,
    fd_gradient_jacobian,
    fd_jacobian,
    holonomy,
    moved_nodes,
    second_difference_hessian,
)

L_VOR = 0.9
GJ = 1.5
SEEDS = range(6)


class EdgePair(RandomEdgePair):
    """A random bent edge pair (``RandomEdgePair``) with a random rest twist."""

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(100 + seed)
        super().__init__(rng)
        self.twist_bar = rng.normal() * 0.5

    def ref_twist(self, p: np.ndarray) -> float:
        return self.rod_frames(p)[3][0]

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        return twist_energy_grad_hess(
            p[0:3], p[3:6], p[6:9], p[9], p[10], self.ref_twist(p), self.twist_bar, L_VOR, GJ
        )


def test_twist_energy_matches_eqns_4_and_5c() -> None:
    pair = EdgePair(0)
    p = pair.p0
    tau = p[10] - p[9] + pair.ref_twist(p)
    expected = 0.5 * GJ / L_VOR * (tau - pair.twist_bar) ** 2
    assert pair.evaluate(p)[0] == pytest.approx(expected, rel=1e-13)


def test_reference_twist_gradient_matches_der_formula() -> None:
    pair = EdgePair(1)
    p = pair.p0
    e, f = p[3:6] - p[0:3], p[6:9] - p[3:6]
    kb = curvature_binormal(p)
    expected = np.concatenate([
        -kb / (2 * np.linalg.norm(e)),
        kb / (2 * np.linalg.norm(e)) - kb / (2 * np.linalg.norm(f)),
        kb / (2 * np.linalg.norm(f)),
    ])
    fd = fd_jacobian(lambda q: np.array([pair.ref_twist(q)]), p, 1e-6)[0][:9]
    np.testing.assert_allclose(fd, expected, atol=1e-8)
    E, g, _ = pair.evaluate(p)
    tau = p[10] - p[9] + pair.ref_twist(p)
    stiff_d = GJ / L_VOR * (tau - pair.twist_bar)
    np.testing.assert_allclose(g[:9], stiff_d * expected, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(g[9:], [-stiff_d, stiff_d], rtol=1e-13)


def test_twist_energy_and_gradient_vanish_at_rest_twist() -> None:
    pair = EdgePair(2)
    p = pair.p0
    pair.twist_bar = p[10] - p[9] + pair.ref_twist(p)
    E, g, H = pair.evaluate(p)
    assert E == 0.0
    np.testing.assert_allclose(g, 0.0, atol=1e-15)
    assert np.linalg.eigvalsh(H).min() > -1e-12 * np.abs(H).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_twist_gradient_matches_finite_differences(seed: int) -> None:
    pair = EdgePair(seed)
    fd = fd_gradient(pair.evaluate, pair.p0)
    g = pair.evaluate(pair.p0)[1]
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(g).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_twist_hessian_is_symmetric_part_of_gradient_finite_differences(seed: int) -> None:
    pair = EdgePair(seed)
    H = pair.evaluate(pair.p0)[2]
    J = fd_gradient_jacobian(pair.evaluate, pair.p0)
    np.testing.assert_array_equal(H, H.T)
    assert np.abs(H - 0.5 * (J + J.T)).max() <= 1e-5 * np.abs(H).max()
    # the theta rows/columns have no transport ambiguity: there J itself must match
    assert np.abs(H[9:, :] - J[9:, :]).max() <= 1e-5 * np.abs(H).max()
    assert np.abs(H[:, 9:] - J[:, 9:]).max() <= 1e-5 * np.abs(H).max()


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_twist_hessian_matches_second_differences_of_energy(seed: int) -> None:
    pair = EdgePair(seed)
    H = pair.evaluate(pair.p0)[2]
    H2 = second_difference_hessian(pair.evaluate, pair.p0)
    assert np.abs(H - H2).max() <= 1e-5 * np.abs(H).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_twist_gradient_jacobian_antisymmetric_part_is_transport_holonomy(seed: int) -> None:
    """The FD Jacobian of the gradient is H minus C, with C antisymmetric:
    ``C[a, b] = sum_edges dE/dtheta * 0.5 (dt/dp_a x dt/dp_b) . t``."""
    pair = EdgePair(seed)
    p = pair.p0
    _, g, _ = pair.evaluate(p)
    J = fd_gradient_jacobian(pair.evaluate, p)
    C = holonomy(p, g)
    assert np.abs(0.5 * (J - J.T) + C).max() <= 1e-5 * np.abs(J).max()


def test_twist_energy_invariant_under_rigid_motion() -> None:
    pair = EdgePair(4)
    p = pair.p0
    R = Rotation.random(random_state=6).as_matrix()
    shift = np.array([-1.0, 0.2, 0.7])
    d1r, tr = pair.d1_0 @ R.T, pair.t0 @ R.T
    ref_r = reference_twist(d1r, tr, pair.ref0)
    assert ref_r[0] == pytest.approx(pair.ref0[0], abs=1e-12)
    x = moved_nodes(p, R, shift)
    E, g, _ = pair.evaluate(p)
    Er, gr, _ = twist_energy_grad_hess(*x, p[9], p[10], ref_r[0], pair.twist_bar, L_VOR, GJ)
    assert Er == pytest.approx(E, rel=1e-12)
    assert_node_forces_rotate(g, gr, R)
