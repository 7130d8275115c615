"""3-vector arithmetic for compiled kernels, rounded as NumPy rounds it, so that a kernel gives the very floats of
the NumPy expressions it replaces.

- ``dot3(a, b)`` (``dot3s`` on components): ``a @ b`` of two float64 3-vectors. NumPy hands this to BLAS, whose
  ddot (OpenBLAS) accumulates with fused multiply-adds: fma(a2, b2, fma(a1, b1, a0 b0)).
- ``rowdot3(a, b)``: ``np.einsum("ij,ij->i", a, b)`` of one row pair, (a0 b0 + a2 b2) + a1 b1 (its pairwise lanes).
- ``rownorm3(v)``: ``np.linalg.norm(v, axis=1)`` of one row, sqrt((v0^2 + v1^2) + v2^2).
- ``norm3(v)``: ``np.linalg.norm(v)`` (and ``math.sqrt(v @ v)``) of a 3-vector.

tests/agents/test_vec3.py checks each against NumPy on random vectors.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, a, b, c):
    """a b + c rounded once (float64; LLVM's llvm.fma)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True)
def dot3s(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """``a @ b`` of two 3-vectors given by their components, rounded as NumPy's BLAS ddot rounds it."""
    return fma(a2, b2, fma(a1, b1, a0 * b0))


@njit(cache=True)
def dot3(a: np.ndarray, b: np.ndarray) -> float:
    """``a @ b`` of two float64 3-vectors, rounded as NumPy's BLAS ddot rounds it."""
    return dot3s(a[0], a[1], a[2], b[0], b[1], b[2])


@njit(cache=True)
def rowdot3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """One row of ``np.einsum("ij,ij->i", a, b)`` for 3 columns, rounded as NumPy rounds it."""
    return (a0 * b0 + a2 * b2) + a1 * b1


@njit(cache=True)
def rownorm3(v0: float, v1: float, v2: float) -> float:
    """One row of ``np.linalg.norm(v, axis=1)`` for 3 columns, rounded as NumPy rounds it."""
    return math.sqrt((v0 * v0 + v1 * v1) + v2 * v2)


@njit(cache=True)
def norm3(v: np.ndarray) -> float:
    """|v| of a float64 3-vector: sqrt(v @ v) as NumPy rounds it (``dot3``)."""
    return math.sqrt(dot3(v, v))


@njit(cache=True)
def segment_projection(x: np.ndarray, a: np.ndarray, b: np.ndarray, length: float
                       ) -> tuple[float, float, float, float]:
    """(s, the closest point's 3 coordinates) of the point ``x`` on the segment from ``a`` to ``b`` of ``length``
    (all (3,) float64, m): s the arc length of x's projection clipped to [0, length], the closest point a + s u with
    u = (b - a) / length; rounded as the NumPy expressions."""
    u0, u1, u2 = (b[0] - a[0]) / length, (b[1] - a[1]) / length, (b[2] - a[2]) / length
    s = min(max(dot3s(x[0] - a[0], x[1] - a[1], x[2] - a[2], u0, u1, u2), 0.0), length)
    return s, a[0] + s * u0, a[1] + s * u1, a[2] + s * u2
