"""Whole-rod elastic energy, gradient and banded Hessian (eqns (5)-(7) of Huang & Jawed 2020).

The rod is a 12-node helix whose first edge is bent away from the helix, like the head edge
of the paper. Finite differences rebuild frames from the unperturbed ones with
``rod_frames`` (time-parallel transport + reference twist), as the simulator's Newton does.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_banded
from scipy.spatial.transform import Rotation

from physics.elastic import (
    BANDWIDTH,
    RodRest,
    banded_to_dense,
    bend_energy_grad_hess,
    elastic_energy,
    elastic_energy_grad_hess_banded,
    elastic_energy_kernel,
    elastic_gradient,
    elastic_hessian_banded,
    material_curvatures,
    rest_from_configuration,
    rod_frames,
    stretch_energy_grad_hess,
    twist_energy_grad_hess,
)
from physics.model.frames import material_frames, reference_twist, tangents

N_NODES = 12
SCALE = 0.01  # m, helix radius
EDGE = 0.6 * SCALE  # m, approximate edge length
EA = 2.0  # N
EI = 0.3 * EA * EDGE**2  # N m^2, bending comparable to stretching at this edge length
GJ = 0.2 * EA * EDGE**2  # N m^2


def helix_with_head_edge(n: int = N_NODES, seed: int = 0) -> np.ndarray:
    """DOF vector (4n-1,) of a helix (nodes 1..n-1) with a bent first edge and random
    twist angles."""
    rng = np.random.default_rng(seed)
    phi = np.arange(n - 1) * 0.6
    helix = np.stack([SCALE * np.cos(phi), SCALE * np.sin(phi), 0.35 * SCALE * phi], axis=1)
    head = helix[0] + 1.2 * SCALE * np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])
    x = np.vstack([head, helix])
    q = np.zeros(4 * n - 1)
    for i in range(n):
        q[4 * i:4 * i + 3] = x[i]
    q[3::4] = rng.uniform(-np.pi, np.pi, n - 1)
    return q


def _stiffness(parts: str, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    on = lambda key: 1.0 if key in parts else 0.0  # noqa: E731
    EA_arr = np.full(n - 1, EA * on("s"))
    EI_arr = np.full(n - 2, EI * on("b"))
    GJ_arr = np.full(n - 2, GJ * on("t"))
    EA_arr[0] *= 3.0  # a stiffer head edge
    EI_arr[0] *= 2.0
    return EA_arr, EI_arr, GJ_arr


class DeformedRod:
    """Rest state from the helix, then a random deformation reached by one
    time-parallel-transport update from the rest frames."""

    def __init__(self, parts: str = "sbt", seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.q_rest = helix_with_head_edge(seed=seed)
        self.rest, d1, _, ref = rest_from_configuration(self.q_rest, *_stiffness(parts, N_NODES))
        self.t_rest, self.d1_rest, self.ref_rest = tangents(self.q_rest), d1, ref
        noise = rng.normal(size=self.q_rest.shape)
        noise[0::4] *= 0.1 * EDGE
        noise[1::4] *= 0.1 * EDGE
        noise[2::4] *= 0.1 * EDGE
        noise[3::4] *= 0.4
        self.q = self.q_rest + noise
        self.t, self.d1, _, self.ref, _, _ = rod_frames(self.q, d1, self.t_rest, ref)

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(d1, d2, ref_twist, m1, m2)`` of ``q`` transported from the frames at ``self.q``."""
        return rod_frames(q, self.d1, self.t, self.ref)[1:]

    def energy(self, q: np.ndarray) -> float:
        return elastic_energy(q, *self.frames(q), self.rest)

    def gradient(self, q: np.ndarray) -> np.ndarray:
        return elastic_gradient(q, *self.frames(q), self.rest)

    def hessian(self, q: np.ndarray) -> np.ndarray:
        return banded_to_dense(elastic_hessian_banded(q, *self.frames(q), self.rest))


def _steps(q: np.ndarray) -> np.ndarray:
    """FD step per DOF: 1e-6 relative to the edge length for positions, 1e-6 rad for angles."""
    h = np.full(q.shape, 1e-6 * EDGE)
    h[3::4] = 1e-6
    return h


def _fd_jacobian(f, q: np.ndarray) -> np.ndarray:
    h = _steps(q)
    cols = []
    for k in range(q.size):
        dq = np.zeros(q.size)
        dq[k] = h[k]
        cols.append((f(q + dq) - f(q - dq)) / (2 * h[k]))
    return np.array(cols).T


PARTS = ["s", "b", "t", "sbt"]


