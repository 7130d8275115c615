"""General-banded (LAPACK) storage helpers shared by the elastic kernels.

The elastic Hessian has ``kl = ku = BANDWIDTH`` and is stored as ``ab`` (21, N) with
``ab[BANDWIDTH + i - j, j] = H[i, j]``, as taken by ``scipy.linalg.solve_banded``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

BANDWIDTH = 10
"""Half-bandwidth (kl = ku) of the elastic Hessian: an edge-pair element spans 11 DOFs."""


@njit(cache=True)
def add_band(ab: np.ndarray, i: int, j: int, v: float) -> None:
    """``H[i, j] += v`` in general-banded storage ``ab`` (2 BANDWIDTH + 1, N)."""
    ab[BANDWIDTH + i - j, j] += v
