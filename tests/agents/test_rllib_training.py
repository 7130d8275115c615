"""Ray RLlib training (``agents.rllib_config``, ``agents.rllib_training``, ``agents.rllib_policy``, ``flagellum train
--engine ray``): the config's checks need no Ray; with Ray installed, a tiny local run on FlagellumTurn-surrogate-v0
checkpoints, resumes, refuses another config, and its checkpoint flies as a controller; a tiny run on
FlagellumBurst-surrogate-v0 flies as a BurstPilot, and a burst checkpoint of another observation size is refused."""

from __future__ import annotations

import csv
import socket
from pathlib import Path

import numpy as np
import pytest

from agents.rllib_config import RayTrainConfig

GOOD = {"env_id": "FlagellumTurn-surrogate-v0", "iterations": 2}


def _config(**changes) -> dict:
    return {"run": {**GOOD, **changes}}


@pytest.mark.parametrize("changes, fragments", [
    ({"no_such_key": 1}, ["unknown key(s) ['no_such_key']", "allowed", "env_id"]),
    ({"env_id": "CartPole-v1"}, ["env_id='CartPole-v1'", "FlagellumTurn-surrogate-v0", "FlagellumSteer-v0",
                                 "FlagellumBurst-surrogate-v0"]),
    ({"env_id": None}, ["env_id=None", "allowed"]),
    ({"address": "nowhere"}, ["address='nowhere'", "'auto'", "host:port"]),
    ({"address": "localhost:99999"}, ["address='localhost:99999'", "host:port"]),
    ({"num_env_runners": -1}, ["num_env_runners=-1", ">= 0"]),
    ({"train_batch_size": 0}, ["train_batch_size=0", ">= 1"]),
    ({"minibatch_size": 500, "train_batch_size": 100}, ["minibatch_size=500", "train_batch_size (100)"]),
    ({"lr": 0}, ["lr=0", "> 0"]),
    ({"gamma": 1.5}, ["gamma=1.5", "<= 1"]),
    ({"iterations": None}, ["iterations and max_wall_time_s", "at least one"]),
    ({"max_wall_time_s": -5}, ["max_wall_time_s=-5", "seconds"]),
    ({"net_arch": [64, 0]}, ["net_arch=[64, 0]", "layer sizes"]),
    ({"normalize_obs": "yes"}, ["normalize_obs='yes'", "true or false"]),
    ({"env_kwargs": [1, 2]}, ["env_kwargs=[1, 2]", "mapping"]),
    ({"checkpoint_every": 1.5}, ["checkpoint_every=1.5", "integer"]),
])
def test_a_bad_config_is_one_line_naming_the_value(changes, fragments):
    with pytest.raises(ValueError) as info:
        RayTrainConfig.from_dict(_config(**changes), source="c.yml")
    msg = str(info.value)
    assert "\n" not in msg and "'c.yml'" in msg
    for frag in fragments:
        assert frag in msg, msg


def test_the_shipped_config_is_valid_and_its_identity_ignores_the_budget_and_where_it_runs():
    from agents.assets import package_file

    config = RayTrainConfig.from_yaml(package_file("configs", "rllib_ppo_surrogate.yml"))
    assert config.env_id == "FlagellumTurn-surrogate-v0" and config.address is None
    more = RayTrainConfig.from_dict({config.name: {**_as_dict(config), "iterations": 7, "num_env_runners": 5,
                                                   "address": "auto", "max_wall_time_s": 10}})
    assert more.identity_hash() == config.identity_hash()
    other = RayTrainConfig.from_dict({config.name: {**_as_dict(config), "lr": config.lr / 2}})
    assert other.identity_hash() != config.identity_hash()
    with pytest.raises(ValueError, match="--address='x y'"):
        config.with_address("x y")


