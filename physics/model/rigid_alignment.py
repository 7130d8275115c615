"""Best-fit rigid rotation between two point clouds (Kabsch 1976).

Used to reuse a hydrodynamic resistance computed at an earlier configuration: the LSBT and
head kernels depend only on relative positions and are isotropic, so for a configuration that
differs from the reference by a rigid motion (x -> Q x + c) the resistance is exactly
R(Qx) = Q~ R(x) Q~^T, with Q~ = block-diag(Q, ..., Q, 1) (the head spin rate is a scalar).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def best_fit_rotation(x_ref: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, float]:
    """Rotation Q minimising sum |(x - mean x) - Q (x_ref - mean x_ref)|^2, and the residual.

    x_ref, x: (n,3) positions, m. Returns Q (3,3) proper rotation and the largest remaining
    (non-rigid) node deviation, m.
    """
    n = x.shape[0]
    ca = np.zeros(3)
    cb = np.zeros(3)
    for i in range(n):
        ca += x_ref[i]
        cb += x[i]
    ca /= n
    cb /= n
    a = x_ref - ca
    b = x - cb
    u, _, vt = np.linalg.svd(a.T @ b)
    d = 1.0 if np.linalg.det(u @ vt) > 0 else -1.0
    D = np.eye(3)
    D[2, 2] = d
    q = (u @ D @ vt).T
    dev2 = 0.0
    for i in range(n):
        s = 0.0
        for k in range(3):
            r = b[i, k] - (q[k, 0] * a[i, 0] + q[k, 1] * a[i, 1] + q[k, 2] * a[i, 2])
            s += r * r
        if s > dev2:
            dev2 = s
    return q, np.sqrt(dev2)
