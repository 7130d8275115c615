"""Helpers shared by the tests of the bending and twisting elements (``test_bend.py``, ``test_twist.py``):
a random bent edge pair with its frames, finite differences and the transport holonomy."""

from __future__ import annotations

import numpy as np

from physics.elastic.rod_energy import rod_frames
from physics.frames import reference_twist


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def to_q(p: np.ndarray) -> np.ndarray:
    """Local element DOFs ``[x0, x1, x2, theta_e, theta_f]`` -> 3-node rod DOFs (11,)."""
    return np.concatenate([p[0:3], [p[9]], p[3:6], [p[10]], p[6:9]])


def fd_jacobian(f, p: np.ndarray, h: float) -> np.ndarray:
    cols = [(f(p + h * ei) - f(p - h * ei)) / (2 * h) for ei in np.eye(p.size)]
    return np.array(cols).T


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
