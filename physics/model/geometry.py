"""Initial (stress-free) configuration of the swimmer, Sec. 2.2 of the paper.

Lab frame = the paper's body frame X_b-Y_b-Z_b at t = 0: +x is X_b (the head-first
swimming direction), +z is Z_b, y = z x x. The head centre x0 is the origin, edge e0 of
length b points along -X_b, e1 = -R x_b + R y_b, and the remaining nodes lie on a
left-handed helix (like a bacterial flagellum in its normal form) of radius R and pitch
lambda whose axis is the -x half-line through x1, with chords of length 2 delta.

With b = 0 (no head) the first edge e0 is a short motor shaft of length 2 delta along the
axis, an ordinary part of the flagellum (LSBT drag, no head terms): the base node x0 translates
freely and the shaft turns at omega about the helix axis (the "flagellum base turns at omega in
the lab frame" convention). N nodes either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.optimize import brentq

from physics.params import SwimmerParams


@dataclass(frozen=True)
class Layout:
    """Where things live in the DOF vector q (length 4 n - 1 for n rod nodes)."""

    n: int  # rod nodes (N, with or without a head)
    has_head: bool

    @property
    def ndof(self) -> int:
        return 4 * self.n - 1

    @property
    def first_flagellum_node(self) -> int:
        """Index (in the rod) of the first node that carries LSBT forces."""
        return 1 if self.has_head else 0

    @property
    def motor_dof(self) -> int:
        """Index in q of the twist angle of the motor edge (theta^0)."""
        return 3

    def position_dofs(self) -> np.ndarray:
        return np.array([4 * i + k for i in range(self.n) for k in range(3)], dtype=np.int64)


def helix_phase_step(params: SwimmerParams) -> float:
    """Phase increment d(phi) such that consecutive helix nodes are 2 delta apart, rad."""
    R, c, chord = params.helix_radius, params.pitch / (2.0 * math.pi), 2.0 * params.cutoff_length

    def f(p: float) -> float:
        return math.hypot(2.0 * R * math.sin(p / 2.0), c * p) - chord

    return brentq(f, 1e-12, math.pi)


PAPER_N_NODES = 122


def initial_nodes(params: SwimmerParams) -> np.ndarray:
    """Node positions of the stress-free swimmer, (n, 3) metres (head centre first if b > 0).

    The helix always spans the paper's extent: 119 chords of length 2 delta (N = 122). Another
    ``n_nodes`` only changes the discretisation: the same helix is split into n_nodes - 3 equal
    chords (longer or shorter than 2 delta).
    """
    R = params.helix_radius
    b = params.head_radius if params.has_head else 2.0 * params.cutoff_length  # head edge or motor shaft
    c = params.pitch / (2.0 * math.pi)
    n_helix = params.n_nodes - 2  # nodes x2 ... x_{N-1}
    dphi = helix_phase_step(params) * (PAPER_N_NODES - 3) / (params.n_nodes - 3)
    phi = dphi * np.arange(n_helix)
    helix = np.stack([-b - R - c * phi, R * np.cos(phi), R * np.sin(phi)], axis=1)
    x1 = np.array([[-b, 0.0, 0.0]])
    return np.vstack([np.zeros((1, 3)), x1, helix])


def layout_for(params: SwimmerParams) -> Layout:
    return Layout(n=params.n_nodes, has_head=params.has_head)


def pack_q(nodes: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Interleave positions (n,3) and edge twist angles (n-1,) into q (4n-1,)."""
    n = nodes.shape[0]
    q = np.empty(4 * n - 1)
    for k in range(3):
        q[k::4] = nodes[:, k]
    q[3::4] = theta
    return q


@njit(cache=True)
def nodes_array(q: np.ndarray) -> np.ndarray:
    """Node positions (n, 3), m, of the DOF vector q (4n-1,): a new C-contiguous array (compiled)."""
    n = (q.shape[0] + 1) // 4
    x = np.empty((n, 3))
    for i in range(n):
        for k in range(3):
            x[i, k] = q[4 * i + k]
    return x


def nodes_of(q: np.ndarray) -> np.ndarray:
    """Node positions (n, 3) from q (4n-1,) (a new array)."""
    return nodes_array(np.asarray(q, dtype=np.float64))


def thetas_of(q: np.ndarray) -> np.ndarray:
    return q[3::4]


@njit(cache=True)
def edge_stretch_extremes(q: np.ndarray, l_bar: np.ndarray) -> tuple[bool, int, float, int, float]:
    """(all of q finite, index and value of the smallest edge length / rest length, index and value of the
    largest) for the DOF vector q (4n-1,) and the rest lengths l_bar (n-1,), m."""
    for v in q:
        if not math.isfinite(v):
            return False, -1, math.nan, -1, math.nan
    i_min = i_max = 0
    r_min, r_max = math.inf, -math.inf
    for i in range(l_bar.shape[0]):
        dx = q[4 * i + 4] - q[4 * i]
        dy = q[4 * i + 5] - q[4 * i + 1]
        dz = q[4 * i + 6] - q[4 * i + 2]
        r = math.sqrt(dx * dx + dy * dy + dz * dz) / l_bar[i]
        if r < r_min:
            r_min, i_min = r, i
        if r > r_max:
            r_max, i_max = r, i
    return True, i_min, r_min, i_max, r_max
