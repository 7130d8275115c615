"""Gymnasium environments for steering the buckling-flagellum swimmer through waypoints.

``import flagellum_env`` registers the package's ids (``flagellum_env.registration``)::

    import gymnasium as gym
    import flagellum_env  # noqa: F401  (registers the ids)

    env = gym.make("FlagellumSteer-v0", path="random")         # the default preset, faithful
    env = gym.make("FlagellumSteer-fast-v0", path="random")  # a looser step tolerance than the default

| id                         | what                                               | preset   |
|----------------------------|----------------------------------------------------|----------|
| ``FlagellumSteer-v0``      | motor speed every ``control_dt`` (2 s)            | faithful |
| ``FlagellumSteer-fast-v0`` | the same, looser error tolerance                  | fast     |

``FlagellumSteer-coarse-v0`` was retired with its preset: ``gym.make`` of it
raises a one-line ValueError naming the replacement (``flagellum_env.registration.RETIRED_ENV_IDS``).

The turn-level ids of the PPO agents (``FlagellumTurn-*``: one step = one turn the planner plans) are registered
by ``import agents``, one layer up (``agents.registration``).

``gym.make("flagellum_env:FlagellumSteer-v0")`` imports the package itself (a worker process that
did not import it, e.g. a ``SubprocVecEnv`` started with ``spawn``, finds every id this way).
Gymnasium 1.x has no plugin entry points that would register them without an import.

The registration is light (Gymnasium only); the names below (the env class, its configuration,
paths) load on first use (PEP 562).
"""

from __future__ import annotations

from flagellum_env.registration import ENV_IDS, STEER_ENV_ID, STEER_FAST_ENV_ID

ENV_ID = STEER_ENV_ID

#: Public name -> module that defines it (imported on first access).
_API = {"FlagellumSteerEnv": "flagellum_env.steer_env", "FlagellumSteerFastEnv": "flagellum_env.steer_env",
        "RandomizationConfig": "flagellum_env.config", "SteerConfig": "flagellum_env.config",
        "RewardConfig": "flagellum_env.rewards",
        "RandomPathConfig": "flagellum_env.paths", "WaypointPath": "flagellum_env.paths",
        "load_path": "flagellum_env.paths", "path_from_waypoints": "flagellum_env.paths",
        "random_path": "flagellum_env.paths", "save_path": "flagellum_env.paths",
        "square_path": "flagellum_env.paths"}

__all__ = sorted(["ENV_ID", "ENV_IDS", "STEER_ENV_ID", "STEER_FAST_ENV_ID", *_API])


def __getattr__(name: str):
    if name in _API:
        import importlib

        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'flagellum_env' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
