"""The shipped agent carries its env: ``meta.json``'s ``env_id`` and ``make_kwargs`` rebuild it with plain
Gymnasium and stable-baselines3 (no project loader), and they are what its training config trains on."""

from __future__ import annotations

import dataclasses
import json

import gymnasium as gym
import numpy as np
import pytest
import yaml

import agents  # noqa: F401  (registers the FlagellumTurn ids)
from agents.assets import pretrained_dir
from agents.ppo_config import TrainConfig
from agents.residual_planner import N_ADAPTIVE_FEATURES, ResidualLimits
from flagellum_env.paths import path_from_waypoints

ONE_TURN = path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], name="one_turn", reach_radius_m=0.015)


def _meta() -> dict:
    return json.loads((pretrained_dir() / "meta.json").read_text(encoding="utf-8"))


def test_the_stored_env_is_the_one_its_config_trains_on():
    pytest.importorskip("stable_baselines3")
    from agents.ppo_training import agent_env

    meta = _meta()
    env_id, kwargs = agent_env(TrainConfig.from_yaml(pretrained_dir() / "config.yml"))
    assert (env_id, json.loads(json.dumps(kwargs))) == (meta["env_id"], meta["make_kwargs"])


def test_the_stored_arguments_build_the_env_the_agent_was_trained_on():
    """Its preset, planner, limits, price of an action, randomised swimmers and the last stage's paths."""
    meta = _meta()
    doc = yaml.safe_load((pretrained_dir() / "config.yml").read_text())
    (task,) = [v["task"] for v in doc.values()]
    env = gym.make(meta["env_id"], **meta["make_kwargs"]).unwrapped
    assert env.preset == meta["preset"] == task["preset"] == "faithful"
    assert type(env.planner).__name__ == "AdaptiveResidualPlanner" and meta["planner"] == task["planner"]
    assert dataclasses.asdict(env.planner.limits) == meta["limits"] == task["limits"]
    assert env.action_cost == meta["action_cost"] == task["action_cost"]
    assert env.observation_space.shape == (N_ADAPTIVE_FEATURES,)
    r = task["env_kwargs"]["randomize"]
    assert env.base.config.randomize.youngs_modulus == r["youngs_modulus"] > 0
    assert meta["make_kwargs"]["random_path"] == task["curriculum"][-1]["random_path"]
    assert [c.planar for c in env._path_configs] == [True, False]


def test_plain_stable_baselines3_loads_the_agent_on_its_env():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    folder, meta = pretrained_dir(), _meta()
    venv = make_vec_env(meta["env_id"], n_envs=1, env_kwargs=meta["make_kwargs"])
    venv = VecNormalize.load(str(folder / "vecnormalize.pkl"), venv)
    venv.training, venv.norm_reward = False, False
    model = PPO.load(str(folder / "model.zip"), env=venv, device="cpu")
    assert model.observation_space == venv.observation_space and model.action_space == venv.action_space
    venv.set_options({"path": ONE_TURN})  # a short path: the first turn is planned after 2 cm
    obs = venv.reset()
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (1, 2) and np.all(np.abs(action) <= 1.0)
    assert ResidualLimits(**meta["limits"]) == venv.get_attr("planner")[0].limits
    venv.close()
