"""Gymnasium's and stable-baselines3's env checkers pass for every action and observation type."""

from __future__ import annotations

import itertools
import warnings

import gymnasium as gym
import pytest
from gymnasium.utils.env_checker import check_env

import flagellum_env  # noqa: F401

COMBOS = list(itertools.product(["continuous", "discrete"], ["flat", "dict"]))


@pytest.mark.parametrize("action_type, observation_type", COMBOS)
def test_gymnasium_check_env_passes(small_kwargs, action_type, observation_type):
    # made through gymnasium.make so that the checker can also try the other render modes
    env = gym.make("FlagellumSteer-v0", action_type=action_type, observation_type=observation_type,
                   render_mode="rgb_array", disable_env_checker=True, **small_kwargs).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings count as failures
        check_env(env, skip_render_check=False)
    env.close()


@pytest.mark.parametrize("action_type, observation_type", COMBOS)
def test_stable_baselines3_check_env_passes(make_env, action_type, observation_type):
    sb3_env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = make_env(action_type=action_type, observation_type=observation_type)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_env_checker.check_env(env, warn=True)
