"""One episode end to end: spaces, reward terms in info, success, time limit, leaving the path,
simulation errors, the starting state."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flagellum_env.rewards import TERMS
from physics.errors import SimulationError

FULL = np.array([1.0], np.float32)
LOW = np.array([-1.0], np.float32)


def _run(env, action, max_steps=100):
    infos, rewards = [], []
    for _ in range(max_steps):
        obs, r, term, trunc, info = env.step(action)
        infos.append(info)
        rewards.append(r)
        if term or trunc:
            return obs, rewards, infos, term, trunc
    raise AssertionError("episode did not end")


def test_observation_layout_has_documented_size_and_parts(make_env):
    env = make_env(n_shape_nodes=8, n_lookahead=2)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (22 + 3 * 8,) and obs.dtype == np.float32
    sl = env.obs_model.slices()
    assert list(sl) == ["waypoints", "orientation", "velocity", "shape", "end_to_end_ratio", "motor_speed",
                        "previous_action", "time_left"]
    # start frame = head pose at the episode start: orientation is the identity there
    assert np.allclose(obs[sl["orientation"]], np.eye(3).ravel(), atol=1e-6)
    # first waypoint (3 mm ahead) seen ahead along X_b, in units of L = 0.13 m
    wp = obs[sl["waypoints"]].reshape(2, 3)
    assert wp[0, 0] == pytest.approx(0.003 / 0.13, rel=1e-4)
    assert obs[sl["end_to_end_ratio"]][0] == pytest.approx(1.0, abs=0.02)  # straight flagellum
    assert obs[sl["previous_action"]][0] == -1.0 and obs[sl["time_left"]][0] == 1.0
    assert obs[sl["motor_speed"]][0] == pytest.approx(10.0 / 40.0)
    v = obs[sl["velocity"]]
    assert v[0] > 0.2  # swimming head first at ~0.45 mm/s already: steady start, not rest


def test_dict_observation_has_the_parts_by_name(make_env):
    env = make_env(observation_type="dict")
    obs, _ = env.reset(seed=0)
    assert set(obs) == set(env.obs_model.part_shapes)
    assert obs["shape"].shape == (4 * 3,) and obs["orientation"].shape == (9,)
    flat_env = make_env()
    flat, _ = flat_env.reset(seed=0)
    assert np.array_equal(np.concatenate([obs[k] for k in env.obs_model.part_shapes]), flat)


def test_reaching_the_last_waypoint_terminates_with_success(make_env):
    env = make_env()
    env.reset(seed=0)
    _, rewards, infos, term, trunc = _run(env, FULL)
    last = infos[-1]
    assert term and not trunc
    assert last["is_success"] and last["waypoint_index"] == 2 == last["n_waypoints"]
    assert sum(i["reward_waypoint"] for i in infos) == pytest.approx(2 * 10.0)
    for info, r in zip(infos, rewards):
        assert r == pytest.approx(sum(info[f"reward_{t}"] for t in TERMS))
    assert last["energy_used_j"] == pytest.approx(sum(i["energy_j"] for i in infos))
    assert last["energy_used_j"] > 0
    assert last["buckling_events"] == 0 and not last["buckled"]
    # progress rewards add up to the path length in cm
    assert sum(i["reward_progress"] for i in infos) == pytest.approx(last["path_length_m"] / 0.01, rel=1e-9)


def test_time_limit_truncates(make_env):
    env = make_env(max_sim_time_s=1.0)
    env.reset(seed=0)
    _, _, infos, term, trunc = _run(env, LOW)
    assert trunc and not term
    assert len(infos) == 5  # 1 s of 0.2 s steps
    assert infos[-1]["sim_time_s"] == pytest.approx(1.0)
    assert not infos[-1]["is_success"]


def test_default_time_budget_follows_the_path_length_rule(make_env):
    env = make_env(max_sim_time_s=None, time_factor=2.0)
    _, info = env.reset(seed=0)
    v0 = env.steady_speed_m_s
    assert 0.5e-3 < v0 < 0.9e-3  # ~0.42 cm per turn at 10 rpm (the flagellum turns at 10 rpm in the lab)
    assert info["max_sim_time_s"] == pytest.approx(2.0 * info["path_length_m"] / v0)
    assert env.max_steps == math.ceil(info["max_sim_time_s"] / 0.2)


def test_leaving_the_path_terminates_with_penalty(make_env):
    env = make_env(path=[[0.0, 0.01, 0.0]], off_path_m=0.001, max_sim_time_s=20.0)  # target to the side
    env.reset(seed=0)
    _, _, infos, term, _ = _run(env, FULL)
    assert term and infos[-1]["off_path"] and not infos[-1]["is_success"]
    assert infos[-1]["reward_penalty"] == -20.0
    assert infos[-1]["cross_track_error_m"] > 0.001


def test_simulation_error_ends_the_episode_without_raising(make_env, monkeypatch):
    env = make_env()
    env.reset(seed=0)
    env.step(LOW)

    def fail() -> None:
        raise SimulationError("Newton did not converge", 7, 1.5, "Newton")

    monkeypatch.setattr(env.simulator, "step", fail)
    obs, reward, term, trunc, info = env.step(FULL)
    assert term and not trunc
    assert "Newton did not converge" in info["error"] and info["error_quantity"] == "Newton"
    assert info["reward_penalty"] == -20.0 and reward == pytest.approx(-20.0, abs=0.1)
    assert env.observation_space.contains(obs) and np.all(np.isfinite(obs))
    with pytest.raises(RuntimeError, match="reset"):
        env.step(FULL)
    env.reset(seed=1)  # a new episode works
    assert not env.step(LOW)[2]


def test_discrete_actions_select_the_listed_speeds(make_env):
    env = make_env(action_type="discrete")
    env.reset(seed=0)
    for i, rpm in enumerate((10.0, 25.0, 40.0)):
        _, _, _, _, info = env.step(i)
        assert info["motor_speed_rpm"] == rpm
    with pytest.raises(ValueError, match="integer from 0 to 2"):
        env.step(3)


def test_continuous_action_maps_linearly_and_clips(make_env):
    env = make_env()
    env.reset(seed=0)
    for a, rpm in ((-1.0, 10.0), (0.0, 25.0), (1.0, 40.0), (3.0, 40.0)):
        assert env.step(np.array([a], np.float32))[4]["motor_speed_rpm"] == pytest.approx(rpm)


def test_reset_option_replaces_the_path_for_one_episode(make_env):
    env = make_env()
    _, info = env.reset(seed=0, options={"path": [[0.01, 0.0, 0.0]]})
    assert info["n_waypoints"] == 1 and info["path_length_m"] == pytest.approx(0.01)
    _, info = env.reset(seed=0)
    assert info["n_waypoints"] == 2


def test_randomized_episodes_draw_physics_and_noise(make_env):
    env = make_env(randomize=True)
    env.reset(seed=0)
    p0 = env.episode_params
    env.reset(seed=1)
    p1 = env.episode_params
    assert p0 != p1 != env.params
    assert p0.shear_modulus / p0.youngs_modulus == pytest.approx(env.params.shear_modulus / env.params.youngs_modulus)
    assert abs(p0.viscosity / env.params.viscosity - 1) <= 0.1
    obs, _ = env.reset(seed=0)
    sl = env.obs_model.slices()
    assert not np.allclose(obs[sl["orientation"]], np.eye(3).ravel(), atol=1e-4)  # noisy sensor
    assert obs[sl["time_left"]][0] == 1.0  # not noisy


def test_info_carries_the_documented_keys(make_env):
    env = make_env()
    _, reset_info = env.reset(seed=0)
    info = env.step(LOW)[4]
    documented = {"is_success", "waypoint_index", "n_waypoints", "cross_track_error_m", "distance_to_waypoint_m",
                  "path_progress_m", "path_length_m", "energy_j", "energy_used_j", "buckled", "buckling_events",
                  "end_to_end_ratio", "motor_speed_rpm", "sim_time_s", "max_sim_time_s", "head_position_m",
                  "off_path"} | {f"reward_{t}" for t in TERMS}
    assert set(info) == documented == set(reset_info)
