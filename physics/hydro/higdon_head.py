"""Hydrodynamics of the rigid spherical head, Sec. 2.4 of Huang & Jawed 2020 (Higdon 1979).

We use the mutually reciprocal Stokes forms:

* flow at flagellum node j from a head translating at U (eqn 10, translational part):
  u = [ (3b/4)(I/r + r r / r^3) + (b^3/4)(I/r^3 - 3 r r / r^5) ] U  =: H_j U
  (the exact Stokes flow of a translating sphere; it equals U on the sphere surface);
* flow from a head spinning at rate s about its axis a (eqn 10, rotational part):
  u = b^3 (a x r) / r^3 s  =: g_j s   (the rotlet; rigid rotation on the surface);
* force and torque the flagellum Stokeslets exert on the head (eqn 11), by Faxen's laws:
  f_h = -sum_j H_j^T f_j,    a . t_h = -sum_j g_j . f_j  (= a . sum_j -b^3 r_j x f_j / r_j^3).

Differences from the equations as printed in the paper, and why: eqn (10) prints the
b^3 term as (b^2/3)(I/r^3 - r r/r^5) inside the 3b/4 bracket, which does not reduce to U on
the sphere (the Stokes solution has 3 r r / r^5); it prints the rotlet as r x Omega, whose
surface value opposes the head's rotation; eqn (11)'s isotropic force coefficient
(-3b/2r + b^3/2r^3) is not the adjoint of eqn (10). The printed torque in eqn (11) agrees with
ours. Our forms make the head-flagellum resistance symmetric and dissipative (reciprocal
theorem); the printed ones do not. The method of images is not used, as in the paper.

The paper's own reading (``head_rotation="paper"``: head not spinning, flagellum base turning
at omega in the lab frame, eqns (10)-(11) as printed) is ``head_operators_as_printed``.

The literal lab-driven reading (``head_rotation="literal"``: theta^0 = omega t in the lab frame, the head
spinning at the rate s that eqn (13) gives, its rotlet acting on the flagellum through eqn (10)) needs s as a
function of the flagellum forces: ``head_spin_map``.

r_j = x_j - x_0 (node relative to the head centre), b the head radius.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _surface_offset(x: np.ndarray, x_head: np.ndarray, b: float, j: int) -> tuple[tuple[float, float, float], float]:
    """(r_s, d): node j's offset r_j = x_j - x_0 (m), moved out onto the sphere of radius b if it was inside (not
    for j = 0: x1 is attached to the surface and never moved), and its length d, m. Scalars only."""
    r0, r1, r2 = x[j, 0] - x_head[0], x[j, 1] - x_head[1], x[j, 2] - x_head[2]
    rn = math.sqrt(r0 ** 2 + r1 ** 2 + r2 ** 2)
    d = rn if j == 0 else max(rn, b)
    f = d / rn
    return (r0 * f, r1 * f, r2 * f), d


@njit(cache=True)
def head_flow_operators(x: np.ndarray, x_head: np.ndarray, axis: np.ndarray,
                        b: float) -> tuple[np.ndarray, np.ndarray]:
    """Head-induced flow operators at the flagellum nodes (reciprocal forms).

    x: (M,3) node positions, m; x_head: (3,) head centre, m; axis: (3,) unit spin axis;
    b: head radius, m. Returns H (3M,3), dimensionless, and g (3M,), m/s per rad/s.
    A node closer to the centre than b (possible only with contact switched off) is evaluated
    on the surface along its direction: the flow is never evaluated inside the head. The first
    node x[0] (x1, the end of e0 on the head's surface) is evaluated where it is.
    """
    m = x.shape[0]
    H = np.zeros((3 * m, 3))
    g = np.zeros(3 * m)
    b3 = b * b * b
    for j in range(m):
        rs, d = _surface_offset(x, x_head, b, j)
        d3 = d * d * d
        iso = 0.75 * b / d + 0.25 * b3 / d3
        rad = 0.75 * b / d - 0.75 * b3 / d3
        for p in range(3):
            for k in range(3):
                H[3 * j + p, k] = (iso if p == k else 0.0) + rad * rs[p] * rs[k] / (d * d)
        g[3 * j + 0] = b3 * (axis[1] * rs[2] - axis[2] * rs[1]) / d3
        g[3 * j + 1] = b3 * (axis[2] * rs[0] - axis[0] * rs[2]) / d3
        g[3 * j + 2] = b3 * (axis[0] * rs[1] - axis[1] * rs[0]) / d3
    return H, g


@njit(cache=True)
def head_operators_as_printed(x: np.ndarray, x_head: np.ndarray, b: float) -> tuple[np.ndarray, np.ndarray]:
    """The head's translational flow and force operators exactly as eqns (10)-(11) print them.

    Flow at node j from a head translating at U (eqn 10, head not spinning):
        u_j = (3b/4) [ (I/r + r r/r^3) + (b^2/3)(I/r^3 - r r/r^5) ] U  =: H_j U,
    force of the flagellum nodes' forces f_i on the head (eqn 11):
        f_h = sum_i [ (-3b/(2r) + b^3/(2r^3)) I + (-3b/(4r) + 3b^3/(4r^3)) r r / r^2 ] f_i =: K F.
    K is not -H^T (the printed forms are not reciprocal), so the resistance built with them is
    not symmetric. Used by the paper's reading (``head_rotation="paper"``); nodes inside the head
    are evaluated on its surface as in ``head_flow_operators``.
    x: (M,3) m; x_head: (3,) m; b: m. Returns H (3M,3) and K (3,3M), dimensionless.
    """
    m = x.shape[0]
    H = np.zeros((3 * m, 3))
    K = np.zeros((3, 3 * m))
    b3 = b * b * b
    for j in range(m):
        rs, d = _surface_offset(x, x_head, b, j)
        d3 = d * d * d
        h_iso = 0.75 * b / d + 0.25 * b3 / d3
        h_rad = 0.75 * b / d - 0.25 * b3 / d3
        k_iso = -1.5 * b / d + 0.5 * b3 / d3
        k_rad = -0.75 * b / d + 0.75 * b3 / d3
        for p in range(3):
            for q in range(3):
                rr = rs[p] * rs[q] / (d * d)
                H[3 * j + p, q] = (h_iso if p == q else 0.0) + h_rad * rr
                K[p, 3 * j + q] = (k_iso if p == q else 0.0) + k_rad * rr
    return H, K


@njit(cache=True)
def head_spin_map(x: np.ndarray, x_head: np.ndarray, axis: np.ndarray, b: float, mu: float) -> np.ndarray:
    """Eqn (13) solved for the head's spin rate s about its axis a: s = w . y, w (3M,) in rad/s per N.

    y (3M,) N are the forces the flagellum nodes put on the fluid (minus the hydrodynamic forces f_j on them).
    The axial part of eqn (13), -8 pi mu b^3 s + a . t_h + a . sum_j r_j x f_j = 0, with the Stokeslets' torque
    on the head a . t_h = -g . f (``head_flow_operators``; eqn (11)'s printed torque) and a . (r_j x f_j) =
    (a x r_j) . f_j, gives 8 pi mu b^3 s = sum_j (g_j - a x r_j) . y_j. r_j = x_j - x_0 is the node's offset
    (not moved onto the surface; g_j is evaluated as in ``head_flow_operators``).
    x: (M,3) flagellum nodes, m; x_head: (3,) m; axis: (3,) unit; b: head radius, m; mu: Pa s.
    """
    _, g = head_flow_operators(x, x_head, axis, b)
    m = x.shape[0]
    w = np.empty(3 * m)
    drag_r = 8.0 * math.pi * mu * b * b * b
    for j in range(m):
        r0, r1, r2 = x[j, 0] - x_head[0], x[j, 1] - x_head[1], x[j, 2] - x_head[2]
        w[3 * j + 0] = (g[3 * j + 0] - (axis[1] * r2 - axis[2] * r1)) / drag_r
        w[3 * j + 1] = (g[3 * j + 1] - (axis[2] * r0 - axis[0] * r2)) / drag_r
        w[3 * j + 2] = (g[3 * j + 2] - (axis[0] * r1 - axis[1] * r0)) / drag_r
    return w


def sphere_translational_drag(mu: float, b: float) -> float:
    """Stokes drag coefficient 6 pi mu b, N s/m (eqn 12)."""
    return 6.0 * math.pi * mu * b


def sphere_rotational_drag(mu: float, b: float) -> float:
    """Rotational drag coefficient 8 pi mu b^3, N m s (eqn 13)."""
    return 8.0 * math.pi * mu * b**3
