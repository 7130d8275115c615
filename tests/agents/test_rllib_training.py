"""Ray RLlib training (``agents.rllib_config``, ``agents.rllib_training``, ``agents.rllib_policy``, ``flagellum train
--engine ray``): the config's checks need no Ray; with Ray installed, a tiny local run on FlagellumTurn-surrogate-v0
checkpoints, resumes, refuses another config, and its checkpoint flies as a controller."""

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
    ({"env_id": "CartPole-v1"}, ["env_id='CartPole-v1'", "FlagellumTurn-surrogate-v0", "FlagellumSteer-v0"]),
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
