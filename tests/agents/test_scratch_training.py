"""Training from scratch on the burst design (task.design "burst", task.tier "surrogate"): the config's checks and a
short run on FlagellumBurst-surrogate-v0 that writes an agent, resumes and refuses another design."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agents.burst_design import N_BURST_ACTIONS, N_BURST_FEATURES
from agents.ppo_config import TrainConfig

PATHS = {"n_waypoints": 1, "segment_length_m": [0.05, 0.08], "min_turn_deg": 30.0, "max_turn_deg": 90.0}
TINY = {"scratch": {"n_envs": 2, "n_timesteps": 64, "seed": 0, "checkpoint_every": 32, "n_steps": 16,
                    "batch_size": 16, "n_epochs": 1, "policy_kwargs": {"net_arch": [8], "log_std_init": -0.5},
                    "task": {"design": "burst", "tier": "surrogate", "limits": {"cruise_max_s": 30.0},
                             "curriculum": [{"name": "one", "until": 64, "random_path": PATHS}],
                             "validation": {"seeds": [5, 6], "every": 32, "random_path": PATHS}}}}


def _with(task_changes=None, drop=()):
    doc = json.loads(json.dumps(TINY))
    doc["scratch"]["task"].update(task_changes or {})
    for k in drop:
        doc["scratch"]["task"].pop(k)
    return doc


@pytest.mark.parametrize("changes, fragment", [
    ({"design": "bursts"}, "task.design='bursts' is not allowed; allowed: ['residual', 'burst']"),
    ({"tier": "reduced"}, "task.tier='reduced' is not allowed; allowed: ['physics', 'surrogate']"),
    ({"planner": "adaptive"}, "design 'burst' has no planner and no action_cost"),
    ({"preset": "paper"}, "task.preset='paper' is not allowed with tier 'surrogate'"),
    ({"preset": "coarse"}, "preset 'coarse' was retired (slower than 'faithful' and wrong: it does not buckle"),
    ({"limits": {"t_c_max": 3.0}}, "t_c_max"),
    ({"limits": {"cruise_min_s": 0.0}}, "cruise_min_s"),
    ({"tier": "physics", "preset": "paper", "map_noise": {"direction_deg": 30, "turn_scale": 0.15}},
     "task.map_noise is only allowed with design 'burst' and tier 'surrogate'"),
    ({"map_noise": {"direction_deg": 30, "turn_scale": 1.5}}, "task.map_noise['turn_scale']=1.5 is not allowed"),
    ({"cheap_fraction": 0.5}, "task.cheap_fraction is only allowed with design 'burst' and tier 'physics'"),
    ({"tier": "physics", "cheap_fraction": 1.0}, "task.cheap_fraction=1.0 is not allowed; give a fraction in [0, 1)"),
    ({"tier": "physics", "cheap_fraction": "half"}, "task.cheap_fraction='half' is not allowed"),
    ({"map_noise": {"direction": 30, "turn_scale": 0.1}}, "task.map_noise={'direction': 30"),
])
def test_bad_scratch_settings_are_refused_naming_the_key(changes, fragment):
    with pytest.raises(ValueError) as err:
        TrainConfig.from_dict(_with(changes))
    assert fragment in str(err.value) and "\n" not in str(err.value)


def test_shipped_scratch_config_loads():
    cfg = TrainConfig.from_yaml("agents/configs/ppo_scratch_surrogate.yml")
    assert (cfg.design, cfg.tier, cfg.preset) == ("burst", "surrogate", "faithful")
    assert all(s < 1000 for s in cfg.validation.seeds)


def test_map_noise_is_refused_for_a_residual_task():
    doc = _with({"design": "residual", "tier": "surrogate", "limits": {},
                 "map_noise": {"direction_deg": 30, "turn_scale": 0.15}})
    with pytest.raises(ValueError, match="task.map_noise is only allowed with design 'burst'") as err:
        TrainConfig.from_dict(doc)
    assert "\n" not in str(err.value)


def test_map_noise_reaches_the_surrogate_env_and_meta_but_not_validation():
    import gymnasium as gym
    import yaml

    from agents.ppo_training import _make_env, agent_env, run_identity

    noise = {"direction_deg": 30, "turn_scale": 0.15}
    cfg = TrainConfig.from_dict(_with({"map_noise": noise}))
    assert cfg.map_noise == noise
    env_id, make_kwargs = agent_env(cfg)
    assert env_id == "FlagellumBurst-surrogate-v0" and make_kwargs["map_noise"] == noise
    assert run_identity(cfg)["map_noise"] == noise
    env = gym.make(env_id, **json.loads(json.dumps(make_kwargs))).unwrapped   # rebuilt from meta.json's record
    assert env.map_noise == (30.0, 0.15)
    assert _make_env(cfg, 0)().map_noise == (30.0, 0.15)
    assert _make_env(cfg, 0, cfg.validation.paths())().map_noise is None   # validation: the map as measured
    # without it: nothing recorded (agents trained before the key existed rebuild as they were)
    plain = TrainConfig.from_dict(_with())
    assert plain.map_noise is None and "map_noise" not in agent_env(plain)[1] and "map_noise" not in run_identity(plain)
    # stage 2 of the recipe randomises the map; stage 1 does not
    doc = yaml.safe_load(open("agents/configs/sac_scratch_randomized.yml", encoding="utf-8"))
    (name, body), = doc.items()
    body.pop("init_from")   # stage 1's agent, not in the repository
    assert TrainConfig.from_dict(doc).map_noise == {"direction_deg": 20, "turn_scale": 0.15}
    doc = yaml.safe_load(open("agents/configs/sac_scratch_surrogate.yml", encoding="utf-8"))
    assert TrainConfig.from_dict(doc).map_noise is None
    # every stage of the recipe ends its bursts by L'/L
    for stage in ("surrogate", "randomized", "faithful"):
        doc = yaml.safe_load(open(f"agents/configs/sac_scratch_{stage}.yml", encoding="utf-8"))
        (name, body), = doc.items()
        body.pop("init_from", None)
        assert TrainConfig.from_dict(doc).limits == {"burst_end": "ratio"}


def test_a_short_scratch_run_writes_an_agent_resumes_and_refuses_another_design(tmp_path):
    from stable_baselines3 import PPO

    from agents.ppo_training import agent_env, train

    out = tmp_path / "run"
    half = json.loads(json.dumps(TINY))
    half["scratch"]["n_timesteps"] = 32
    result = train(TrainConfig.from_dict(half), out, progress=False)
    assert result.decisions == 32
    meta = json.loads((out / "meta.json").read_text())
    assert (meta["mode"], meta["design"], meta["tier"]) == ("scratch", "burst", "surrogate")
    assert meta["env_id"] == "FlagellumBurst-surrogate-v0" and meta["make_kwargs"]["limits"]["cruise_max_s"] == 30.0
    assert agent_env(TrainConfig.from_dict(TINY)) == (meta["env_id"], meta["make_kwargs"])
    result = train(TrainConfig.from_dict(TINY), out, resume=True, progress=False)
    assert result.decisions == 64
    with np.load(out / "eval" / "evaluations.npz") as d:
        assert list(d["timesteps"]) == [32, 64]
    model = PPO.load(str(out / "model.zip"), device="cpu")
    assert model.action_space.shape == (N_BURST_ACTIONS,) and model.observation_space.shape == (N_BURST_FEATURES,)
    other = _with({"design": "residual", "tier": "physics", "preset": "paper"}, drop=("limits",))
    other["scratch"]["n_timesteps"] = 96
    with pytest.raises(ValueError, match="design"):
        train(TrainConfig.from_dict(other), out, resume=True, progress=False)


SAC_TINY = {"scratch_sac": {"algorithm": "sac", "n_envs": 1, "n_timesteps": 40, "seed": 0, "checkpoint_every": 20,
                            "learning_starts": 10, "batch_size": 8, "buffer_size": 1000,
                            "policy_kwargs": {"net_arch": [8]},
                            "task": {"design": "burst", "tier": "surrogate",
                                     "curriculum": [{"name": "one", "until": 40, "random_path": PATHS}],
                                     "validation": {"seeds": [5], "every": 20, "random_path": PATHS}}}}


def test_sac_settings_are_checked_against_the_algorithm():
    doc = json.loads(json.dumps(SAC_TINY))
    doc["scratch_sac"]["n_epochs"] = 3
    with pytest.raises(ValueError, match=r"\['n_epochs'\] are not sac arguments"):
        TrainConfig.from_dict(doc)
    doc = json.loads(json.dumps(SAC_TINY))
    doc["scratch_sac"]["algorithm"] = "td3"
    with pytest.raises(ValueError, match="algorithm='td3' is not allowed; allowed: \\['ppo', 'sac'\\]"):
        TrainConfig.from_dict(doc)
    doc = json.loads(json.dumps(SAC_TINY))
    doc["scratch_sac"]["ent_coef"] = "auto"
    assert TrainConfig.from_dict(doc).hyperparameters["ent_coef"] == "auto"


def test_a_sac_run_checkpoints_its_replay_buffer_and_resumes_with_it(tmp_path):
    from stable_baselines3 import SAC

    from agents.ppo_training import replay_buffer_file, train

    out = tmp_path / "sac"
    half = json.loads(json.dumps(SAC_TINY))
    half["scratch_sac"]["n_timesteps"] = 20
    assert train(TrainConfig.from_dict(half), out, progress=False).decisions == 20
    assert replay_buffer_file(out / "checkpoints", 20).is_file()
    assert train(TrainConfig.from_dict(SAC_TINY), out, resume=True, progress=False).decisions == 40
    model = SAC.load(str(out / "model.zip"), device="cpu")
    model.load_replay_buffer(str(replay_buffer_file(out / "checkpoints", 40)))
    assert model.replay_buffer.size() == 40   # the first session's 20 transitions came back with the resume
    meta = json.loads((out / "meta.json").read_text())
    assert meta["run"]["algorithm"] == "sac"
