"""The turn-level ids of the PPO agents, registered by ``import agents`` (the env layer registers only its own).

One step of ``FlagellumTurn-*`` is one turn the planner plans (``agents.turn_decision_env``); each id is a class
with its own defaults and docstring:

| id                          | class (entry point)                                | preset   |
|-----------------------------|----------------------------------------------------|----------|
| ``FlagellumTurn-v0``        | ``agents.turn_decision_env.TurnDecisionEnv``       | faithful |
| ``FlagellumTurn-fast-v0``   | ``agents.turn_decision_env.TurnDecisionFastEnv``   | fast     |

and in ``SURROGATE_TURN_ENV_IDS`` (no rod: ``agents.surrogate_turn_env``, the turn map of ``faithful`` replayed at
~10^3-10^4 decisions per CPU second):

| id                             | class (entry point)                            | model                       |
|--------------------------------|------------------------------------------------|-----------------------------|
| ``FlagellumTurn-surrogate-v0`` | ``agents.surrogate_turn_env.SurrogateTurnEnv`` | faithful's turn map, no rod |

and in ``BURST_ENV_IDS`` (the burst action design of ``agents.burst_design``: no planner inside, for agents that
learn from scratch; the two are twins, with the same spaces, rewards and ``info`` keys):

| id                              | class (entry point)                              | model                       |
|---------------------------------|--------------------------------------------------|-----------------------------|
| ``FlagellumBurst-v0``           | ``agents.burst_decision_env.BurstDecisionEnv``   | the rod, faithful (default) |
| ``FlagellumBurst-surrogate-v0`` | ``agents.surrogate_burst_env.SurrogateBurstEnv`` | faithful's turn map, no rod |

``FlagellumTurn-coarse-v0`` went with its preset (``RETIRED_TURN_ENV_IDS``):
registered only so that ``gymnasium.make`` of it raises a one-line ValueError naming the replacement
(``refuse_retired_env``).

Every episode ends within the base env's time budget, a few to some tens of decisions, so no ``TimeLimit`` is
added. Light on purpose, like ``flagellum_env.registration``: it imports Gymnasium only; the entry points are
strings that ``gymnasium.make`` loads. ``gym.make("agents:FlagellumTurn-v0")`` imports the package itself (a
``SubprocVecEnv`` worker started with ``spawn`` finds the ids this way).
"""

from __future__ import annotations

import functools

import gymnasium as gym

TURN_ENV_ID = "FlagellumTurn-v0"
TURN_FAST_ENV_ID = "FlagellumTurn-fast-v0"
TURN_SURROGATE_ENV_ID = "FlagellumTurn-surrogate-v0"
BURST_ENV_ID = "FlagellumBurst-v0"
BURST_SURROGATE_ENV_ID = "FlagellumBurst-surrogate-v0"

#: id -> entry point
TURN_ENV_IDS: dict[str, str] = {
    TURN_ENV_ID: "agents.turn_decision_env:TurnDecisionEnv",
    TURN_FAST_ENV_ID: "agents.turn_decision_env:TurnDecisionFastEnv",
}
#: Retired id -> (its retired preset, the id to use instead); registered only to be refused
RETIRED_TURN_ENV_IDS: dict[str, tuple[str, str]] = {
    "FlagellumTurn-coarse-v0": ("coarse", TURN_ENV_ID),
}
#: id -> entry point of the turn-level surrogates (no rod; the same spaces, rewards and ``info`` as
#: ``FlagellumTurn-v0``, the calibrated range of the default preset only: no ``preset`` other than it, no rendering)
SURROGATE_TURN_ENV_IDS: dict[str, str] = {
    TURN_SURROGATE_ENV_ID: "agents.surrogate_turn_env:SurrogateTurnEnv",
}
#: id -> entry point of the burst action design (``agents.burst_design``: one action = one burst command, no
#: planner), for agents that learn from scratch
BURST_ENV_IDS: dict[str, str] = {
    BURST_ENV_ID: "agents.burst_decision_env:BurstDecisionEnv",
    BURST_SURROGATE_ENV_ID: "agents.surrogate_burst_env:SurrogateBurstEnv",
}


def refuse_retired_env(env_id: str, preset: str, replacement: str, /, **kwargs: object) -> None:
    """The entry point of a retired id: raises ValueError (``physics.presets.retired_env_message``) whatever it is
    given."""
    from physics.presets import retired_env_message  # not at import: the registration stays light

    raise ValueError(retired_env_message(env_id, preset, replacement))


def register_turn_envs() -> None:
    """Register every id of ``TURN_ENV_IDS``, ``SURROGATE_TURN_ENV_IDS`` and ``BURST_ENV_IDS`` not registered yet
    (re-importing registers nothing twice)."""
    for env_id, entry_point in {**TURN_ENV_IDS, **SURROGATE_TURN_ENV_IDS, **BURST_ENV_IDS}.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point, max_episode_steps=None)
    for env_id, (preset, replacement) in RETIRED_TURN_ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=functools.partial(refuse_retired_env, env_id, preset, replacement),
                         max_episode_steps=None)


register_turn_envs()