def test_the_burst_ids_pass_the_config_check_and_the_shipped_burst_config_is_valid():
    from agents.assets import package_file
    from agents.registration import BURST_ENV_IDS
    from agents.rllib_config import rllib_controller_env_ids, rllib_env_ids

    assert set(BURST_ENV_IDS) <= set(rllib_env_ids()) and set(BURST_ENV_IDS) <= set(rllib_controller_env_ids())
    for env_id in BURST_ENV_IDS:
        assert RayTrainConfig.from_dict(_config(env_id=env_id)).env_id == env_id
    config = RayTrainConfig.from_yaml(package_file("configs", "rllib_ppo_burst_surrogate.yml"))
    assert config.env_id == "FlagellumBurst-surrogate-v0" and config.iterations and config.train_batch_size == 4000
    assert set(config.env_kwargs) == {"env_kwargs", "random_path", "limits"}


def _as_dict(config: RayTrainConfig) -> dict:
    from agents.rllib_config import DEFAULTS

    return {k: list(v) if isinstance(v, tuple) else v for k in DEFAULTS if (v := getattr(config, k)) is not None}


def test_a_config_file_that_cannot_be_read_names_the_file(tmp_path):
    with pytest.raises(ValueError, match="cannot read the training config"):
        RayTrainConfig.from_yaml(tmp_path / "missing.yml")


# --- with Ray ---------------------------------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_address_where_no_ray_answers_is_refused_at_once():
    pytest.importorskip("ray")
    from agents.rllib_training import check_address

    address = f"127.0.0.1:{_free_port()}"
    with pytest.raises(ValueError) as info:
        check_address(address, timeout_s=1.0)
    assert address in str(info.value) and "\n" not in str(info.value)


def test_cli_refuses_a_bad_ray_config_and_a_dead_address_before_writing(usage_error, tmp_path):
    pytest.importorskip("ray")
    cfg = tmp_path / "c.yml"
    cfg.write_text("run: {env_id: FlagellumTurn-surrogate-v0, iterations: 1, lr: fast}\n")
    line = usage_error(["train", "--engine", "ray", "--config", str(cfg), "--out", str(tmp_path / "o")])
    assert "lr='fast'" in line and str(cfg) in line
    cfg.write_text("run: {env_id: FlagellumTurn-surrogate-v0, iterations: 1}\n")
    address = f"127.0.0.1:{_free_port()}"
    line = usage_error(["train", "--engine", "ray", "--config", str(cfg), "--out", str(tmp_path / "o"),
                        "--address", address])
    assert address in line
    assert not (tmp_path / "o" / "checkpoints").exists()
    line = usage_error(["train", "--engine", "ray", "--config", str(cfg), "--out", str(tmp_path / "o"),
                        "--preset", "paper"])
    assert "--preset paper" in line and "env_kwargs" in line


