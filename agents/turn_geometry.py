"""Directions and angles of a turn (Sec. 3, Fig. 5a of Huang & Jawed 2020); pure functions.

The swimmer's straight path at the low motor speed is a helix: the head wobbles at the
flagellum's rotation rate in the lab frame, so a *heading* is the head displacement over one
wobble period (which cancels the wobble). A turn takes the heading d0 to t1:

- theta = angle(d0, t1);
- phi = angle between t1 and the x-y plane of the reference frame (signed, + towards +z); the
  paper's reference frame is the body frame at the start (x, y, z along -X_b, -Y_b, Z_b);
  theta and phi do not depend on the signs of x and y;
- psi = azimuth of t1 about d0, measured from the azimuth of a chosen flagellum node at the
  moment the burst starts. The flagellum's shape is what buckles, so the direction of a turn
  is fixed relative to the flagellum's rotation phase (Fig. 5e): psi is a property of the
  burst length, and the planner picks the out-of-plane angle by choosing when to burst.
"""

from __future__ import annotations

import math

import numpy as np


_X = np.array([1.0, 0.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


def unit(v: np.ndarray) -> np.ndarray:
    """v / |v| for a non-zero 3-vector; ValueError for a zero or non-finite one."""
    v = np.asarray(v, dtype=np.float64)
    n = math.sqrt(float(v @ v))  # np.linalg.norm of a vector, without its overhead
    if not math.isfinite(n) or n == 0.0:
        raise ValueError(f"cannot normalise the vector {v.tolist()} (zero or not finite)")
    return v / n


def perpendicular_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) with (e1, e2, axis) right-handed and orthonormal; axis (3,) unit."""
    a = unit(axis)
    helper = _Z if abs(a[2]) < 0.9 else _X
    e1 = unit(helper - (helper @ a) * a)
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(e1[0]), float(e1[1]), float(e1[2])
    # a x e1, the products and differences of np.cross (same values), without its overhead
    return e1, np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def azimuth(v: np.ndarray, axis: np.ndarray) -> float:
    """Angle (rad, (-pi, pi]) of v's component across ``axis`` in ``perpendicular_basis(axis)``."""
    e1, e2 = perpendicular_basis(axis)
    return math.atan2(float(v @ e2), float(v @ e1))


def wrap_angle(a: float) -> float:
    """a wrapped to (-pi, pi] (rad)."""
    return math.pi - (math.pi - a) % (2.0 * math.pi)


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two non-zero vectors, rad in [0, pi]."""
    return math.acos(min(max(float(unit(a) @ unit(b)), -1.0), 1.0))


def turn_angles(d0: np.ndarray, t1: np.ndarray, frame: np.ndarray) -> tuple[float, float]:
    """(theta, phi) in degrees for directions d0, t1 (lab); ``frame`` (3, 3) columns X_b, Y_b, Z_b."""
    t = frame.T @ unit(t1)
    theta = math.degrees(angle_between(d0, t1))
    phi = math.degrees(math.asin(float(np.clip(t[2], -1.0, 1.0))))
    return theta, phi


def direction_from(d0: np.ndarray, theta_rad: float, azimuth_rad: float) -> np.ndarray:
    """The unit direction at angle theta from d0 and at ``azimuth`` about it (inverse of the above)."""
    e1, e2 = perpendicular_basis(d0)
    return (math.cos(theta_rad) * unit(d0)
            + math.sin(theta_rad) * (math.cos(azimuth_rad) * e1 + math.sin(azimuth_rad) * e2))
