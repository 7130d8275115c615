"""Reward terms of the steering task. Each term is reported in ``info`` under ``reward_<name>``.

Per env step, with ds the gain in path progress (m), e the cross-track error at the end of the
step (m), tau the simulated duration of the step (s), E the motor energy of the step (J) and n
the number of waypoints reached in the step:

=============  ==================================================  ==========================
term           value                                               default weight
=============  ==================================================  ==========================
progress       + progress_per_cm * ds / 1 cm                       1.0 per cm
cross_track    - cross_track_per_cm_s * (e / 1 cm) * tau           0.005 per cm per s
energy         - energy_per_mj * E / 1 mJ                          0.01 per mJ
waypoint       + waypoint_bonus * n                                10.0 per waypoint
penalty        - off_path_penalty (left the path) or
               - error_penalty (SimulationError), once, at the end 20.0 each
=============  ==================================================  ==========================

The reward is the sum of the terms.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from numba import njit

from physics.validation import require_finite

CM = 1e-2  # m
MJ = 1e-3  # J

TERMS = ("progress", "cross_track", "energy", "waypoint", "penalty")


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the reward terms (all >= 0; see the module docstring for the formulas)."""

    progress_per_cm: float = 1.0
    cross_track_per_cm_s: float = 0.005
    energy_per_mj: float = 0.01
    waypoint_bonus: float = 10.0
    off_path_penalty: float = 20.0
    error_penalty: float = 20.0

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, require_finite(f"reward.{f.name}", getattr(self, f.name), 0.0))


def reward_terms(cfg: RewardConfig, progress_m: float, cross_track_m: float, duration_s: float,
                 energy_j: float, n_reached: int, off_path: bool = False, failed: bool = False) -> dict[str, float]:
    """The terms of one step's reward, keyed by ``TERMS``; the reward is their sum (``reward_values``)."""
    return dict(zip(TERMS, reward_values(cfg.progress_per_cm, cfg.cross_track_per_cm_s, cfg.energy_per_mj,
                                         cfg.waypoint_bonus, cfg.off_path_penalty, cfg.error_penalty,
                                         float(progress_m), float(cross_track_m), float(duration_s), float(energy_j),
                                         int(n_reached), bool(off_path), bool(failed))))


@njit(cache=True)
def reward_values(progress_per_cm: float, cross_track_per_cm_s: float, energy_per_mj: float, waypoint_bonus: float,
                  off_path_penalty: float, error_penalty: float, progress_m: float, cross_track_m: float,
                  duration_s: float, energy_j: float, n_reached: int, off_path: bool, failed: bool
                  ) -> tuple[float, float, float, float, float]:
    """The terms of one step's reward in the order of ``TERMS`` (module docstring): ``RewardConfig``'s weights,
    the progress (m), the cross-track error (m) over the duration (s), the motor energy (J), the waypoints reached,
    whether the step left the path or failed."""
    penalty = 0.0
    if failed:
        penalty -= error_penalty
    elif off_path:
        penalty -= off_path_penalty
    return (progress_per_cm * progress_m / CM, -cross_track_per_cm_s * (cross_track_m / CM) * duration_s,
            -energy_per_mj * energy_j / MJ, waypoint_bonus * n_reached, penalty)
