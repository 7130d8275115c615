"""Helpers shared by the tests of the bending and twisting elements (``test_bend.py``, ``test_twist.py``):
a random bent edge pair with its frames, its curvature binormal, finite differences of an element's
energy and gradient, a rigid motion of its nodes and the transport holonomy.

An element's ``evaluate(p)`` returns ``(E, g (11,), H (11, 11))`` for local DOFs ``p`` (11,)."""

from __future__ import annotations

import numpy as np

from physics.elastic.rod_energy import rod_frames
from physics.model.frames import reference_twist


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def to_q(p: np.ndarray) -> np.ndarray:
    """Local element DOFs ``[x0, x1, x2, theta_e, theta_f]`` -> 3-node rod DOFs (11,)."""
    return np.concatenate([p[0:3], [p[9]], p[3:6], [p[10]], p[6:9]])


def fd_jacobian(f, p: np.ndarray, h: float) -> np.ndarray:
    cols = [(f(p + h * ei) - f(p - h * ei)) / (2 * h) for ei in np.eye(p.size)]
    return np.array(cols).T


def fd_gradient(evaluate, p: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences (11,) of the energy ``evaluate(p)[0]``."""
    return fd_jacobian(lambda x: np.array([evaluate(x)[0]]), p, h)[0]


def fd_gradient_jacobian(evaluate, p: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences (11, 11) of the gradient ``evaluate(p)[1]``."""
    return fd_jacobian(lambda x: evaluate(x)[1], p, h)


def second_difference_hessian(evaluate, p0: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """Hessian (11, 11) of the energy ``evaluate(p)[0]`` from second differences of the energy alone."""
    E = lambda p: evaluate(p)[0]  # noqa: E731
    I = np.eye(11) * h
    return np.array([
        [(E(p0 + I[a] + I[b]) - E(p0 + I[a] - I[b]) - E(p0 - I[a] + I[b]) + E(p0 - I[a] - I[b]))
         / (4 * h * h) for b in range(11)]
        for a in range(11)
    ])


def curvature_binormal(p: np.ndarray) -> np.ndarray:
    """``kb = 2 e x f / (|e||f| + e.f)`` (eqn (2)) of the edge pair of local DOFs ``p`` (11,)."""
    e, f = p[3:6] - p[0:3], p[6:9] - p[3:6]
    return 2.0 * np.cross(e, f) / (np.linalg.norm(e) * np.linalg.norm(f) + e.dot(f))


def moved_nodes(p: np.ndarray, R: np.ndarray, shift: np.ndarray) -> list[np.ndarray]:
    """The three nodes of ``p`` (11,) under the rigid motion ``x -> R x + shift``."""
    return [R @ p[3 * k:3 * k + 3] + shift for k in range(3)]


def assert_node_forces_rotate(g: np.ndarray, g_moved: np.ndarray, R: np.ndarray) -> None:
    """The node blocks of a gradient (11,) turn with the body: ``g_moved = R g`` node by node."""
    for k in range(3):
        np.testing.assert_allclose(g_moved[3 * k:3 * k + 3], R @ g[3 * k:3 * k + 3], atol=1e-12 * np.abs(g).max())


class RandomEdgePair:
    """A random bent edge pair drawn from ``rng``: DOFs ``p0`` (11,), tangents ``t0``, reference directors
    ``d1_0`` (arbitrary, normal to the tangents) and their reference twist ``ref0``. Frames of nearby
    configurations follow by time-parallel transport from these (``rod_frames``), as in the simulator's Newton
    loop. A subclass draws its rest state from the same ``rng`` afterwards."""

    def __init__(self, rng: np.random.Generator) -> None:
        te = unit(rng.normal(size=3))
        tf = unit(te + 0.9 * rng.normal(size=3))
        x0 = rng.normal(size=3)
        x1 = x0 + rng.uniform(0.6, 1.4) * te
        x2 = x1 + rng.uniform(0.6, 1.4) * tf
        self.p0 = np.concatenate([x0, x1, x2, rng.uniform(-np.pi, np.pi, 2)])
        self.t0 = np.stack([te, tf])
        self.d1_0 = np.stack([unit(np.cross(t, rng.normal(size=3))) for t in (te, tf)])
        self.ref0 = reference_twist(self.d1_0, self.t0, np.zeros(1))

    def rod_frames(self, p: np.ndarray):
        """``rod_frames`` of configuration ``p`` (11,): ``(t, d1, d2, ref_twist, m1, m2)``."""
        return rod_frames(to_q(p), self.d1_0, self.t0, self.ref0)


_LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _LEVI_CIVITA[_i, _j, _k] = 1.0
    _LEVI_CIVITA[_i, _k, _j] = -1.0


def holonomy(p: np.ndarray, g: np.ndarray) -> np.ndarray:
    """``C[a, b] = sum_edges dE/dtheta * 0.5 (dt/dp_a x dt/dp_b) . t`` (11, 11): the part of
    the gradient's Jacobian that comes from parallel transport not commuting."""
    x = p[:9].reshape(3, 3)
    C = np.zeros((11, 11))
    for k, gth in ((0, g[9]), (1, g[10])):
        e = x[k + 1] - x[k]
        le = np.linalg.norm(e)
        t = e / le
        D = np.zeros((3, 11))
        D[:, 3 * k:3 * k + 3] = -np.eye(3)
        D[:, 3 * k + 3:3 * k + 6] = np.eye(3)
        Dt = (np.eye(3) - np.outer(t, t)) @ D / le
        C += 0.5 * gth * np.einsum("ia,jb,k,ijk->ab", Dt, Dt, t, _LEVI_CIVITA)
    return C
