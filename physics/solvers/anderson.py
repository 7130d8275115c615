"""Anderson acceleration of a fixed-point iteration (Anderson 1965; Walker & Ni 2011).

The chord iteration q <- g(q) = q - J_old^{-1} r(q) converges linearly when the Jacobian is
reused from another geometry (its error modes decay at different rates). Anderson mixing
combines the last ``depth`` iterates to cancel the slowly decaying modes: with
f_k = g(q_k) - q_k it solves min || f_k - dF gamma || over the differences of recent f and
takes q_{k+1} = g(q_k) - dG gamma. With depth 0 it is the plain iteration.
"""

from __future__ import annotations

import numpy as np


class AndersonMixing:
    """Type-II Anderson mixing with a diagonal scaling ``weights`` of the DOFs."""

    def __init__(self, weights: np.ndarray, depth: int) -> None:
        self.w = weights
        self.depth = depth
        self._f: list[np.ndarray] = []
        self._g: list[np.ndarray] = []

    def update(self, q: np.ndarray, g: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Next iterate from the current q, its image g = g(q) and f = g - q (all (n,))."""
        if self.depth <= 0:
            return g
        fw = f * self.w
        self._f.append(fw)
        self._g.append(g)
        if len(self._f) > self.depth + 1:
            self._f.pop(0)
            self._g.pop(0)
        if len(self._f) < 2:
            return g
        dF = np.stack([self._f[i + 1] - self._f[i] for i in range(len(self._f) - 1)], axis=1)
        dG = np.stack([self._g[i + 1] - self._g[i] for i in range(len(self._g) - 1)], axis=1)
        gamma, *_ = np.linalg.lstsq(dF, fw, rcond=1e-10)
        return g - dG @ gamma
