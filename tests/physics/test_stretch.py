"""Stretching element, eqns (1), (5a) of Huang & Jawed 2020."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics.elastic.stretch import stretch_energy_grad_hess

L_BAR = 0.8
EA = 3.0


def _config(seed: int) -> np.ndarray:
    """(6,) = [x0, x1], an edge 0.5x to 1.5x its rest length in a random direction."""
    rng = np.random.default_rng(seed)
    x0 = rng.normal(size=3)
    d = rng.normal(size=3)
    return np.concatenate([x0, x0 + rng.uniform(0.5, 1.5) * L_BAR * d / np.linalg.norm(d)])


def _energy(p: np.ndarray) -> float:
    return stretch_energy_grad_hess(p[:3], p[3:], L_BAR, EA)[0]


def _grad(p: np.ndarray) -> np.ndarray:
    return stretch_energy_grad_hess(p[:3], p[3:], L_BAR, EA)[1]


def test_stretch_energy_matches_eqn_5a() -> None:
    p = _config(0)
    strain = np.linalg.norm(p[3:] - p[:3]) / L_BAR - 1.0
    assert _energy(p) == pytest.approx(0.5 * EA * strain**2 * L_BAR, rel=1e-14)


def test_stretch_energy_and_gradient_vanish_at_rest_length() -> None:
    E, g, H = stretch_energy_grad_hess(np.zeros(3), np.array([0.0, L_BAR, 0.0]), L_BAR, EA)
    assert E == 0.0
    np.testing.assert_allclose(g, 0.0, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(H) > -1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_stretch_gradient_matches_finite_differences(seed: int) -> None:
    p = _config(seed)
    h = 1e-6 * L_BAR
    fd = np.array([(_energy(p + h * ei) - _energy(p - h * ei)) / (2 * h) for ei in np.eye(6)])
    g = _grad(p)
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(g).max()


@pytest.mark.parametrize("seed", range(5))
def test_stretch_hessian_matches_finite_differences(seed: int) -> None:
    p = _config(seed)
    H = stretch_energy_grad_hess(p[:3], p[3:], L_BAR, EA)[2]
    h = 1e-6 * L_BAR
    fd = np.array([(_grad(p + h * ei) - _grad(p - h * ei)) / (2 * h) for ei in np.eye(6)]).T
    assert np.abs(H - fd).max() <= 1e-5 * np.abs(H).max()
    np.testing.assert_array_equal(H, H.T)


def test_stretch_energy_invariant_under_rigid_motion() -> None:
    p = _config(3)
    R = Rotation.random(random_state=4).as_matrix()
    shift = np.array([0.3, -2.0, 1.1])
    moved = np.concatenate([R @ p[:3] + shift, R @ p[3:] + shift])
    assert _energy(moved) == pytest.approx(_energy(p), rel=1e-12)
