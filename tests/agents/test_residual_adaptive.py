"""The residual policy on the adaptive planner (agents/residual_planner.py: AdaptiveResidualPlanner,
corrected_adaptive_plan, map_features) and FlagellumTurn-v0 with planner="adaptive"."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import agents  # noqa: F401  (registers the FlagellumTurn ids)
from agents.assets import default_turn_map
from agents.adaptive_planner import AdaptivePlanner
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap
from agents.residual_planner import (N_ADAPTIVE_FEATURES, N_FEATURES, N_MAP_FEATURES, AdaptiveResidualPlanner,
                                     ResidualLimits, corrected_adaptive_plan, map_features)
from agents.turn_map import TurnMap
from flagellum_env.steer_env import FlagellumSteerEnv

#: a frozen turn map (faithful preset, 150 rpm bursts, torque-free head): the numbers below were read off it
MAP_150_RPM = Path(__file__).parent / "data" / "turn_map_150rpm.json"

ONE_TURN = [[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]]


@pytest.fixture(scope="module")
def tmap() -> TurnMap:
    """The default swimmer's shipped map (the episodes fly the default swimmer)."""
    return TurnMap.load(default_turn_map("faithful"))


@pytest.fixture(scope="module")
def frozen_map() -> TurnMap:
    return TurnMap.load(MAP_150_RPM)


def _episode(planner_cls, tmap, params=None, **kwargs):
    """One episode on the one-turn path: (actions, turns, info)."""
    env = FlagellumSteerEnv(path=ONE_TURN, control_dt=0.1, reach_radius_m=0.015, **(params or {}))
    planner = planner_cls.for_env(env, tmap, **kwargs)
    obs, _ = env.reset(seed=0)
    planner.reset()
    actions, start, done, info = [], True, False, {}
    while not done:
        act, _ = planner.predict(obs, episode_start=np.array([start]))
        start = False
        actions.append(float(np.asarray(act).reshape(-1)[0]))
        obs, _, term, trunc, info = env.step(act)
        done = term or trunc
    turns = planner._episodes[0].turns
    env.close()
    return actions, turns, info


def test_with_zero_corrections_it_flies_the_adaptive_planners_episode(tmap):
    a_ref, t_ref, i_ref = _episode(AdaptivePlanner, tmap)
    a, t, i = _episode(AdaptiveResidualPlanner, tmap, policy=lambda f: np.zeros(2))
    assert i_ref["is_success"] and t_ref
    assert a == a_ref and len(t) == len(t_ref)
    assert [x["t_c"] for x in t] == [x["t_c"] for x in t_ref]


def test_unmatched_swimmer_zero_corrections_keep_the_corrected_maps_plan(tmap):
    online = OnlineMapConfig(cruise_match_tol=0.0)  # never matched: turns chosen on the corrected map
    a_ref, t_ref, _ = _episode(AdaptivePlanner, tmap, online=online)
    a, t, _ = _episode(AdaptiveResidualPlanner, tmap, online=online, policy=lambda f: np.zeros(2))
    assert t_ref and not t_ref[0].get("follows_model")
    assert a == a_ref
    for x, y in zip(t, t_ref):
        assert x["t_c"] == y["t_c"] and x["map_t"] == pytest.approx(y["map_t"], abs=1e-12)
        assert x["theta_deg"] == pytest.approx(y["theta_deg"], abs=1e-9)


def test_features_carry_the_online_maps_state(tmap):
    seen = []

    def policy(f):
        seen.append(np.array(f))
        return np.zeros(2)

    _episode(AdaptiveResidualPlanner, tmap, online=OnlineMapConfig(cruise_match_tol=0.0), policy=policy)
    assert seen and all(f.shape == (N_ADAPTIVE_FEATURES,) and f.dtype == np.float32 for f in seen)
    assert all(np.all(np.isfinite(f)) for f in seen)
    m = seen[0][N_FEATURES:]
    assert m.shape == (N_MAP_FEATURES,)
    prior = OnlineTurnMap(tmap, OnlineMapConfig(cruise_match_tol=0.0))
    assert m[1] == pytest.approx(prior.shift_std_s, rel=1e-6) or m[1] < prior.shift_std_s  # a cruise may narrow it
    assert m[4] == 0.0  # not following the model: the cruise was not matched


