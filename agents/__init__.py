"""Controllers that steer the swimmer: the paper's rule-based turn planner, the adaptive and receding-horizon
planners, and PPO agents.

``import agents`` registers the turn-level env of the residual agents (``agents.turn_decision_env``: one step =
one turn the planner plans) as ``FlagellumTurn-v0`` and its variant ``FlagellumTurn-fast-v0``, and its turn-level surrogate
``FlagellumTurn-surrogate-v0`` (``agents.surrogate_turn_env``: no rod), and the burst action design for agents with
no planner (``agents.burst_design``: one step = one burst command) as ``FlagellumBurst-v0`` (the rod) and
``FlagellumBurst-surrogate-v0`` (``agents.registration``)::

    import gymnasium as gym
    import agents  # noqa: F401  (registers the FlagellumTurn ids)

    env = gym.make("FlagellumTurn-v0")  # the shipped agent's env, at the default preset

``gym.make("agents:FlagellumTurn-v0", ...)`` imports the registering package itself. The registration only
names the entry points: ``import agents`` loads Gymnasium, not the env, the physics, torch or stable-baselines3.
"""

from __future__ import annotations

from agents.registration import (BURST_ENV_ID, BURST_ENV_IDS, BURST_SURROGATE_ENV_ID, SURROGATE_TURN_ENV_IDS,
                                 TURN_ENV_ID, TURN_ENV_IDS, TURN_FAST_ENV_ID, TURN_SURROGATE_ENV_ID)

__all__ = ["BURST_ENV_ID", "BURST_ENV_IDS", "BURST_SURROGATE_ENV_ID", "SURROGATE_TURN_ENV_IDS", "TURN_ENV_ID",
           "TURN_ENV_IDS", "TURN_FAST_ENV_ID", "TURN_SURROGATE_ENV_ID"]
