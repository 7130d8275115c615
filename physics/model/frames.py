"""Reference and material frames of a discrete rod (Bergou et al. 2008, 2010).

Every function here is a Numba kernel over plain arrays. The DOF vector ``q`` of an
``n``-node rod has length ``4n-1``: node ``i`` is ``q[4i:4i+3]`` (metres) and the twist
angle of edge ``i`` is ``q[4i+3]`` (radians), as in Section 2.2 of Huang & Jawed 2020.

Inside loops, 3-vectors are 3-tuples of floats (``vcross``, ``row3``, ...), which Numba
keeps in registers, so the per-edge work allocates nothing; only the returned arrays are
allocated. :func:`update_frames` is the fused per-step kernel behind
``physics.elastic.rod_frames``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_TWO_PI = 2.0 * np.pi
_INV_TWO_PI = 1.0 / _TWO_PI


@njit(cache=True)
def dot3(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two (3,) vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two (3,) vectors, returned as a new (3,) array.

    Allocates; the kernels use the allocation-free tuple form :func:`vcross` instead."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


# Allocation-free 3-vector helpers: a 3-vector is a 3-tuple of floats; arrays of shape
# (3,) are accepted wherever one is read.


@njit(cache=True)
def vec(a: np.ndarray) -> tuple[float, float, float]:
    """The (3,) array ``a`` as a 3-tuple."""
    return (a[0], a[1], a[2])


@njit(cache=True)
def row3(a: np.ndarray, i: int) -> tuple[float, float, float]:
    """Row ``i`` of an (m, 3) array as a 3-tuple (no view is created)."""
    return (a[i, 0], a[i, 1], a[i, 2])


@njit(cache=True)
def vcross(a, b) -> tuple[float, float, float]:
    """Cross product ``a x b`` of two 3-vectors, as a 3-tuple."""
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


@njit(cache=True)
def write3(out: np.ndarray, i: int, v) -> None:
    """``out[i, :] = v`` for an (m, 3) array ``out`` and 3-vector ``v``."""
    out[i, 0] = v[0]
    out[i, 1] = v[1]
    out[i, 2] = v[2]


@njit(cache=True)
def _half_turn(u, t1) -> tuple[float, float, float]:
    """Half turn of ``u`` about the fixed normal :func:`_normal_of` of ``t1`` (the
    anti-parallel fallback of :func:`parallel_transport`); kept out of line."""
    p = _normal_of(t1)
    s = 2.0 * dot3(p, u)
    return (s * p[0] - u[0], s * p[1] - u[1], s * p[2] - u[2])


@njit(cache=True, inline="always", error_model="numpy")
def _rodrigues(u, t1, t2, c: float) -> tuple[float, float, float]:
    """The transport formula, in one place: ``c u + b x u + (b.u) b / (1 + c)`` with
    ``b = t1 x t2`` and ``c = t1.t2`` (passed in, so callers test ``1 + c`` for the
    anti-parallel case once). Inlined, so the loops of :func:`update_frames` still
    vectorise; anti-parallel tangents (``1 + c = 0``) give inf/nan, not an exception."""
    b = vcross(t1, t2)
    bxu = vcross(b, u)
    s = dot3(b, u) / (1.0 + c)
    return (
        c * u[0] + bxu[0] + s * b[0],
        c * u[1] + bxu[1] + s * b[1],
        c * u[2] + bxu[2] + s * b[2],
    )


@njit(cache=True)
def _transport(u, t1, t2) -> tuple[float, float, float]:
    """Tuple form of :func:`parallel_transport`."""
    c = dot3(t1, t2)
    if 1.0 + c <= 1e-12:
        return _half_turn(u, t1)
    return _rodrigues(u, t1, t2, c)


@njit(cache=True)
def _normal_of(t) -> tuple[float, float, float]:
    """A deterministic unit vector normal to unit ``t`` (3-vector): the coordinate axis
    least aligned with ``t``, with its ``t`` component removed."""
    k = 0
    if abs(t[1]) < abs(t[k]):
        k = 1
    if abs(t[2]) < abs(t[k]):
        k = 2
    a = (1.0 if k == 0 else 0.0, 1.0 if k == 1 else 0.0, 1.0 if k == 2 else 0.0)
    return _normal_part(a, t)


@njit(cache=True)
def _normal_part(u, t) -> tuple[float, float, float]:
    """3-vector ``u`` with its component along unit ``t`` removed, normalised."""
    s = dot3(u, t)
    o0 = u[0] - s * t[0]
    o1 = u[1] - s * t[1]
    o2 = u[2] - s * t[2]
    inv = 1.0 / np.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    return (o0 * inv, o1 * inv, o2 * inv)


@njit(cache=True)
def _as_array(v) -> np.ndarray:
    """A new (3,) array holding 3-vector ``v``."""
    out = np.empty(3)
    out[0] = v[0]
    out[1] = v[1]
    out[2] = v[2]
    return out


@njit(cache=True)
def parallel_transport(u: np.ndarray, t1: np.ndarray, t2: np.ndarray) -> np.ndarray:
    """Transport ``u`` (3,) from unit tangent ``t1`` to unit tangent ``t2``.

    The map is the rotation about ``t1 x t2`` that takes ``t1`` to ``t2`` (Bergou et al.
    2008), written in Rodrigues form ``c u + b x u + (b.u) b / (1 + c)`` with
    ``b = t1 x t2`` and ``c = t1.t2``; it is the identity when the tangents coincide.
    Anti-parallel tangents (no unique minimal rotation) fall back to a half turn about a
    fixed axis normal to ``t1``. Returns a new (3,) array.
    """
    return _as_array(_transport(vec(u), vec(t1), vec(t2)))


@njit(cache=True)
def edge_tangent(q: np.ndarray, i: int) -> tuple[float, float, float]:
    """Unit tangent of edge ``i`` of DOF vector ``q`` (4n-1,), as a 3-tuple."""
    p = 4 * i
    e0 = q[p + 4] - q[p]
    e1 = q[p + 5] - q[p + 1]
    e2 = q[p + 6] - q[p + 2]
    inv = 1.0 / np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    return (e0 * inv, e1 * inv, e2 * inv)


@njit(cache=True)
def tangents(q: np.ndarray) -> np.ndarray:
    """Unit edge tangents ``t^i = e^i / |e^i|`` of DOF vector ``q`` (4n-1,); returns (n-1, 3)."""
    n = (q.shape[0] + 1) // 4
    t = np.empty((n - 1, 3))
    for i in range(n - 1):
        write3(t, i, edge_tangent(q, i))
    return t


@njit(cache=True)
def transported_director(d1_old, t_old, t_new) -> tuple[float, float, float]:
    """Reference director ``d1_old`` time-parallel transported from ``t_old`` to ``t_new``
    and re-orthonormalised against ``t_new`` (3-vectors in, 3-tuple out)."""
    return _normal_part(_transport(d1_old, t_old, t_new), t_new)


@njit(cache=True)
def node_reference_twist(d1_prev, t_prev, d1_i, t_i, ref_old: float) -> float:
    """Signed angle about ``t_i`` from ``d1_prev`` transported ``t_prev -> t_i`` to
    ``d1_i``, shifted by a multiple of 2*pi to lie closest to ``ref_old`` (rad)."""
    u = _transport(d1_prev, t_prev, t_i)
    ang = np.arctan2(dot3(vcross(u, d1_i), t_i), dot3(u, d1_i))
    ang += _TWO_PI * np.round((ref_old - ang) * _INV_TWO_PI)
    return ang


@njit(cache=True)
def rotated_directors(d1, d2, theta: float):
    """``(m1, m2)`` = ``(cos d1 + sin d2, -sin d1 + cos d2)`` of ``theta`` (3-tuples)."""
    c = np.cos(theta)
    s = np.sin(theta)
    m1 = (c * d1[0] + s * d2[0], c * d1[1] + s * d2[1], c * d1[2] + s * d2[2])
    m2 = (-s * d1[0] + c * d2[0], -s * d1[1] + c * d2[1], -s * d1[2] + c * d2[2])
    return m1, m2


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
    if m == 0:
        return d1, d2
    ti = row3(t, 0)
    a = _normal_of(ti)
    write3(d1, 0, a)
    write3(d2, 0, vcross(ti, a))
    for i in range(1, m):
        tp = ti
        ti = row3(t, i)
        a = _normal_part(_transport(a, tp, ti), ti)
        write3(d1, i, a)
        write3(d2, i, vcross(ti, a))
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
        tn = row3(t_new, i)
        a = transported_director(row3(d1_old, i), row3(t_old, i), tn)
        write3(d1, i, a)
        write3(d2, i, vcross(tn, a))
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
        ref[i - 1] = node_reference_twist(
            row3(d1, i - 1), row3(t, i - 1), row3(d1, i), row3(t, i), ref_twist_old[i - 1]
        )
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
        a, b = rotated_directors(row3(d1, i), row3(d2, i), theta[i])
        write3(m1, i, a)
        write3(m2, i, b)
    return m1, m2


@njit(cache=True, error_model="numpy")
def update_frames(
    q: np.ndarray, d1_old: np.ndarray, t_old: np.ndarray, ref_twist_old: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """All frames of configuration ``q`` (4n-1,) reached from the previous step: the
    results of :func:`tangents`, :func:`time_parallel_transport` (from ``d1_old`` along
    ``t_old -> t``, both (n-1, 3)), :func:`reference_twist` (continuous with
    ``ref_twist_old`` (n-2,)) and :func:`material_frames` (angles ``q[3::4]``), with the
    same formulas. Returns ``(t, d1, d2, ref_twist, m1, m2)``.

    This is the per-step hot path, so it works on a structure-of-arrays scratch block
    that lets the compiler vectorise the transport arithmetic across edges; the rare
    anti-parallel transports are redone afterwards with the scalar formulas, and the
    libm calls (``arctan2``, ``sin``, ``cos``) get loops of their own. A zero-length edge
    raises ``ZeroDivisionError`` as :func:`tangents` does.
    """
    m = (q.shape[0] + 1) // 4 - 1
    t = np.empty((m, 3))
    d1 = np.empty((m, 3))
    d2 = np.empty((m, 3))
    ref = np.empty(max(m - 1, 0))
    m1 = np.empty((m, 3))
    m2 = np.empty((m, 3))
    w = np.empty((13, m))
    tx, ty, tz = w[0], w[1], w[2]  # edge vectors, then unit tangents
    ax, ay, az = w[3], w[4], w[5]  # old tangents, then d1
    ux, uy, uz = w[6], w[7], w[8]  # old d1, then d2
    cpl = w[9]  # 1 + cos of the transport angle (anti-parallel test)
    xs, ys = w[10], w[11]  # arctan2 arguments of the reference twist
    ang = w[12]  # material angles

    for i in range(m):
        p = 4 * i
        e0 = q[p + 4] - q[p]
        e1 = q[p + 5] - q[p + 1]
        e2 = q[p + 6] - q[p + 2]
        if e0 * e0 + e1 * e1 + e2 * e2 == 0.0:
            raise ZeroDivisionError("division by zero")
        tx[i], ty[i], tz[i] = e0, e1, e2
        ax[i], ay[i], az[i] = t_old[i, 0], t_old[i, 1], t_old[i, 2]
        ux[i], uy[i], uz[i] = d1_old[i, 0], d1_old[i, 1], d1_old[i, 2]
        ang[i] = q[p + 3]

    # tangent, time-parallel transport of d1 (transported_director) and d2 = t x d1
    for i in range(m):
        e0, e1, e2 = tx[i], ty[i], tz[i]
        inv = 1.0 / np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        t0, t1, t2 = e0 * inv, e1 * inv, e2 * inv
        a = (ax[i], ay[i], az[i])
        ti = (t0, t1, t2)
        c = dot3(a, ti)
        v0, v1, v2 = _rodrigues((ux[i], uy[i], uz[i]), a, ti, c)
        s = v0 * t0 + v1 * t1 + v2 * t2
        v0 = v0 - s * t0
        v1 = v1 - s * t1
        v2 = v2 - s * t2
        inv = 1.0 / np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        v0, v1, v2 = v0 * inv, v1 * inv, v2 * inv
        tx[i], ty[i], tz[i] = t0, t1, t2
        ax[i], ay[i], az[i] = v0, v1, v2
        ux[i], uy[i], uz[i] = t1 * v2 - t2 * v1, t2 * v0 - t0 * v2, t0 * v1 - t1 * v0
        cpl[i] = 1.0 + c
    for i in range(m):
        if cpl[i] <= 1e-12:  # anti-parallel: redo with the half-turn fallback
            ti = (tx[i], ty[i], tz[i])
            dn = transported_director(row3(d1_old, i), row3(t_old, i), ti)
            ax[i], ay[i], az[i] = dn
            ux[i], uy[i], uz[i] = vcross(ti, dn)

    # reference twist: d1[i-1] transported t[i-1] -> t[i], signed angle to d1[i]
    for i in range(1, m):
        tp = (tx[i - 1], ty[i - 1], tz[i - 1])
        ti = (tx[i], ty[i], tz[i])
        di = (ax[i], ay[i], az[i])
        c = dot3(tp, ti)
        u = _rodrigues((ax[i - 1], ay[i - 1], az[i - 1]), tp, ti, c)
        ys[i] = dot3(vcross(u, di), ti)
        xs[i] = dot3(u, di)
        cpl[i] = 1.0 + c
    for i in range(1, m):
        if cpl[i] <= 1e-12:
            ti = (tx[i], ty[i], tz[i])
            di = (ax[i], ay[i], az[i])
            u = _transport((ax[i - 1], ay[i - 1], az[i - 1]), (tx[i - 1], ty[i - 1], tz[i - 1]), ti)
            ys[i] = dot3(vcross(u, di), ti)
            xs[i] = dot3(u, di)
    for i in range(1, m):
        phi = np.arctan2(ys[i], xs[i])
        ref[i - 1] = phi + _TWO_PI * np.round((ref_twist_old[i - 1] - phi) * _INV_TWO_PI)

    # material frames
    for i in range(m):
        th = ang[i]
        xs[i] = np.cos(th)
        ys[i] = np.sin(th)
    for i in range(m):
        c = xs[i]
        s = ys[i]
        a0, a1, a2 = ax[i], ay[i], az[i]
        b0, b1, b2 = ux[i], uy[i], uz[i]
        t[i, 0], t[i, 1], t[i, 2] = tx[i], ty[i], tz[i]
        d1[i, 0], d1[i, 1], d1[i, 2] = a0, a1, a2
        d2[i, 0], d2[i, 1], d2[i, 2] = b0, b1, b2
        m1[i, 0], m1[i, 1], m1[i, 2] = c * a0 + s * b0, c * a1 + s * b1, c * a2 + s * b2
        m2[i, 0], m2[i, 1], m2[i, 2] = -s * a0 + c * b0, -s * a1 + c * b1, -s * a2 + c * b2
    return t, d1, d2, ref, m1, m2
