"""Twisting element, eqns (4), (5c) of Huang & Jawed 2020, DER reference-twist derivatives.

Finite differences move the nodes and then rebuild the reference frames and the reference
twist exactly as the simulator does inside Newton (``rod_frames`` on the 3-node rod:
time-parallel transport of the unperturbed reference frames).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from physics.elastic.rod_energy import rod_frames
from physics.elastic.twist import twist_energy_grad_hess
from physics.frames import reference_twist

L_VOR = 0.9
GJ = 1.5
SEEDS = range(6)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _to_q(p: np.ndarray) -> np.ndarray:
    """Local element DOFs ``[x0, x1, x2, theta_e, theta_f]`` -> 3-node rod DOFs (11,)."""
    return np.concatenate([p[0:3], [p[9]], p[3:6], [p[10]], p[6:9]])


class EdgePair:
    """A random bent edge pair with arbitrary reference frames and rest twist."""

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(100 + seed)
        te = _unit(rng.normal(size=3))
        tf = _unit(te + 0.9 * rng.normal(size=3))
        x0 = rng.normal(size=3)
        x1 = x0 + rng.uniform(0.6, 1.4) * te
        x2 = x1 + rng.uniform(0.6, 1.4) * tf
        self.p0 = np.concatenate([x0, x1, x2, rng.uniform(-np.pi, np.pi, 2)])
        self.t0 = np.stack([te, tf])
        self.d1_0 = np.stack([_unit(np.cross(t, rng.normal(size=3))) for t in (te, tf)])
        self.ref0 = reference_twist(self.d1_0, self.t0, np.zeros(1))
        self.twist_bar = rng.normal() * 0.5

    def ref_twist(self, p: np.ndarray) -> float:
        return rod_frames(_to_q(p), self.d1_0, self.t0, self.ref0)[3][0]

    def evaluate(self, p: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        return twist_energy_grad_hess(
            p[0:3], p[3:6], p[6:9], p[9], p[10], self.ref_twist(p), self.twist_bar, L_VOR, GJ
        )


def _fd_jacobian(f, p: np.ndarray, h: float) -> np.ndarray:
    cols = [(f(p + h * ei) - f(p - h * ei)) / (2 * h) for ei in np.eye(p.size)]
    return np.array(cols).T


def _kb(p: np.ndarray) -> np.ndarray:
    e, f = p[3:6] - p[0:3], p[6:9] - p[3:6]
    return 2.0 * np.cross(e, f) / (np.linalg.norm(e) * np.linalg.norm(f) + e.dot(f))


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
    kb = _kb(p)
    expected = np.concatenate([
        -kb / (2 * np.linalg.norm(e)),
        kb / (2 * np.linalg.norm(e)) - kb / (2 * np.linalg.norm(f)),
        kb / (2 * np.linalg.norm(f)),
    ])
    fd = _fd_jacobian(lambda q: np.array([pair.ref_twist(q)]), p, 1e-6)[0][:9]
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
    fd = _fd_jacobian(lambda p: np.array([pair.evaluate(p)[0]]), pair.p0, 1e-6)[0]
    g = pair.evaluate(pair.p0)[1]
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(g).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_twist_hessian_is_symmetric_part_of_gradient_finite_differences(seed: int) -> None:
    pair = EdgePair(seed)
    H = pair.evaluate(pair.p0)[2]
    J = _fd_jacobian(lambda p: pair.evaluate(p)[1], pair.p0, 1e-6)
    np.testing.assert_array_equal(H, H.T)
    assert np.abs(H - 0.5 * (J + J.T)).max() <= 1e-5 * np.abs(H).max()
    # the theta rows/columns have no transport ambiguity: there J itself must match
    assert np.abs(H[9:, :] - J[9:, :]).max() <= 1e-5 * np.abs(H).max()
    assert np.abs(H[:, 9:] - J[:, 9:]).max() <= 1e-5 * np.abs(H).max()


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_twist_hessian_matches_second_differences_of_energy(seed: int) -> None:
    pair = EdgePair(seed)
    p0 = pair.p0
    H = pair.evaluate(p0)[2]
    h = 1e-4
    E = lambda p: pair.evaluate(p)[0]  # noqa: E731
    I = np.eye(11) * h
    H2 = np.array([
        [(E(p0 + I[a] + I[b]) - E(p0 + I[a] - I[b]) - E(p0 - I[a] + I[b]) + E(p0 - I[a] - I[b]))
         / (4 * h * h) for b in range(11)]
        for a in range(11)
    ])
    assert np.abs(H - H2).max() <= 1e-5 * np.abs(H).max()


@pytest.mark.parametrize("seed", SEEDS)
def test_twist_gradient_jacobian_antisymmetric_part_is_transport_holonomy(seed: int) -> None:
    """The FD Jacobian of the gradient is H minus C, with C antisymmetric:
    ``C[a, b] = sum_edges dE/dtheta * 0.5 (dt/dp_a x dt/dp_b) . t``."""
    pair = EdgePair(seed)
    p = pair.p0
    _, g, _ = pair.evaluate(p)
    J = _fd_jacobian(lambda q: pair.evaluate(q)[1], p, 1e-6)
    x = p[:9].reshape(3, 3)
    C = np.zeros((11, 11))
    for k, gth in ((0, g[9]), (1, g[10])):
        e = x[k + 1] - x[k]
        t = e / np.linalg.norm(e)
        D = np.zeros((3, 11))
        D[:, 3 * k:3 * k + 3] = -np.eye(3)
        D[:, 3 * k + 3:3 * k + 6] = np.eye(3)
        Dt = (np.eye(3) - np.outer(t, t)) @ D / np.linalg.norm(e)
        for a in range(11):
            for b in range(11):
                C[a, b] += 0.5 * gth * np.cross(Dt[:, a], Dt[:, b]).dot(t)
    assert np.abs(0.5 * (J - J.T) + C).max() <= 1e-5 * np.abs(J).max()


def test_twist_energy_invariant_under_rigid_motion() -> None:
    pair = EdgePair(4)
    p = pair.p0
    R = Rotation.random(random_state=6).as_matrix()
    shift = np.array([-1.0, 0.2, 0.7])
    d1r, tr = pair.d1_0 @ R.T, pair.t0 @ R.T
    ref_r = reference_twist(d1r, tr, pair.ref0)
    assert ref_r[0] == pytest.approx(pair.ref0[0], abs=1e-12)
    x = [R @ p[3 * k:3 * k + 3] + shift for k in range(3)]
    E, g, _ = pair.evaluate(p)
    Er, gr, _ = twist_energy_grad_hess(*x, p[9], p[10], ref_r[0], pair.twist_bar, L_VOR, GJ)
    assert Er == pytest.approx(E, rel=1e-12)
    for k in range(3):
        np.testing.assert_allclose(gr[3 * k:3 * k + 3], R @ g[3 * k:3 * k + 3], atol=1e-12 * np.abs(g).max())
