"""Controllers that steer the swimmer: the paper's rule-based turn planner and PPO agents.

``import agents`` registers ``FlagellumTurn-v0``, the residual agent's training env
(``agents.turn_decision_env.TurnDecisionEnv``: one step = one turn the planner plans)::

    import gymnasium as gym
    import agents  # noqa: F401  (registers the env)

    env = gym.make("FlagellumTurn-v0", preset="coarse")

``gym.make("agents:FlagellumTurn-v0", ...)`` imports the package itself. The registration only
names the entry point: ``import agents`` loads Gymnasium, not the env, the physics, torch or
stable-baselines3.
"""

from __future__ import annotations

import physics  # noqa: F401  (first: it asks for single-threaded BLAS before NumPy is loaded)

import gymnasium as gym

TURN_ENV_ID = "FlagellumTurn-v0"

if TURN_ENV_ID not in gym.registry:
    gym.register(id=TURN_ENV_ID, entry_point="agents.turn_decision_env:TurnDecisionEnv")

__all__ = ["TURN_ENV_ID"]
