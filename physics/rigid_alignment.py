"""Best-fit rigid rotation between two point clouds (Kabsch 1976).

Used to reuse a hydrodynamic resistance computed at an earlier configuration: the LSBT and
head kernels depend only on relative positions and are isotropic, so for a configuration that
differs from the reference by a rigid motion (x -> Q x + c) the resistance is exactly
R(Qx) = Q~ R(x) Q~^T, with Q~ = block-diag(Q, ..., Q, 1) (the head spin rate is a scalar).
"""

from __future__ import annotations

import numpy as np


def best_fit_rotation(x_ref: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, float]:
    """Rotation Q minimising sum |(x - mean x) - Q (x_ref - mean x_ref)|^2, and the residual.

    x_ref, x: (n,3) positions, m. Returns Q (3,3) proper rotation and the largest remaining
    (non-rigid) node deviation, m.
    """
    a = x_ref - x_ref.mean(axis=0)
    b = x - x.mean(axis=0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(u @ vt))
    q = (u @ np.diag([1.0, 1.0, d]) @ vt).T
    dev = float(np.sqrt(((b - a @ q.T) ** 2).sum(axis=1).max()))
    return q, dev
