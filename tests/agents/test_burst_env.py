"""The burst action design (agents/burst_design.py) and its surrogate env, FlagellumBurst-surrogate-v0."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import agents  # noqa: F401  (registers the ids)
from agents.burst_design import N_BURST_FEATURES, BurstHistory, BurstLimits, burst_observation, decode_burst_action
from agents.turn_geometry import angle_between
from flagellum_env.paths import path_from_waypoints

ID = "FlagellumBurst-surrogate-v0"
ONE_TURN = path_from_waypoints([[0.12, 0.0, 0.0], [0.12, 0.15, 0.0]], name="one_turn", reach_radius_m=0.015)


def test_gymnasium_check_env_passes():
    env = gym.make(ID).unwrapped
    check_env(env, skip_render_check=True)
    assert env.observation_space.shape == (N_BURST_FEATURES,) and env.action_space.shape == (4,)


def test_decoding_maps_the_box_onto_burst_length_phase_and_cruise():
    lim = BurstLimits(t_c_max_s=4.5, cruise_min_s=2.0, cruise_max_s=60.0)
    none = decode_burst_action([-0.3, 0.0, 0.5, -1.0], lim, 0.1)
    assert none.t_c_s == 0.0 and none.beta_rad == pytest.approx(0.5 * math.pi) and none.cruise_s == pytest.approx(2.0)
    full = decode_burst_action([1.0, -1.0, -1e-9, 1.0], lim, 0.1)
    assert full.t_c_s == pytest.approx(4.5) and full.beta_rad == pytest.approx(-math.pi)
    assert full.cruise_s == pytest.approx(60.0)
    mid = decode_burst_action([0.72, 0.3, 0.3, 0.0], lim, 0.1)   # 3.24 s -> whole steps of 0.1 s
    assert mid.t_c_s == pytest.approx(3.2) and mid.cruise_s == pytest.approx(31.0)
    assert mid.beta_rad == pytest.approx(0.25 * math.pi)
    assert decode_burst_action([5.0, 0.0, 3.0, 9.0], lim, 0.1) == decode_burst_action([1.0, 0.0, 1.0, 1.0], lim, 0.1)


@pytest.mark.parametrize("bad", [[0.1, 0.2, 0.3], [0.1, np.nan, 0.0, 0.0], "abc", [1j, 0, 0, 0]])
def test_an_action_that_is_not_three_finite_numbers_is_refused(bad):
    env = gym.make(ID).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="four finite numbers"):
        env.step(bad)


@pytest.mark.parametrize("kwargs, match", [({"limits": {"t_c_max": 4.0}}, "unknown limits key"),
                                           ({"limits": {"cruise_min_s": 9.0, "cruise_max_s": 3.0}}, "cruise_min_s"),
                                           ({"limits": {"t_c_max_s": -1.0}}, "t_c_max_s"),
                                           ({"planner": "rule"}, "unknown argument"),
                                           ({"preset": "fast"}, "preset='fast'"),
                                           ({"render_mode": "rgb_array"}, "render_mode")])
def test_bad_arguments_are_refused_in_one_line(kwargs, match):
    with pytest.raises(ValueError, match=match) as err:
        gym.make(ID, **kwargs)
    assert "\n" not in str(err.value)


def test_no_burst_swims_straight_for_the_cruise_asked():
    env = gym.make(ID, paths=[ONE_TURN]).unwrapped
    env.reset(seed=0)
    d0, t0 = env.episode.heading.copy(), env.episode.time_s
    obs, _, term, trunc, info = env.step(np.array([-1.0, 1.0, 0.0, -1.0]))
    assert not (term or trunc) and info["turns"] == 0
    assert np.array_equal(env.episode.heading, d0)
    assert env.episode.time_s - t0 == pytest.approx(2.0)
    assert not obs[27:].any()   # no burst yet: an empty history


def test_a_burst_turns_the_heading_by_the_maps_theta_and_the_observation_says_so():
    env = gym.make(ID, paths=[ONE_TURN]).unwrapped
    env.reset(seed=0)
    d0 = env.episode.heading.copy()
    t_c = 3.5
    obs, _, _, _, info = env.step(np.array([t_c / env.limits.t_c_max_s, 0.7, 0.7, -1.0]))
    turned = angle_between(d0, env.episode.heading)
    thetas = [p.theta_deg for p in env.turn_map.points if p.t_c == t_c]
    assert info["turns"] == 1
    assert min(thetas) - 1e-6 <= math.degrees(turned) <= max(thetas) + 1e-6
    assert obs[28] == pytest.approx(turned / math.pi, rel=1e-5)
    assert obs[27] == pytest.approx(t_c / env.limits.t_c_max_s, rel=1e-6) and not obs[29:].any()


def test_the_observation_is_the_task_in_the_headings_frame():
    head, d = np.zeros(3), np.array([1.0, 0.0, 0.0])
    targets = np.array([[0.1, 0.0, 0.0], [0.1, -0.1, 0.0]])
    obs = burst_observation(head, d, targets, (np.zeros(3), targets[0]), 0.5, BurstHistory())
    first, second = obs[:10], obs[10:20]
    assert first[:4] == pytest.approx([1.0, 0.0, 0.0, 1.0]) and first[4:7] == pytest.approx([1.0, 0.0, 0.0])
    assert first[7] == pytest.approx(0.0) and first[8:10] == pytest.approx([1.0, 0.0])   # dead ahead
    # the second: 10 cm ahead and 10 cm along -y = +e2 (e1 = z, e2 = d x e1 = -y): 45 deg off, azimuth 90 deg
    assert second[:4] == pytest.approx([1.0, 0.0, 1.0, math.sqrt(2.0)], rel=1e-6)
    assert second[7] == pytest.approx(0.25) and second[8:10] == pytest.approx([0.0, 1.0], abs=1e-7)
    assert obs[20:23] == pytest.approx([1.0, 0.0, 0.0]) and obs[23:26] == pytest.approx([0.0, 0.0, 0.0])
    assert obs[26] == pytest.approx(0.5)
    # a head 1 cm off the segment's line (along +z: e1 of the heading's frame)
    off = burst_observation(np.array([0.02, 0.0, 0.01]), d, targets, (np.zeros(3), targets[0]), 0.5, BurstHistory())
    assert off[23:26] == pytest.approx([0.0, 0.1, 0.0], abs=1e-6)


def test_episodes_end_and_a_seed_repeats_them():
    def run(seed):
        env = gym.make(ID)
        rng = np.random.default_rng(1)
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(200):
            obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, 4))
            out.append(obs)
            if term or trunc:
                return np.concatenate(out), info
        raise AssertionError("no episode end in 200 decisions")

    a, info = run(5)
    b, _ = run(5)
    assert np.array_equal(a, b) and set(info) >= {"is_success", "mean_cross_track_m", "out_of_range"}


def test_the_history_keeps_the_last_four_bursts_newest_first():
    h = BurstHistory()
    for k in range(6):
        h.record(0.1 * k, math.pi * 0.05 * k)
    assert h.features() == pytest.approx([0.5, 0.25, 0.4, 0.2, 0.3, 0.15, 0.2, 0.1])