@pytest.mark.parametrize("parts", PARTS)
def test_rod_gradient_matches_finite_differences(parts: str) -> None:
    rod = DeformedRod(parts, seed=1)
    g = rod.gradient(rod.q)
    fd = _fd_jacobian(lambda q: np.array([rod.energy(q)]), rod.q)[0]
    assert np.abs(g - fd).max() <= 1e-6 * np.abs(g).max()


@pytest.mark.parametrize("parts", PARTS)
def test_rod_banded_hessian_matches_finite_differences(parts: str) -> None:
    rod = DeformedRod(parts, seed=2)
    H = rod.hessian(rod.q)
    J = _fd_jacobian(rod.gradient, rod.q)
    scale = np.abs(H).max()
    np.testing.assert_array_equal(H, H.T)
    assert np.abs(H - 0.5 * (J + J.T)).max() <= 1e-5 * scale
    i, j = np.indices(J.shape)
    assert np.abs(J[np.abs(i - j) > BANDWIDTH]).max() <= 1e-9 * scale  # nothing outside the band


def test_rod_energy_is_sum_of_element_energies() -> None:
    rng = np.random.default_rng(3)
    rod = DeformedRod("sbt", seed=3)
    n = N_NODES
    rest = RodRest(
        l_bar=rod.rest.l_bar, l_vor=rod.rest.l_vor, kappa_bar=rod.rest.kappa_bar,
        twist_bar=rod.rest.twist_bar, EA=EA * rng.uniform(0.5, 2.0, n - 1),
        EI=EI * rng.uniform(0.5, 2.0, n - 2), GJ=GJ * rng.uniform(0.5, 2.0, n - 2),
    )
    d1, d2, ref, m1, m2 = rod.frames(rod.q)
    x = [rod.q[4 * i:4 * i + 3] for i in range(n)]
    theta = rod.q[3::4]
    expected = sum(
        stretch_energy_grad_hess(x[i], x[i + 1], rest.l_bar[i], rest.EA[i])[0] for i in range(n - 1)
    )
    for i in range(1, n - 1):
        k = i - 1
        expected += bend_energy_grad_hess(x[i - 1], x[i], x[i + 1], m1[i - 1], m2[i - 1], m1[i], m2[i],
                                          rest.kappa_bar[k], rest.l_vor[k], rest.EI[k])[0]
        expected += twist_energy_grad_hess(x[i - 1], x[i], x[i + 1], theta[i - 1], theta[i], ref[k],
                                           rest.twist_bar[k], rest.l_vor[k], rest.GJ[k])[0]
    assert elastic_energy(rod.q, d1, d2, ref, m1, m2, rest) == pytest.approx(expected, rel=1e-13)


def test_rod_energy_invariant_under_rigid_motion() -> None:
    rod = DeformedRod("sbt", seed=4)
    R = Rotation.random(random_state=7).as_matrix()
    shift = np.array([0.05, -0.3, 0.12])
    qr = rod.q.copy()
    for i in range(N_NODES):
        qr[4 * i:4 * i + 3] = R @ rod.q[4 * i:4 * i + 3] + shift
    d1, d2, ref, m1, m2 = rod.frames(rod.q)
    d1r, d2r, tr = d1 @ R.T, d2 @ R.T, tangents(qr)
    ref_r = reference_twist(d1r, tr, ref)
    m1r, m2r = material_frames(d1r, d2r, qr[3::4].copy())
    np.testing.assert_allclose(ref_r, ref, atol=1e-12)
    E = elastic_energy(rod.q, d1, d2, ref, m1, m2, rod.rest)
    Er = elastic_energy(qr, d1r, d2r, ref_r, m1r, m2r, rod.rest)
    assert Er == pytest.approx(E, rel=1e-12)
    g = elastic_gradient(rod.q, d1, d2, ref, m1, m2, rod.rest)
    gr = elastic_gradient(qr, d1r, d2r, ref_r, m1r, m2r, rod.rest)
    expected = g.copy()
    for i in range(N_NODES):
        expected[4 * i:4 * i + 3] = R @ g[4 * i:4 * i + 3]
    np.testing.assert_allclose(gr, expected, atol=1e-10 * np.abs(g).max())


def test_rest_configuration_has_zero_gradient() -> None:
    q = helix_with_head_edge(seed=5)
    rest, d1, d2, ref = rest_from_configuration(q, *_stiffness("sbt", N_NODES))
    _, d1f, d2f, reff, m1, m2 = rod_frames(q, d1, tangents(q), ref)
    np.testing.assert_allclose(d1f, d1, atol=1e-15)
    assert elastic_energy(q, d1f, d2f, reff, m1, m2, rest) <= 1e-25
    g = elastic_gradient(q, d1f, d2f, reff, m1, m2, rest)
    force_scale = max(rest.EA.max(), rest.EI.max() / EDGE**2, rest.GJ.max() / EDGE**2)  # N
    assert np.abs(np.delete(g, np.s_[3::4])).max() <= 1e-10 * force_scale
    assert np.abs(g[3::4]).max() <= 1e-10 * force_scale * EDGE


