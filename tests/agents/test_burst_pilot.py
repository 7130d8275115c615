"""The ``ppo-scratch`` controller (agents/burst_pilot.py): a burst agent flying FlagellumSteer-v0 one control step at a
time flies the episode FlagellumBurst-v0 flies with the same commands, reading from the observations alone what the
env reads from its base env; bad specs and folders are refused in one line.

Cheap on purpose: one 3.5 s burst at the default preset (~2 CPU s) on a two-waypoint path, flown twice.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import agents  # noqa: F401  (registers the ids)
from agents.burst_design import N_BURST_FEATURES
from agents.burst_pilot import BurstPilot, burst_agent_folder
from agents.path_following import env_settings, make_controller
from agents.ppo_policy import TrainedAgent, load_agent
from agents.turn_map import TurnMap
from agents.assets import default_turn_map
from flagellum_env.paths import path_from_waypoints
from flagellum_env.steer_env import FlagellumSteerEnv

ONE_TURN = path_from_waypoints([[0.12, 0.0, 0.0], [0.12, 0.15, 0.0]], name="one_turn", reach_radius_m=0.015)
#: cruise 4 s; burst 3.5 s at beta = pi/4 (85 deg), relax, cruise 12 s; cruise 2 s
COMMANDS = [np.array([-1.0, 1.0, 0.0, -0.9]), np.array([3.5 / 3.7, math.cos(math.pi / 4), math.sin(math.pi / 4), -0.7]),
            np.array([-1.0, 1.0, 0.0, -1.0])]


class _Scripted:
    """A stand-in for a trained model: the commands in turn, recording the observations it was shown."""

    observation_space = gym.spaces.Box(-10.0, 10.0, (N_BURST_FEATURES,), np.float32)

    def __init__(self) -> None:
        self.seen: list[np.ndarray] = []

    def predict(self, obs, deterministic=True):
        self.seen.append(np.array(obs))
        return COMMANDS[min(len(self.seen) - 1, len(COMMANDS) - 1)], None


def _scripted_agent(burst_end: str = "time") -> TrainedAgent:
    meta = {"mode": "scratch", "design": "burst", "make_kwargs": {"limits": {"burst_end": burst_end}}}
    return TrainedAgent(_Scripted(), None, 10.0, 1e-8, meta, Path("."))


@pytest.mark.parametrize("burst_end", ["time", "ratio"])
def test_the_pilot_flies_the_twin_envs_episode(burst_end):
    env = gym.make("FlagellumBurst-v0", paths=[ONE_TURN], limits={"burst_end": burst_end}).unwrapped
    obs, info = env.reset(seed=0)
    env_obs = [obs]
    for command in COMMANDS:
        obs, _, term, trunc, info = env.step(command)
        env_obs.append(obs)
        assert not (term or trunc)
    assert info["turns"] == 1

    assert env.last_burst["stopped_by"] == burst_end   # the 3.5 s burst: read by the clock when asked
    agent = _scripted_agent(burst_end)
    steer = FlagellumSteerEnv(path=ONE_TURN, **env_settings("ppo-scratch", "faithful"))
    pilot = BurstPilot.for_env(steer, agent, TurnMap.load(default_turn_map("faithful")))
    assert pilot.limits.burst_end == burst_end
    obs, step_info = steer.reset(seed=0, options={"path": ONE_TURN})
    cross = []
    while True:  # until the agent is asked for a fourth command: the three commands are flown
        action, _ = pilot.predict(obs)
        if len(agent.model.seen) > len(COMMANDS):
            break
        obs, _, term, trunc, step_info = steer.step(action)
        cross.append(step_info["cross_track_error_m"])
        assert not (term or trunc)
    assert len(pilot.turns) == 1
    assert step_info["sim_time_s"] == pytest.approx(info["time_s"], abs=1e-9)
    assert float(np.mean(cross)) == pytest.approx(info["mean_cross_track_m"], rel=1e-9)
    # what the agent was shown: the twin's observations, up to the float32 observations the pilot reckons from
    np.testing.assert_allclose(np.array(agent.model.seen), np.array(env_obs), atol=2e-5)


def test_specs_and_folders_are_checked(tmp_path):
    with pytest.raises(ValueError, match="nothing follows 'ppo-scratch:'"):
        make_controller("ppo-scratch:", None, "faithful")
    with pytest.raises(ValueError, match=r"no trained from-scratch agent at .*missing model.zip"):
        burst_agent_folder(str(tmp_path))
    for name in ("model.zip", "vecnormalize.pkl"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "meta.json").write_text(json.dumps({"mode": "residual", "planner": "adaptive"}))
    with pytest.raises(ValueError, match=r"mode 'residual' and design None; .*--controller ppo:DIR"):
        burst_agent_folder(str(tmp_path))
    (tmp_path / "meta.json").write_text(json.dumps({"mode": "scratch", "design": "burst"}))
    assert burst_agent_folder(str(tmp_path / "model.zip")) == tmp_path
    with pytest.raises(ValueError, match=f"--controller ppo-scratch:{tmp_path}"):
        load_agent(str(tmp_path))


def test_an_env_without_two_waypoints_is_refused():
    steer = FlagellumSteerEnv(path=ONE_TURN, **env_settings("ppo-scratch", "faithful", {"n_lookahead": 1}))
    with pytest.raises(ValueError, match="n_lookahead=2"):
        BurstPilot.for_env(steer, _scripted_agent(), TurnMap.load(default_turn_map("faithful")))


def test_the_shipped_agent_is_a_burst_agent():
    steer = FlagellumSteerEnv(path=ONE_TURN, **env_settings("ppo-scratch", "faithful"))
    pilot = make_controller("ppo-scratch", steer, "faithful")
    assert pilot.agent.model.observation_space.shape == (N_BURST_FEATURES,)
    obs, _ = steer.reset(seed=0)
    action, _ = pilot.predict(obs)
    assert steer.action_space.contains(action)
