"""Controllers that steer the swimmer: the paper's rule-based turn planner and PPO agents.

The turn-level env of the residual agent (``agents.turn_decision_env.TurnDecisionEnv``: one step =
one turn the planner plans) is registered with every other id by ``import flagellum_env``
(``flagellum_env.registration``), which ``import agents`` runs too::

    import gymnasium as gym
    import flagellum_env  # noqa: F401  (registers the ids)

    env = gym.make("FlagellumTurn-coarse-v0")  # the shipped agent's env

``gym.make("flagellum_env:FlagellumTurn-v0", ...)`` imports the registering package itself. The
registration only names the entry points: ``import agents`` loads Gymnasium, not the env, the
physics, torch or stable-baselines3.
"""

from __future__ import annotations

from flagellum_env.registration import TURN_COARSE_ENV_ID, TURN_ENV_ID, TURN_FAST_ENV_ID

__all__ = ["TURN_COARSE_ENV_ID", "TURN_ENV_ID", "TURN_FAST_ENV_ID"]
