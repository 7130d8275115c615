"""Every id the env layer registers (``flagellum_env.registration``): its class, preset, time limit and render
rate, and both env checkers (Gymnasium's and stable-baselines3's) on ``gymnasium.make`` of it. The turn-level ids
of ``agents`` are tested in tests/agents/test_turn_env_registration.py.

Cheap on purpose: the small configuration (tests/env/conftest.py: 0.2 s steps, a 6 mm path, no buckling) at each
id's own preset (the physics is not the point: the id's class, validation and spaces are). The retired ids
(``RETIRED_ENV_IDS``) are registered only to be refused with a one-line message naming the replacement.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import pytest
from gymnasium.utils.env_checker import check_env

import flagellum_env
from flagellum_env.config import SteerConfig
from flagellum_env.paths import RandomPathConfig
from flagellum_env.registration import ENV_IDS, RETIRED_ENV_IDS, steer_max_episode_steps

ROOT = Path(__file__).resolve().parents[2]
PRESET = {"FlagellumSteer-v0": "faithful", "FlagellumSteer-fast-v0": "fast"}


def cheap_kwargs(env_id: str, small: dict) -> dict:
    return {k: v for k, v in small.items() if k != "preset"}  # the id's own preset


def test_every_id_of_the_env_layer_is_registered_with_its_class_and_time_limit():
    ours = sorted(i for i in gym.registry if i.startswith("FlagellumSteer"))
    assert ours == sorted([*ENV_IDS, *RETIRED_ENV_IDS]) and sorted(ENV_IDS) == sorted(PRESET)
    assert sorted(RETIRED_ENV_IDS) == ["FlagellumSteer-coarse-v0"]
    for env_id, (entry_point, max_steps) in ENV_IDS.items():
        spec = gym.spec(env_id)
        assert spec.entry_point == entry_point and spec.max_episode_steps == max_steps == 400
        assert entry_point.startswith("flagellum_env.")


def test_the_registered_time_limit_is_the_largest_budget_of_the_default_random_paths():
    cfg, rp = SteerConfig(), RandomPathConfig()
    bound = steer_max_episode_steps(cfg.control_dt, cfg.time_factor, rp.n_waypoints * rp.segment_length_m[1])
    assert bound == steer_max_episode_steps() == gym.spec("FlagellumSteer-v0").max_episode_steps == 400
    # v0 at 10 rpm: 4.68e-4 m/s with the head counter-rotating (the slowest reading; 7.1e-4 with the default):
    # the longest default path's budget, 385 steps, fits
    assert cfg.time_factor * 0.24 / 4.68e-4 / cfg.control_dt < bound


@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
def test_make_gives_the_ids_class_and_preset(env_id):
    env = gym.make(env_id).unwrapped
    assert type(env).env_id == env_id
    assert env.config.preset == PRESET[env_id]
    env.close()


@pytest.mark.parametrize("env_id, preset, why", [
    ("FlagellumSteer-coarse-v0", "coarse", "slower than 'faithful' and wrong: it does not buckle")])
def test_a_retired_id_is_refused_on_one_line_naming_the_replacement(env_id, preset, why, small_kwargs):
    for kwargs in ({}, small_kwargs):
        with pytest.raises(ValueError) as err:
            gym.make(env_id, **kwargs)
        assert str(err.value) == (
            f"{env_id} was retired with its preset (use FlagellumSteer-v0): preset {preset!r} was retired ({why}; "
            "docs/presets.md); use 'faithful' (the default), or FlagellumTurn-surrogate-v0 / "
            "FlagellumBurst-surrogate-v0 for a cheap turn-level swimmer")
    with pytest.raises(ValueError, match=f"^preset {preset!r} was retired"):
        gym.make("FlagellumSteer-v0", preset=preset)


def test_render_fps_follows_control_dt(small_kwargs):
    for dt, fps in ((2.0, 4.0), (0.2, 40.0)):
        env = gym.make("FlagellumSteer-v0", **{**small_kwargs, "control_dt": dt})
        assert env.metadata["render_fps"] == env.unwrapped.metadata["render_fps"] == fps
        env.close()


def test_the_env_warns_when_the_registered_time_limit_would_cut_its_budget(small_kwargs):
    kwargs = {**small_kwargs, "max_sim_time_s": 100.0}  # 500 steps of 0.2 s > 400
    env = gym.make("FlagellumSteer-v0", **kwargs)
    with pytest.warns(UserWarning, match="max_episode_steps=400"):
        env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=1)  # once per env
        # made without gymnasium.make (no TimeLimit): nothing to warn about
        flagellum_env.FlagellumSteerEnv(**kwargs).reset(seed=0)
    env.close()


@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
def test_gymnasium_check_env_passes(env_id, small_kwargs):
    env = gym.make(env_id, render_mode="rgb_array", disable_env_checker=True,
                   **cheap_kwargs(env_id, small_kwargs)).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings count as failures
        check_env(env, skip_render_check=False)
    env.close()


@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
def test_stable_baselines3_check_env_passes(env_id, small_kwargs):
    sb3_env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, render_mode="rgb_array", **cheap_kwargs(env_id, small_kwargs))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_env_checker.check_env(env, warn=True)
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3
    env.close()


def _fresh_python(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300,
                          check=False)


def test_import_flagellum_env_registers_its_ids_and_imports_no_agent_code():
    r = _fresh_python("import sys, gymnasium as gym, flagellum_env\n"
                      "print(sorted(i for i in gym.registry if i.startswith('Flagellum')))\n"
                      "print(sorted(m for m in sys.modules if m.split('.')[0] in ('agents', 'physics', 'flagellum')))")
    assert r.returncode == 0, r.stderr
    ids, modules = r.stdout.strip().splitlines()
    assert ids == str(sorted([*ENV_IDS, *RETIRED_ENV_IDS])) and modules == "[]"


def test_a_spawned_subprocvecenv_worker_finds_the_id_through_the_module_prefix(small_kwargs):
    sb3 = pytest.importorskip("stable_baselines3.common.env_util")
    from stable_baselines3.common.vec_env import SubprocVecEnv

    kwargs = cheap_kwargs("FlagellumSteer-v0", small_kwargs)
    venv = sb3.make_vec_env("flagellum_env:FlagellumSteer-v0", n_envs=1, env_kwargs=kwargs,
                            vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": "spawn"})
    try:
        assert venv.reset().shape == (1, *venv.observation_space.shape)
    finally:
        venv.close()
