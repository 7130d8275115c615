"""The head's body frame (X_b, Y_b, Z_b) carried along with the swimmer, compiled.

X_b is the head axis -t^0 (from the first flagellum node to the head centre). Each step the frame is parallel
transported from the old axis to the new one (the minimal rotation), then, for a spinning head, rotated about
the new axis by the head's spin increment dpsi (Sec. 2.5 of Huang & Jawed 2020: theta^0 = psi + omega t), and
re-orthonormalised. Same arithmetic as the NumPy form it replaced (Rodrigues' rotation; norms as sqrt of the
dot product)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def rotate_about(u: np.ndarray, k: np.ndarray, ang: float) -> np.ndarray:
    """Rodrigues rotation of u (3,) about the unit vector k (3,) by ang radians."""
    c, s = math.cos(ang), math.sin(ang)
    return u * c + _cross(k, u) * s + k * _dot(k, u) * (1 - c)


@njit(cache=True)
def transport(u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Parallel transport of u (3,) from the unit vector a to the unit vector b (minimal rotation)."""
    c = _cross(a, b)
    s = math.sqrt(_dot(c, c))
    if s < 1e-14:
        return u.copy()
    return rotate_about(u, c / s, math.atan2(s, _dot(a, b)))


@njit(cache=True)
def transported_body_frame(frame: np.ndarray, head: np.ndarray, first_node: np.ndarray, dpsi: float,
                           spins: bool) -> np.ndarray:
    """The body frame (3, 3) (columns X_b, Y_b, Z_b) after a step: ``frame`` before it, the head centre and the
    first flagellum node after it (3,) m, the head's spin increment dpsi rad (used if ``spins``)."""
    old_axis = frame[:, 0].copy()
    new_axis = head - first_node
    new_axis = new_axis / math.sqrt(_dot(new_axis, new_axis))
    y = transport(frame[:, 1].copy(), old_axis, new_axis)
    if spins:  # spin by dpsi about t0 = -X_b
        y = rotate_about(y, new_axis, -dpsi)
    y = y - _dot(y, new_axis) * new_axis
    y = y / math.sqrt(_dot(y, y))
    z = _cross(new_axis, y)
    out = np.empty((3, 3))
    for k in range(3):
        out[k, 0] = new_axis[k]
        out[k, 1] = y[k]
        out[k, 2] = z[k]
    return out
