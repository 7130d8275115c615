"""Banded Newton matrices: the elastic Hessian (general-banded storage, ``physics.elastic.banded``) plus the terms
that keep the band: lumped inertia M/h^2, block-diagonal drag/h (RFT blocks, the head's own drag), contact
Hessian blocks that fall inside the band, and Dirichlet rows. Used by the banded Newton solver of the RFT model
(``step_solvers``) and by the Newton-Krylov preconditioner (``newton_krylov``)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def add_banded_drag(ab: np.ndarray, mass_over_h2: np.ndarray, blocks_over_h: np.ndarray, first: int,
                      head_t: float, head_r: float) -> None:
    bw = 10  # BANDWIDTH of physics.elastic
    for j in range(ab.shape[1]):
        ab[bw, j] += mass_over_h2[j]
    for j in range(blocks_over_h.shape[0]):
        base = 4 * (j + first)
        for p in range(3):
            for k in range(3):
                ab[bw + p - k, base + k] += blocks_over_h[j, p, k]
    if first:
        for k in range(3):
            ab[bw, k] += head_t
        ab[bw, 3] += head_r


@njit(cache=True)
def banded_dirichlet(ab: np.ndarray, k: int) -> None:
    bw = 10  # BANDWIDTH of physics.elastic
    n = ab.shape[1]
    for j in range(max(0, k - bw), min(n, k + bw + 1)):
        ab[bw + k - j, j] = 0.0  # row k
    for i in range(ab.shape[0]):
        ab[i, k] = 0.0  # column k
    ab[bw, k] = 1.0


@njit(cache=True)
def add_blocks_to_banded(ab: np.ndarray, nodes: np.ndarray, blocks: np.ndarray) -> None:
    """Add the entries of contact Hessian blocks that lie within the band (others are dropped:
    a quasi-Newton Jacobian for contact between distant parts of the rod)."""
    bw = 10  # BANDWIDTH of physics.elastic
    for a in range(nodes.shape[0]):
        for p in range(4):
            for q in range(4):
                for k in range(3):
                    for m in range(3):
                        i = 4 * nodes[a, p] + k
                        j = 4 * nodes[a, q] + m
                        if abs(i - j) <= bw:
                            ab[bw + i - j, j] += blocks[a, 3 * p + k, 3 * q + m]
