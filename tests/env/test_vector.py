"""The env runs in parallel: Gymnasium's async vector env and stable-baselines3's SubprocVecEnv."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import flagellum_env  # noqa: F401
from flagellum_env.steer_env import FlagellumSteerEnv


def test_gymnasium_async_vector_env_runs(small_kwargs):
    envs = gym.make_vec("FlagellumSteer-v0", num_envs=2, vectorization_mode="async", **small_kwargs)
    try:
        obs, infos = envs.reset(seed=[0, 1])
        assert obs.shape == (2, envs.single_observation_space.shape[0])
        for _ in range(25):  # long enough for episodes to end and auto-reset
            obs, rewards, _, _, infos = envs.step(envs.action_space.sample())
        assert obs.shape[0] == 2 and rewards.shape == (2,)
        assert "is_success" in infos and "cross_track_error_m" in infos
    finally:
        envs.close()


class _Make:
    """Picklable env factory for subprocesses."""

    def __init__(self, kwargs: dict) -> None:
        self.kwargs = kwargs

    def __call__(self) -> FlagellumSteerEnv:
        return FlagellumSteerEnv(**self.kwargs)


def test_stable_baselines3_subproc_vec_env_runs(small_kwargs):
    vec_env = pytest.importorskip("stable_baselines3.common.vec_env")
    envs = vec_env.SubprocVecEnv([_Make(small_kwargs), _Make(small_kwargs)])
    try:
        envs.seed(0)
        obs = envs.reset()
        assert obs.shape == (2, envs.observation_space.shape[0])
        for _ in range(25):
            obs, _, _, infos = envs.step(np.array([envs.action_space.sample() for _ in range(2)]))
        assert len(infos) == 2 and "is_success" in infos[0]
    finally:
        envs.close()
