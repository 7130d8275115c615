"""Local resistive-force theory for the flagellum: the O(N) alternative to LSBT.

Each flagellum node j carries the drag of its own segment (length ell_j, tangent t_j),

    f_j = -ell_j [ zeta_perp (I - t t) + zeta_par t t ] u_j,

with no interaction between segments, so the resistance is block-diagonal and the Newton
Jacobian stays banded. Coefficients (force per length per velocity):

* Lighthill (1976), "Flagellar hydrodynamics", SIAM Rev. 18, 161, for a helix:
  zeta_perp = 4 pi mu / (ln(2q/r0) + 1/2), zeta_par = 2 pi mu / ln(2q/r0), q = 0.09 Lambda,
  Lambda the helix wavelength measured along the filament;
* Gray & Hancock (1955), J. Exp. Biol. 32, 802:
  zeta_perp = 4 pi mu / (ln(2 lambda/r0) + 1/2), zeta_par = 2 pi mu / (ln(2 lambda/r0) - 1/2),
  lambda the pitch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from physics.hydro.lsbt import node_tangent
from physics.params import SwimmerParams


def rft_coefficients(params: SwimmerParams, kind: str) -> tuple[float, float]:
    """(zeta_perp, zeta_par), N s/m^2, for ``kind`` = "lighthill" or "gray_hancock"."""
    mu, r0, lam = params.viscosity, params.rod_radius, params.pitch
    if kind == "lighthill":
        contour_wavelength = lam * math.sqrt(1.0 + (2.0 * math.pi * params.helix_radius / lam) ** 2)
        log = math.log(2.0 * 0.09 * contour_wavelength / r0)
        return 4.0 * math.pi * mu / (log + 0.5), 2.0 * math.pi * mu / log
    if kind == "gray_hancock":
        log = math.log(2.0 * lam / r0)
        return 4.0 * math.pi * mu / (log + 0.5), 2.0 * math.pi * mu / (log - 0.5)
    raise ValueError(f"rft_coefficients={kind!r}; choose 'lighthill' or 'gray_hancock'")


@njit(cache=True)
def rft_blocks(x: np.ndarray, zeta_perp: float, zeta_par: float) -> np.ndarray:
    """Per-node 3x3 resistance blocks (M,3,3), N s/m, for flagellum nodes x (M,3), m.

    ell_j is half the sum of the adjacent edge lengths; t_j the normalised mean edge tangent.
    """
    m = x.shape[0]
    out = np.empty((m, 3, 3))
    for j in range(m):
        t0, t1, t2, ell = node_tangent(x, j)
        t = (t0, t1, t2)
        for p in range(3):
            for k in range(3):
                tt = t[p] * t[k]
                out[j, p, k] = ell * (zeta_perp * ((1.0 if p == k else 0.0) - tt) + zeta_par * tt)
    return out


@njit(cache=True)
def apply_blocks(blocks: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Block-diagonal product: out[3j:3j+3] = blocks[j] @ u[3j:3j+3]."""
    out = np.empty_like(u)
    for j in range(blocks.shape[0]):
        for p in range(3):
            out[3 * j + p] = (blocks[j, p, 0] * u[3 * j] + blocks[j, p, 1] * u[3 * j + 1]
                              + blocks[j, p, 2] * u[3 * j + 2])
    return out


@njit(cache=True)
def local_drag_apply(V: np.ndarray, blocks: np.ndarray, first: int, drag_t: float, drag_r: float,
                     spin: bool) -> np.ndarray:
    """R V (nv,) of local RFT with the head's Stokes drag: minus the hydrodynamic generalised force (N on the node
    blocks, N m on the head spin) for the generalised velocities V (nv,) (m/s, rad/s; node blocks, then the head
    spin rate when ``spin``). The flagellum nodes from node ``first`` (1 with a head, 0 without) carry the blocks
    (M, 3, 3) N s/m (``rft_blocks``: f_j = -ell_j [zeta_perp (I - t t) + zeta_par t t] u_j); the head translates
    against drag_t = 6 pi mu b (N s/m) and spins against drag_r = 8 pi mu b^3 (N m s). ``force_terms.LocalResistance``
    and the compiled chord iteration (``chord_iteration``) both apply R through this kernel."""
    nv = V.shape[0]
    out = np.empty_like(V)
    f = 3 * first
    m3 = 3 * blocks.shape[0]
    out[f:f + m3] = apply_blocks(blocks, V[f:f + m3])
    if first:
        for k in range(3):
            out[k] = drag_t * V[k]
    if spin:
        out[nv - 1] = drag_r * V[nv - 1]
    return out
