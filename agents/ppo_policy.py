"""Load a trained PPO agent as a controller of ``FlagellumSteer-v0`` (``--controller ppo[:PATH]``).

An agent is a folder written by ``flagellum train`` (``agents.ppo_training``): ``model.zip``,
``vecnormalize.pkl``, ``meta.json`` and ``config.yml``. ``PATH`` may be that folder or its
``model.zip``; without it, the pretrained agent shipped with the package (``PRETRAINED_DIR``) is used.

With plain stable-baselines3, the agent on its own env (``meta.json`` stores the env as a registered id
and its ``gymnasium.make`` arguments; tests/agents/test_shipped_agent_env.py)::

    import json, agents  # registers the FlagellumTurn ids
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    meta = json.load(open(f"{folder}/meta.json"))
    venv = VecNormalize.load(f"{folder}/vecnormalize.pkl",
                             make_vec_env(meta["env_id"], env_kwargs=meta["make_kwargs"]))
    venv.training, venv.norm_reward = False, False
    model = PPO.load(f"{folder}/model.zip", env=venv)

The agent is residual (``meta["mode"] == "residual"``): a ``ResidualPlanner`` (``meta["planner"] == "rule"``,
the default) or an ``AdaptiveResidualPlanner`` (``"adaptive"``) whose planned turns are corrected by the policy,
with the turn map of the env's preset. Its corrections are on the
map's turning angle, so an agent trained on one preset drives another through that preset's map.
"""

from __future__ import annotations

import json
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.assets import default_turn_map, missing_turn_map_message, pretrained_dir
from agents.residual_planner import AdaptiveResidualPlanner, ResidualLimits, ResidualPlanner, base_planner
from agents.turn_map import TurnMap

#: The pretrained agent shipped with the package (package data, ``agents.assets``).
PRETRAINED_DIR = pretrained_dir()


@dataclass
class TrainedAgent:
    """A trained stable-baselines3 policy (PPO or SAC) with its observation normalisation;
    ``act(features, deterministic)``."""

    model: Any
    obs_rms: Any
    clip_obs: float
    epsilon: float
    meta: dict[str, Any]
    folder: Path

    def act(self, features: np.ndarray, deterministic: bool = True) -> np.ndarray:
        """The action in [-1, 1] for one feature vector: a residual agent's (2,) for the planner's features
        (``BASE_PLANNERS[planner].n_features``,), a burst agent's (4,) for ``burst_observation``'s."""
        f = np.asarray(features, dtype=np.float64)
        if self.obs_rms is not None:
            f = np.clip((f - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon), -self.clip_obs,
                        self.clip_obs)
        action, _ = self.model.predict(f.astype(np.float32), deterministic=deterministic)
        return np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)


def agent_folder(arg: str | None) -> Path:
    """The agent's folder for ``ppo`` (None: the pretrained one) or ``ppo:PATH``; ValueError if absent."""
    folder = PRETRAINED_DIR if arg is None else Path(arg)
    if folder.suffix == ".zip":
        folder = folder.parent
    missing = [n for n in ("model.zip", "meta.json") if not (folder / n).is_file()]
    if missing:
        raise ValueError(f"no trained PPO agent at {str(folder)!r} (missing {', '.join(missing)}); train one with "
                         "'flagellum train --out DIR' and use --controller ppo:DIR")
    return folder


def load_policy(folder: Path) -> TrainedAgent:
    """The trained policy in an agent folder (``agent_folder``): stable-baselines3 PPO or SAC as ``meta.json``'s
    ``run.algorithm`` says (PPO before it was recorded), with the observation statistics of ``vecnormalize.pkl``."""
    from agents.ppo_training import algorithm_class

    meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    model = algorithm_class(meta.get("run", {}).get("algorithm", "ppo")).load(str(folder / "model.zip"), device="cpu")
    obs_rms, clip, eps = None, 10.0, 1e-8
    stats = folder / "vecnormalize.pkl"
    if stats.is_file():
        with open(stats, "rb") as f:
            vn = pickle.load(f)  # VecNormalize without its venv: the statistics are what is needed
        if vn.norm_obs:
            obs_rms, clip, eps = vn.obs_rms, float(vn.clip_obs), float(vn.epsilon)
    return TrainedAgent(model, obs_rms, clip, eps, meta, folder)


def load_agent(arg: str | None = None) -> TrainedAgent:
    """Load the residual agent named by ``arg`` (see ``agent_folder``)."""
    folder = agent_folder(arg)
    meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    if meta.get("mode") == "scratch":
        raise ValueError(f"the agent in {str(folder)!r} was trained from scratch (no planner inside); fly it with "
                         f"--controller ppo-scratch:{folder}")
    if meta.get("mode") != "residual":
        raise ValueError(f"the agent in {str(folder)!r} has mode {meta.get('mode')!r}; this version drives "
                         "'residual' agents")
    planner = meta.get("planner", "rule")
    try:
        _, planner_cls, _ = base_planner(planner)
    except ValueError as exc:
        raise ValueError(f"the agent in {str(folder)!r} corrects a planner this version does not have: {exc}") \
            from None
    agent = load_policy(folder)
    n = planner_cls.n_features
    if agent.model.observation_space.shape != (n,):
        raise ValueError(f"the agent in {str(folder)!r} expects {agent.model.observation_space.shape} observations, "
                         f"this version's turn features of the {planner} planner are ({n},): retrain it")
    return agent


class _AgentDriven:
    """A residual planner driven by a trained agent (mixin); ``predict`` like a stable-baselines3 policy.
    ``deterministic``: what the last ``predict`` asked for (the agent acts on it)."""

    agent: TrainedAgent
    deterministic: bool = True

    def drive_with(self, agent) -> None:
        """Let ``agent`` (anything with ``act(features, deterministic)``: ``TrainedAgent``, an RLlib agent) correct
        the planner's turns."""
        self.agent = agent
        self.policy = lambda f: agent.act(f, self.deterministic)

    def predict(self, observation: np.ndarray, state=None, episode_start=None, deterministic: bool = True):
        self.deterministic = bool(deterministic)
        return super().predict(observation, state, episode_start, deterministic)  # type: ignore[misc]


class PPOController(_AgentDriven, ResidualPlanner):
    """The rule planner corrected by a trained agent."""


class AdaptivePPOController(_AgentDriven, AdaptiveResidualPlanner):
    """The adaptive planner corrected by a trained agent."""


def load_ppo_controller(arg: str | None, env, preset: str) -> PPOController | AdaptivePPOController:
    """``--controller ppo[:PATH]`` for this env: the agent plus the turn map of ``preset``."""
    agent = load_agent(arg)
    tmap_file = default_turn_map(preset)
    if not tmap_file.is_file():
        raise ValueError("the PPO agent corrects the turn planner, which needs a turn map: "
                         + missing_turn_map_message(tmap_file, preset))
    limits = ResidualLimits(**agent.meta.get("limits", {}))
    kind, _, config = base_planner(agent.meta.get("planner", "rule"))
    cls = AdaptivePPOController if kind == "adaptive" else PPOController
    ctrl = cls.for_env(env, TurnMap.load(tmap_file), config, limits=limits)
    ctrl.drive_with(agent)
    return ctrl
