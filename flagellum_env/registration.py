"""The Gymnasium ids of the env layer, registered in one place (``import flagellum_env`` runs this).

Light on purpose: it imports Gymnasium only, not the env, the physics or NumPy (the entry points are
strings, loaded by ``gymnasium.make``). Each id is a class with its own defaults and docstring
(highway-env's pattern: ``highway-fast-v0`` beside ``highway-v0``):

| id                           | class (entry point)                                 | preset   | max_episode_steps |
|------------------------------|-----------------------------------------------------|----------|-------------------|
| ``FlagellumSteer-v0``        | ``flagellum_env.steer_env.FlagellumSteerEnv``       | faithful | 400               |
| ``FlagellumSteer-fast-v0``   | ``flagellum_env.steer_env.FlagellumSteerFastEnv``   | fast     | 400               |

The env ends every episode on its own time budget (``time_factor`` x path length / v0, see the class
docstring), which depends on the path. ``max_episode_steps`` at registration is the largest that budget can be
with the registered defaults (the longest default random path, 3 x 8 cm, at ``STEADY_SPEED_FLOOR_M_S``), so the
``TimeLimit`` Gymnasium adds never cuts an episode the env would have run on: ``steer_max_episode_steps()``. Give
``gymnasium.make`` a larger ``max_episode_steps`` (or -1: no ``TimeLimit``) for a longer path or a shorter
``control_dt``; the env warns when it sees that the registered limit would cut its budget.

``FlagellumSteer-coarse-v0`` went with its preset (``RETIRED_ENV_IDS``): it
stays registered only so that ``gymnasium.make`` of it raises a one-line ValueError naming the replacement
(``refuse_retired_env``) instead of Gymnasium's generic "doesn't exist".

The turn-level ids of the PPO agents (``FlagellumTurn-*``) live one layer up and are registered by ``import
agents`` (``agents.registration``).
"""

from __future__ import annotations

import functools
import math

import gymnasium as gym

STEER_ENV_ID = "FlagellumSteer-v0"
STEER_FAST_ENV_ID = "FlagellumSteer-fast-v0"

#: A lower bound of the steady straight-swimming speed at 10 rpm, m/s (``env.steady_speed_m_s``): measured 7.15e-4
#: m/s at the faithful and fast presets (7.08e-4 at the retired coarse) with the default head reading (held), 4.68e-4 with the
#: head counter-rotating (``head_rotation=torque_free``, the slowest reading); 4 % below the slowest.
STEADY_SPEED_FLOOR_M_S = 4.5e-4
#: The defaults the bound is computed from (``SteerConfig`` / ``RandomPathConfig``; a test holds them equal).
STEER_DEFAULT_CONTROL_DT_S = 2.0
STEER_DEFAULT_TIME_FACTOR = 1.5
STEER_DEFAULT_MAX_PATH_LENGTH_M = 3 * 0.08  # n_waypoints x the longest segment


def steer_max_episode_steps(control_dt: float = STEER_DEFAULT_CONTROL_DT_S,
                            time_factor: float = STEER_DEFAULT_TIME_FACTOR,
                            path_length_m: float = STEER_DEFAULT_MAX_PATH_LENGTH_M) -> int:
    """The most env steps ``FlagellumSteer-*``'s own time budget allows for a path this long (rounded up to
    a multiple of 10): ``time_factor * path_length_m / STEADY_SPEED_FLOOR_M_S / control_dt``."""
    steps = time_factor * path_length_m / STEADY_SPEED_FLOOR_M_S / control_dt
    return int(10 * math.ceil(steps / 10 - 1e-9))


#: id -> (entry point, max_episode_steps)
ENV_IDS: dict[str, tuple[str, int | None]] = {
    STEER_ENV_ID: ("flagellum_env.steer_env:FlagellumSteerEnv", steer_max_episode_steps()),
    STEER_FAST_ENV_ID: ("flagellum_env.steer_env:FlagellumSteerFastEnv", steer_max_episode_steps()),
}

#: Retired id -> (its retired preset, the id to use instead); registered only to be refused (``refuse_retired_env``).
RETIRED_ENV_IDS: dict[str, tuple[str, str]] = {
    "FlagellumSteer-coarse-v0": ("coarse", STEER_ENV_ID),
}


def refuse_retired_env(env_id: str, preset: str, replacement: str, /, **kwargs: object) -> None:
    """The entry point of a retired id: raises ValueError (``physics.presets.retired_env_message``) whatever it is
    given."""
    from physics.presets import retired_env_message  # not at import: the registration stays light

    raise ValueError(retired_env_message(env_id, preset, replacement))


def register_retired_envs(retired: dict[str, tuple[str, str]]) -> None:
    """Register each retired id (not registered yet) with an entry point that refuses it."""
    for env_id, (preset, replacement) in retired.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=functools.partial(refuse_retired_env, env_id, preset, replacement),
                         max_episode_steps=None)


def register_envs() -> None:
    """Register every id of ``ENV_IDS`` that is not registered yet (re-importing registers nothing twice)."""
    for env_id, (entry_point, max_steps) in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point, max_episode_steps=max_steps)
    register_retired_envs(RETIRED_ENV_IDS)


def registered_max_episode_steps(env_id: str | None) -> int | None:
    """The ``max_episode_steps`` ``env_id`` is registered with (None: no id, not registered or none)."""
    spec = gym.registry.get(env_id) if env_id else None
    return spec.max_episode_steps if spec is not None else None


register_envs()
