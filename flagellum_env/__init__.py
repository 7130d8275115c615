"""Gymnasium environment for steering the buckling-flagellum swimmer through waypoints.

``import flagellum_env`` registers ``FlagellumSteer-v0``::

    import gymnasium as gym
    import flagellum_env  # noqa: F401  (registers the env)

    env = gym.make("FlagellumSteer-v0", path="random", control_dt=2.0)

``gym.make("flagellum_env:FlagellumSteer-v0")`` imports the package itself. (Gymnasium 1.x has
no plugin entry points that would register it without an import.)
"""

from __future__ import annotations

import physics  # noqa: F401  (first: it asks for single-threaded BLAS before NumPy is loaded)

import gymnasium as gym

from flagellum_env.config import RandomizationConfig, SteerConfig
from flagellum_env.paths import (
    RandomPathConfig,
    WaypointPath,
    load_path,
    path_from_waypoints,
    random_path,
    save_path,
    square_path,
)
from flagellum_env.rewards import RewardConfig
from flagellum_env.steer_env import FlagellumSteerEnv

ENV_ID = "FlagellumSteer-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="flagellum_env.steer_env:FlagellumSteerEnv")

__all__ = ["ENV_ID", "FlagellumSteerEnv", "RandomPathConfig", "RandomizationConfig", "RewardConfig",
           "SteerConfig", "WaypointPath", "load_path", "path_from_waypoints", "random_path", "save_path",
           "square_path"]
