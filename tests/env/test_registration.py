"""``import flagellum_env`` registers FlagellumSteer-v0; ``gymnasium.make`` then builds it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest
from gymnasium.envs import registration

import flagellum_env
from flagellum_env.steer_env import FlagellumSteerEnv

ROOT = Path(__file__).resolve().parents[2]


def test_import_registers_the_env_and_make_passes_arguments(small_kwargs):
    assert flagellum_env.ENV_ID == "FlagellumSteer-v0"
    assert "FlagellumSteer-v0" in gym.registry
    env = gym.make("FlagellumSteer-v0", **{**small_kwargs, "action_type": "discrete"})
    assert isinstance(env.unwrapped, FlagellumSteerEnv)
    assert env.action_space == gym.spaces.Discrete(3)
    env.close()


def _fresh_python(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          timeout=300, check=False)


@pytest.mark.skipif(hasattr(registration, "load_plugin_envs"), reason="this Gymnasium loads plugin entry points")
def test_without_a_prior_import_the_module_prefixed_id_works():
    # Gymnasium >= 1.0 has no plugin entry points; "module:EnvId" imports the module first
    r = _fresh_python("import gymnasium as gym, sys\n"
                      "assert 'flagellum_env' not in sys.modules\n"
                      "env = gym.make('flagellum_env:FlagellumSteer-v0', settle_time_s=2.0, control_dt=0.2,"
                      " path=[[0.002, 0, 0]])\n"
                      "print(type(env.unwrapped).__name__)")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "FlagellumSteerEnv"


@pytest.mark.skipif(not hasattr(registration, "load_plugin_envs"), reason="this Gymnasium has no plugin entry points")
def test_without_a_prior_import_the_plain_id_works():  # pragma: no cover - older Gymnasium only
    r = _fresh_python("import gymnasium as gym\n"
                      "print(type(gym.make('FlagellumSteer-v0', settle_time_s=2.0).unwrapped).__name__)")
    assert r.returncode == 0, r.stderr


def test_reimporting_does_not_register_twice():
    import importlib

    importlib.reload(flagellum_env)
    assert "FlagellumSteer-v0" in gym.registry
