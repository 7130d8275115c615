"""Reference and material frames of a discrete rod (Bergou et al. 2008, 2010).

Every function here is a Numba kernel over plain arrays. The DOF vector ``q`` of an
``n``-node rod has length ``4n-1``: node ``i`` is ``q[4i:4i+3]`` (metres) and the twist
angle of edge ``i`` is ``q[4i+3]`` (radians), as in Section 2.2 of Huang & Jawed 2020.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_TWO_PI = 2.0 * np.pi


@njit(cache=True)
def dot3(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two (3,) vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two (3,) vectors, returned as a new (3,) array."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True)
def parallel_transport(u: np.ndarray, t1: np.ndarray, t2: np.ndarray) -> np.ndarray:
    """Transport ``u`` (3,) from unit tangent ``t1`` to unit tangent ``t2``.

    The map is the rotation about ``t1 x t2`` that takes ``t1`` to ``t2`` (Bergou et al.
    2008), written in Rodrigues form ``c u + b x u + (b.u) b / (1 + c)`` with
    ``b = t1 x t2`` and ``c = t1.t2``; it is the identity when the tangents coincide.
    Anti-parallel tangents (no unique minimal rotation) fall back to a half turn about a
    fixed axis normal to ``t1``.
    """
    c = dot3(t1, t2)
    out = np.empty(3)
    if 1.0 + c <= 1e-12:
        p = _any_normal(t1)
        s = 2.0 * dot3(p, u)
        for k in range(3):
            out[k] = s * p[k] - u[k]
        return out
    b = cross3(t1, t2)
    bxu = cross3(b, u)
    s = dot3(b, u) / (1.0 + c)
    for k in range(3):
        out[k] = c * u[k] + bxu[k] + s * b[k]
    return out


@njit(cache=True)
def _any_normal(t: np.ndarray) -> np.ndarray:
    """A deterministic unit vector normal to unit ``t`` (3,): the coordinate axis least
    aligned with ``t``, with its ``t`` component removed."""
    k = 0
    if abs(t[1]) < abs(t[k]):
        k = 1
    if abs(t[2]) < abs(t[k]):
        k = 2
    a = np.zeros(3)
    a[k] = 1.0
    return _unit_normal_part(a, t)


@njit(cache=True)
def _unit_normal_part(u: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``u`` (3,) with its component along unit ``t`` removed, normalised."""
    s = dot3(u, t)
    out = np.empty(3)
    for k in range(3):
        out[k] = u[k] - s * t[k]
    nrm = np.sqrt(dot3(out, out))
    for k in range(3):
        out[k] /= nrm
    return out


@njit(cache=True)
def tangents(q: np.ndarray) -> np.ndarray:
    """Unit edge tangents ``t^i = e^i / |e^i|`` of DOF vector ``q`` (4n-1,); returns (n-1, 3)."""
    n = (q.shape[0] + 1) // 4
    t = np.empty((n - 1, 3))
    for i in range(n - 1):
        nrm = 0.0
        for k in range(3):
            e = q[4 * i + 4 + k] - q[4 * i + k]
            t[i, k] = e
            nrm += e * e
        nrm = np.sqrt(nrm)
        for k in range(3):
            t[i, k] /= nrm
    return t


@njit(cache=True)
def space_parallel_frames(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Space-parallel reference frames along the rod (Bergou et al. 2008, Sec. 4.2).

    ``t``: (n-1, 3) unit tangents. ``d1^0`` is the coordinate axis least aligned with
    ``t^0``, made normal to it; ``d1^i`` is ``d1^{i-1}`` parallel transported from
    ``t^{i-1}`` to ``t^i``; ``d2 = t x d1``. Returns ``(d1, d2)``, each (n-1, 3).
    """
    m = t.shape[0]
    d1 = np.empty((m, 3))
    d2 = np.empty((m, 3))
    d1[0] = _any_normal(t[0])
    for i in range(1, m):
        d1[i] = _unit_normal_part(parallel_transport(d1[i - 1], t[i - 1], t[i]), t[i])
    for i in range(m):
        d2[i] = cross3(t[i], d1[i])
    return d1, d2


@njit(cache=True)
def time_parallel_transport(
    d1_old: np.ndarray, t_old: np.ndarray, t_new: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Time-parallel reference frames (Bergou et al. 2010, Sec. 4.1).

    Each edge's old reference director ``d1_old[i]`` is parallel transported from
    ``t_old[i]`` to ``t_new[i]`` (all (m, 3)), then re-orthonormalised against
    ``t_new[i]``; ``d2 = t_new x d1``. Returns ``(d1, d2)``, each (m, 3).
    """
    m = t_new.shape[0]
    d1 = np.empty((m, 3))
    d2 = np.empty((m, 3))
    for i in range(m):
        d1[i] = _unit_normal_part(parallel_transport(d1_old[i], t_old[i], t_new[i]), t_new[i])
        d2[i] = cross3(t_new[i], d1[i])
    return d1, d2


@njit(cache=True)
def reference_twist(d1: np.ndarray, t: np.ndarray, ref_twist_old: np.ndarray) -> np.ndarray:
    """Reference twist at the interior nodes (Bergou et al. 2010, Sec. 4.2).

    For node ``i`` (1..n-2) this is the signed angle, about ``t^i``, from
    ``d1^{i-1}`` parallel transported to edge ``i`` to ``d1^i``, shifted by a multiple of
    2*pi to lie closest to ``ref_twist_old[i-1]`` so it stays continuous in time.
    ``d1``, ``t``: (n-1, 3); ``ref_twist_old``: (n-2,) rad. Returns (n-2,) rad.
    """
    m = t.shape[0]
    ref = np.empty(max(m - 1, 0))
    for i in range(1, m):
        u = parallel_transport(d1[i - 1], t[i - 1], t[i])
        ang = np.arctan2(dot3(cross3(u, d1[i]), t[i]), dot3(u, d1[i]))
        ang += _TWO_PI * np.round((ref_twist_old[i - 1] - ang) / _TWO_PI)
        ref[i - 1] = ang
    return ref


@njit(cache=True)
def material_frames(
    d1: np.ndarray, d2: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Material directors ``m1 = cos(theta) d1 + sin(theta) d2``,
    ``m2 = -sin(theta) d1 + cos(theta) d2`` (Bergou et al. 2008, eqn (1)).

    ``d1``, ``d2``: (m, 3); ``theta``: (m,) rad. Returns ``(m1, m2)``, each (m, 3).
    """
    m = theta.shape[0]
    m1 = np.empty((m, 3))
    m2 = np.empty((m, 3))
    for i in range(m):
        c = np.cos(theta[i])
        s = np.sin(theta[i])
        for k in range(3):
            m1[i, k] = c * d1[i, k] + s * d2[i, k]
            m2[i, k] = -s * d1[i, k] + c * d2[i, k]
    return m1, m2