def test_a_tiny_local_run_checkpoints_resumes_and_flies_as_a_controller(tmp_path):
    pytest.importorskip("ray")
    import gymnasium as gym

    from agents.path_following import env_settings, make_controller
    from agents.rllib_policy import load_rllib_agent
    from agents.rllib_training import checkpoint_info, checkpoints, train

    tiny = {"env_id": "FlagellumTurn-surrogate-v0", "num_env_runners": 1, "train_batch_size": 64,
            "minibatch_size": 32, "num_epochs": 1, "net_arch": [8], "checkpoint_every": 1, "iterations": 1}
    out = tmp_path / "run"
    first = train(RayTrainConfig.from_dict({"tiny": tiny}), out, progress=False)
    assert first.iterations == 1 and first.env_steps >= 64 and not first.interrupted
    with pytest.raises(ValueError, match="already holds a training run"):
        train(RayTrainConfig.from_dict({"tiny": tiny}), out, progress=False)
    with pytest.raises(ValueError) as info:  # another config: refused before Ray starts
        train(RayTrainConfig.from_dict({"tiny": {**tiny, "iterations": 2, "lr": 1e-3}}), out, resume=True)
    assert "lr is 0.0003 there and 0.001 here" in str(info.value)

    second = train(RayTrainConfig.from_dict({"tiny": {**tiny, "iterations": 2}}), out, resume=True, progress=False)
    assert second.iterations == 2 and second.env_steps >= 2 * 64 and second.wall_time_s > first.wall_time_s
    assert [checkpoint_info(c)["iteration"] for c in checkpoints(out)] == [1, 2]
    with open(out / "progress.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["iteration"]) for r in rows] == [1, 2]
    assert int(rows[1]["env_steps"]) == second.env_steps and float(rows[1]["cpu_s"]) > float(rows[0]["cpu_s"])
    assert all(0.0 <= float(r["success_rate"]) <= 1.0 for r in rows if r["success_rate"])

    # the checkpoint on its own env, one episode, deterministic
    agent = load_rllib_agent(str(out), 14, "rule")
    assert agent.folder == checkpoints(out)[-1] and agent.obs_filter is not None
    env = gym.make("FlagellumTurn-surrogate-v0")
    obs, _ = env.reset(seed=0)
    done, steps = False, 0
    while not done:
        action = agent.act(obs)
        assert action.shape == (2,) and np.all(np.abs(action) <= 1.0)
        assert np.array_equal(action, agent.act(obs))  # the mean: deterministic
        obs, _, terminated, truncated, _ = env.step(action)
        done, steps = terminated or truncated, steps + 1
    assert steps >= 1
    # ... and as a controller of FlagellumSteer (the planner corrected by it), as the ppo controller is built
    spec = f"rllib:{out}"
    steer = gym.make("FlagellumSteer-v0", **{k: v for k, v in env_settings(spec, "faithful").items()
                                              if k != "preset"})
    ctrl = make_controller(spec, steer, "faithful")
    assert ctrl.agent.folder == agent.folder
    features = np.zeros(14, dtype=np.float32)
    assert np.array_equal(ctrl.policy(features), agent.act(features))
    with pytest.raises(ValueError) as info:  # another observation size
        load_rllib_agent(str(out), 20, "adaptive")
    assert "(14,)" in str(info.value) and "(20,)" in str(info.value) and "FlagellumTurn-surrogate-v0" in str(info.value)


def test_a_folder_without_a_checkpoint_is_not_a_controller(tmp_path):
    from agents.controller_spec import controller_kind

    with pytest.raises(ValueError, match="'rllib' has no default"):
        controller_kind("rllib")
    pytest.importorskip("ray")
    from agents.rllib_policy import checkpoint_folder

    with pytest.raises(ValueError, match="no RLlib checkpoint"):
        checkpoint_folder(str(tmp_path))


# --- burst agents ------------------------------------------------------------------------------------------------
#: Not the default limits: the pilot must read them from the checkpoint.
BURST_LIMITS = {"t_c_max_s": 3.5, "cruise_min_s": 2.0, "cruise_max_s": 30.0, "burst_end": "time"}


@pytest.fixture(scope="module")
def burst_run(tmp_path_factory) -> Path:
    """A tiny local run on FlagellumBurst-surrogate-v0 (no env runner actor, one iteration of 64 decisions)."""
    pytest.importorskip("ray")
    from agents.rllib_training import train

    tiny = {"env_id": "FlagellumBurst-surrogate-v0", "env_kwargs": {"limits": BURST_LIMITS}, "num_env_runners": 0,
            "train_batch_size": 64, "minibatch_size": 32, "num_epochs": 1, "net_arch": [8], "iterations": 1}
    out = tmp_path_factory.mktemp("burst") / "run"
    result = train(RayTrainConfig.from_dict({"tiny_burst": tiny}), out, progress=False)
    assert result.iterations == 1 and result.env_steps >= 64 and result.checkpoint is not None
    return out


def test_a_bad_burst_env_argument_is_refused_before_ray_starts(tmp_path):
    pytest.importorskip("ray")
    from agents.rllib_training import train

    bad = {"env_id": "FlagellumBurst-surrogate-v0", "env_kwargs": {"limits": {"t_c_max_s": -1.0}}, "iterations": 1}
    with pytest.raises(ValueError) as info:
        train(RayTrainConfig.from_dict({"bad": bad}), tmp_path / "o", progress=False)
    assert "t_c_max_s=-1.0" in str(info.value) and "\n" not in str(info.value)
    assert not (tmp_path / "o").exists()


def test_a_tiny_burst_run_flies_as_a_burst_pilot(burst_run):
    from agents.burst_design import N_BURST_FEATURES, BurstLimits
    from agents.burst_pilot import BurstPilot
    from agents.path_following import env_settings, make_controller
    from agents.rllib_policy import RLlibAgent, load_rllib_agent
    from agents.rllib_training import checkpoint_info, checkpoints
    from flagellum_env.steer_env import FlagellumSteerEnv

    info = checkpoint_info(checkpoints(burst_run)[-1])
    assert info["env_id"] == "FlagellumBurst-surrogate-v0" and info["env_kwargs"] == {"limits": BURST_LIMITS}
    assert info["observation_shape"] == [N_BURST_FEATURES] and info["action_shape"] == [4]

    spec = f"rllib:{burst_run}"
    steer = FlagellumSteerEnv(**env_settings(spec, "faithful"))  # the random path of seed 0
    pilot = make_controller(spec, steer, "faithful")
    assert isinstance(pilot, BurstPilot) and isinstance(pilot.agent, RLlibAgent)
    assert pilot.limits == BurstLimits(**BURST_LIMITS)
    agent = load_rllib_agent(str(burst_run), N_BURST_FEATURES)
    features = np.linspace(-1.0, 1.0, N_BURST_FEATURES, dtype=np.float32)
    assert np.array_equal(pilot.agent.act(features), agent.act(features))

    asked: list[np.ndarray] = []
    rllib_agent = pilot.agent

    class _Recording:
        def act(self, features: np.ndarray, deterministic: bool = True) -> np.ndarray:
            asked.append(np.array(features))
            return rllib_agent.act(features, deterministic)

    pilot.agent = _Recording()
    obs, _ = steer.reset(seed=0)
    for _ in range(80):  # 8 s: the heading measured over a wobble period (5.5 s), then the agent's first command
        action, _ = pilot.predict(obs)
        assert steer.action_space.contains(action)
        obs, _, terminated, truncated, _ = steer.step(action)
        assert not (terminated or truncated)
        if asked:
            break
    assert len(asked) == 1 and asked[0].shape == (N_BURST_FEATURES,)


def test_a_burst_checkpoint_of_another_observation_size_or_a_steer_checkpoint_is_refused(burst_run, tmp_path):
    import json
    import shutil

    from agents.path_following import env_settings, make_controller
    from agents.rllib_policy import load_rllib_agent
    from agents.rllib_training import checkpoints
    from flagellum_env.steer_env import FlagellumSteerEnv

    copy = tmp_path / "ckpt"
    shutil.copytree(checkpoints(burst_run)[-1], copy)
    info_file = copy / "flagellum.json"
    info = json.loads(info_file.read_text())
    info_file.write_text(json.dumps({**info, "observation_shape": [35]}))
    spec = f"rllib:{copy}"
    steer = FlagellumSteerEnv(**env_settings(spec, "faithful"))
    with pytest.raises(ValueError) as refused:
        make_controller(spec, steer, "faithful")
    msg = str(refused.value)
    assert "\n" not in msg and "(35,)" in msg and "(43,)" in msg and "retrain it" in msg, msg

    info_file.write_text(json.dumps({**info, "env_id": "FlagellumSteer-v0"}))
    with pytest.raises(ValueError) as refused:
        load_rllib_agent(str(copy))
    msg = str(refused.value)
    assert "\n" not in msg and "'FlagellumSteer-v0'" in msg and "FlagellumBurst-surrogate-v0" in msg, msg
