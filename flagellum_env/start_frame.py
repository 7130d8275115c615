"""The start frame of an episode and the transforms between it, the simulator's lab frame and
the head's body frame.

The simulator keeps its own lab frame (its t = 0 pose). An episode starts later, from steady
swimming, so the env defines the *start frame* as the head's pose at the episode start: origin
at the head centre, axes the head's body axes X_b, Y_b, Z_b at that instant. Paths are given in
the start frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StartFrame:
    """origin: (3,) m, lab frame; axes: (3, 3) rotation whose columns are the start frame's
    x, y, z axes in the lab frame."""

    origin: np.ndarray
    axes: np.ndarray

    @classmethod
    def from_pose(cls, head_position: np.ndarray, head_orientation: np.ndarray) -> StartFrame:
        """Start frame of a head at ``head_position`` (3,) m with body axes ``head_orientation`` (3, 3)."""
        origin = np.array(head_position, dtype=float)
        axes = np.array(head_orientation, dtype=float)
        origin.setflags(write=False)
        axes.setflags(write=False)
        return cls(origin=origin, axes=axes)

    def points_to_start(self, x_lab: np.ndarray) -> np.ndarray:
        """Lab-frame points (..., 3) m -> start-frame points (..., 3) m."""
        return (np.asarray(x_lab) - self.origin) @ self.axes

    def points_to_lab(self, x_start: np.ndarray) -> np.ndarray:
        """Start-frame points (..., 3) m -> lab-frame points (..., 3) m."""
        return np.asarray(x_start) @ self.axes.T + self.origin

    def rotation_to_start(self, r_lab: np.ndarray) -> np.ndarray:
        """A rotation whose columns are axes in the lab frame -> the same axes in the start frame, (3, 3)."""
        return self.axes.T @ r_lab


def to_body(vectors_lab: np.ndarray, head_orientation: np.ndarray) -> np.ndarray:
    """Lab-frame vectors (..., 3) -> components along the head's body axes X_b, Y_b, Z_b (..., 3)."""
    return np.asarray(vectors_lab) @ head_orientation
