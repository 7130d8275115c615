"""Controllers that steer the swimmer: the paper's rule-based turn planner, the adaptive and receding-horizon
planners, and PPO agents.

``import agents`` registers the turn-level env of the residual agents (``agents.turn_decision_env``: one step =
one turn the planner plans) as ``FlagellumTurn-v0`` and its variants, and its turn-level surrogate
``FlagellumTurn-surrogate-v0`` (``agents.surrogate_turn_env``: no rod) (``agents.registration``)::

    import gymnasium as gym
    import agents  # noqa: F401  (registers the FlagellumTurn ids)

    env = gym.make("FlagellumTurn-v0")  # the shipped agent's env, at the default preset

``gym.make("agents:FlagellumTurn-v0", ...)`` imports the registering package itself. The registration only
names the entry points: ``import agents`` loads Gymnasium, not the env, the physics, torch or stable-baselines3.
"""

from __future__ import annotations

from agents.registration import (SURROGATE_TURN_ENV_IDS, TURN_COARSE_ENV_ID, TURN_ENV_ID, TURN_ENV_IDS,
                                 TURN_FAST_ENV_ID, TURN_SURROGATE_ENV_ID)

__all__ = ["SURROGATE_TURN_ENV_IDS", "TURN_COARSE_ENV_ID", "TURN_ENV_ID", "TURN_ENV_IDS", "TURN_FAST_ENV_ID",
           "TURN_SURROGATE_ENV_ID"]