def test_rest_configuration_hessian_is_positive_semidefinite() -> None:
    q = helix_with_head_edge(seed=6)
    rest, d1, d2, ref = rest_from_configuration(q, *_stiffness("sbt", N_NODES))
    _, d1, d2, ref, m1, m2 = rod_frames(q, d1, tangents(q), ref)
    H = banded_to_dense(elastic_hessian_banded(q, d1, d2, ref, m1, m2, rest))
    # scale the DOFs so positions and angles weigh alike before looking at eigenvalues
    s = np.where(np.arange(q.size) % 4 == 3, 1.0, 1.0 / EDGE)
    Hs = H / np.outer(s, s)
    eig = np.linalg.eigvalsh(Hs)
    assert eig.min() >= -1e-10 * eig.max()
    assert np.sum(eig < 1e-9 * eig.max()) >= 3  # at least the three translations are free


def test_rest_from_configuration_records_rest_state() -> None:
    q = helix_with_head_edge(seed=7)
    rest, d1, d2, ref = rest_from_configuration(q, EA, EI, GJ)
    x = np.stack([q[4 * i:4 * i + 3] for i in range(N_NODES)])
    l_bar = np.linalg.norm(np.diff(x, axis=0), axis=1)
    np.testing.assert_allclose(rest.l_bar, l_bar, rtol=1e-15)
    np.testing.assert_allclose(rest.l_vor, 0.5 * (l_bar[1:] + l_bar[:-1]), rtol=1e-15)
    np.testing.assert_allclose(ref, 0.0, atol=1e-13)  # space-parallel frames are twist-free
    np.testing.assert_allclose(rest.twist_bar, np.diff(q[3::4]) + ref, atol=1e-15)
    m1, m2 = material_frames(d1, d2, q[3::4].copy())
    for i in range(1, N_NODES - 1):
        k = material_curvatures(x[i - 1], x[i], x[i + 1], m1[i - 1], m2[i - 1], m1[i], m2[i])
        np.testing.assert_allclose(rest.kappa_bar[i - 1], k, rtol=1e-14)
    assert rest.EA.shape == (N_NODES - 1,) and np.all(rest.EA == EA)
    assert rest.EI.shape == rest.GJ.shape == (N_NODES - 2,)
    assert rest.n_nodes == N_NODES


def test_rod_rest_rejects_inconsistent_shapes() -> None:
    rest = rest_from_configuration(helix_with_head_edge(), EA, EI, GJ)[0]
    fields = dict(l_bar=rest.l_bar, l_vor=rest.l_vor, kappa_bar=rest.kappa_bar,
                  twist_bar=rest.twist_bar, EA=rest.EA, EI=rest.EI, GJ=rest.GJ)
    RodRest(**fields)
    for name in ("l_vor", "kappa_bar", "twist_bar", "EA", "EI", "GJ"):
        bad = dict(fields)
        bad[name] = fields[name][:-1]
        with pytest.raises(ValueError, match=name):
            RodRest(**bad)


def test_banded_hessian_layout_works_with_solve_banded() -> None:
    rod = DeformedRod("sbt", seed=8)
    ab = elastic_hessian_banded(rod.q, *rod.frames(rod.q), rod.rest)
    assert ab.shape == (2 * BANDWIDTH + 1, rod.q.size)
    ab[BANDWIDTH] += 10.0 * np.abs(ab).max()  # a diagonal shift, like the mass matrix in eqn (7)
    A = banded_to_dense(ab)
    rhs = np.random.default_rng(0).normal(size=rod.q.size)
    np.testing.assert_allclose(solve_banded((BANDWIDTH, BANDWIDTH), ab, rhs), np.linalg.solve(A, rhs),
                               rtol=1e-10, atol=1e-14)


def test_energy_grad_hess_banded_matches_separate_calls() -> None:
    rod = DeformedRod("sbt", seed=9)
    frames = rod.frames(rod.q)
    E, g, ab = elastic_energy_grad_hess_banded(rod.q, *frames, rod.rest)
    assert E == elastic_energy_kernel(rod.q, *frames, *rod.rest.arrays())
    np.testing.assert_array_equal(g, elastic_gradient(rod.q, *frames, rod.rest))
    np.testing.assert_array_equal(ab, elastic_hessian_banded(rod.q, *frames, rod.rest))