def test_a_correction_moves_the_burst_and_its_map_timing_together(frozen_map):
    tmap = frozen_map
    online = OnlineTurnMap(tmap, OnlineMapConfig())
    online.shift_s, online.bias_s = 0.4, 0.1
    t_c = 6.0  # past the first L'/L the map records (4.9 s): the burst is flown by the ratio clock
    theta, psi = online.turn_at(t_c + online.shift_s)
    plan = {"t_c": t_c, "theta_deg": math.degrees(theta), "burst_phase": 0.3,
            "predicted_azimuth": 0.3 + psi, "heading": [1.0, 0.0, 0.0], **online.burst_plan(t_c)}
    limits = ResidualLimits(max_dtc_fraction=0.1, max_dphase_deg=20.0)
    out = corrected_adaptive_plan(plan, np.array([0.5, -1.0]), online, tmap, limits)
    assert out["t_c"] == pytest.approx(t_c * 1.05)
    assert out["map_t"] == pytest.approx(out["t_c"] + 0.4)
    assert out["clock_map_t"] == pytest.approx(out["map_t"] - 0.1)
    theta2, psi2 = online.turn_at(out["map_t"])
    assert out["theta_deg"] == pytest.approx(math.degrees(theta2))
    assert out["burst_phase"] == pytest.approx(0.3 - math.radians(20.0))
    assert math.cos(out["predicted_azimuth"] - (out["burst_phase"] + psi2)) == pytest.approx(1.0)
    # the paper's rule (the map's own swimmer): the rule's timing, the map's turn at the corrected burst
    rule = corrected_adaptive_plan({**plan, "follows_model": True}, np.array([0.5, 0.0]), online, tmap, limits)
    assert rule["map_t"] == plan["map_t"] and rule["theta_deg"] == rule["predicted_theta_deg"]


def test_map_features_are_bounded_and_finite(tmap):
    online = OnlineTurnMap(tmap, OnlineMapConfig())
    online.shift_s = math.inf
    f = map_features(online)
    assert f.shape == (N_MAP_FEATURES,) and np.all(np.abs(f) <= 10.0)


def test_turn_env_with_the_adaptive_planner():
    env = gym.make("FlagellumTurn-v0", paths=[ONE_TURN], planner="adaptive")
    assert env.observation_space.shape == (N_ADAPTIVE_FEATURES,)
    obs, info = env.reset(seed=0)
    assert obs.shape == (N_ADAPTIVE_FEATURES,) and np.any(obs != 0.0)  # a turn is waiting
    obs, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
    assert math.isfinite(reward) and info["turns"] == 1
    env.close()
    with pytest.raises(ValueError, match="planner='best'"):
        gym.make("FlagellumTurn-v0", planner="best")


SHORT_TURN = {"n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}
TINY_ADAPTIVE = {"tiny_adaptive": {
    "n_envs": 1, "n_timesteps": 3, "seed": 0, "checkpoint_every": 3, "n_steps": 3, "batch_size": 3, "n_epochs": 1,
    "policy_kwargs": {"net_arch": [8], "log_std_init": -1.0},
    "task": {"preset": "faithful", "planner": "adaptive",
             "curriculum": [{"name": "one", "until": 3, "random_path": SHORT_TURN}],
             "validation": {"seeds": [5], "every": 3, "random_path": SHORT_TURN}}}}


def test_an_agent_trained_on_the_adaptive_planner_drives_it(tmp_path):
    import json

    from agents.path_following import make_controller
    from agents.ppo_config import TrainConfig
    from agents.ppo_policy import AdaptivePPOController, load_agent
    from agents.ppo_training import train

    out = tmp_path / "run"
    result = train(TrainConfig.from_dict(TINY_ADAPTIVE), out, progress=False)
    assert result.decisions == 3
    meta = json.loads((out / "meta.json").read_text())
    assert meta["planner"] == "adaptive" and meta["make_kwargs"]["planner"] == "adaptive"
    agent = load_agent(str(out))
    assert agent.act(np.zeros(N_ADAPTIVE_FEATURES, np.float32)).shape == (2,)
    env = FlagellumSteerEnv(path=ONE_TURN, control_dt=0.1, reach_radius_m=0.015)
    ctrl = make_controller(f"ppo:{out}", env, "faithful")
    assert isinstance(ctrl, AdaptivePPOController)
    env.close()
    bad = json.loads(json.dumps(TINY_ADAPTIVE))
    bad["tiny_adaptive"]["task"]["planner"] = "horizon"
    with pytest.raises(ValueError, match="planner='horizon' is not allowed"):
        TrainConfig.from_dict(bad)


def test_the_planner_aims_at_each_drawn_paths_reach_radius():
    from agents.turn_decision_env import TurnDecisionEnv

    env = TurnDecisionEnv(planner="adaptive", random_path={**SHORT_TURN, "reach_radius_m": [0.02, 0.03]})
    radii = []
    for seed in (0, 1):
        env.reset(seed=seed)
        radii.append(env.base.tracker.reach_radius_m)
        assert env.planner.reach_radius_m == radii[-1] and 0.02 <= radii[-1] <= 0.03
    assert radii[0] != radii[1]
    env.close()


def test_the_adaptive_agents_training_config_loads():
    from agents.assets import package_file
    from agents.ppo_config import TrainConfig

    cfg = TrainConfig.from_yaml(package_file("configs", "ppo_residual_adaptive.yml"))
    assert cfg.planner == "adaptive" and cfg.preset == "faithful" and cfg.max_wall_time_s <= 7200
    assert cfg.curriculum[-1].random_path["n_waypoints"] == [2, 5]
