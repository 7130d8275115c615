"""The burst action design (agents/burst_design.py) and its surrogate env, FlagellumBurst-surrogate-v0."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import agents  # noqa: F401  (registers the ids)
from agents.burst_design import (N_BURST_FEATURES, BurstHistory, BurstLimits, burst_observation, decode_burst_action,
                                 turn_seen)
from agents.turn_geometry import angle_between, direction_from, perpendicular_basis
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
                                           ({"preset": "coarse"}, "preset 'coarse' was retired"),
                                           ({"preset": "turbo"}, "preset='turbo'"),
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
    assert obs[27] == pytest.approx(t_c / env.limits.t_c_max_s, rel=1e-6) and not obs[31:].any()
    # the turn's direction relative to beta is the map's psi (a turn > 10 deg: full weight)
    psi = env.swimmer.turn(d0, t_c, math.pi / 4).psi_rad
    assert obs[29:31] == pytest.approx([math.cos(psi), math.sin(psi)], abs=1e-5)


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
        h.record(0.1 * k, math.pi * 0.05 * k, 0.3 * k, 0.1 * k)   # turns of 9 k deg, 0.2 k rad from beta
    expected = []
    for k in (5, 4, 3, 2):
        w = min(1.0, 9.0 * k / 10.0)
        expected += [0.1 * k, 0.05 * k, w * math.cos(0.2 * k), w * math.sin(0.2 * k)]
    assert h.features() == pytest.approx(expected)
    assert N_BURST_FEATURES == 43 and BurstHistory().features() == pytest.approx(np.zeros(16))


def test_the_history_gives_a_turns_direction_relative_to_the_commanded_phase():
    d0 = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    e1, e2 = perpendicular_basis(d0)
    beta, delta, theta = 2.5, math.radians(130.0), math.radians(40.0)
    d1 = math.cos(theta) * d0 + math.sin(theta) * (math.cos(beta + delta) * e1 + math.sin(beta + delta) * e2)
    turn, az = turn_seen(d0, d1)
    assert turn == pytest.approx(theta) and az == pytest.approx(beta + delta - 2.0 * math.pi)
    h = BurstHistory()
    h.record(0.8, turn, az, beta)
    assert h.features()[:4] == pytest.approx([0.8, theta / math.pi, math.cos(delta), math.sin(delta)])
    # a tiny turn's direction is weighted down: 2 deg -> 0.2 of the unit vector; no turn -> zeros
    h.record(0.1, *turn_seen(d0, direction_from(d0, math.radians(2.0), beta + delta)), beta)
    assert h.features()[2:4] == pytest.approx([0.2 * math.cos(delta), 0.2 * math.sin(delta)], abs=1e-9)
    h.record(0.1, *turn_seen(d0, d0), beta)
    assert h.features()[1:4] == pytest.approx([0.0, 0.0, 0.0], abs=1e-7)


def _random_episodes(seeds=(3, 7), **kwargs):
    """Observations, rewards and the path and swimmer of seeded random-action episodes (randomised swimmers)."""
    out = []
    for seed in seeds:
        env = gym.make(ID, env_kwargs={"randomize": {"youngs_modulus": 0.1, "viscosity": 0.1, "head_radius": 0.1,
                                                      "geometry": 0.04, "obs_noise_std": 0.0}}, **kwargs).unwrapped
        rng = np.random.default_rng(seed)
        obs, _ = env.reset(seed=seed)
        rows, rewards, turns = [obs], [], []
        setup = (env.path.waypoints.copy(), env.episode_params)
        for _ in range(40):
            d0 = env.episode.heading.copy()
            obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, 4))
            rows.append(obs)
            rewards.append(r)
            turns.append(angle_between(d0, env.episode.heading))
            if term or trunc:
                break
        out.append((np.array(rows), rewards, setup, turns, env))
    return out


def test_map_noise_off_is_the_env_without_it_and_on_keeps_a_seeds_path_and_swimmer():
    plain, off, on = _random_episodes(), _random_episodes(map_noise=None), _random_episodes(
        map_noise={"direction_deg": 30, "turn_scale": 0.15})
    for a, b, c in zip(plain, off, on):
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]
        assert b[4].map_bias_rad == 0.0 and b[4].map_turn_scale == 1.0
        assert np.array_equal(a[2][0], c[2][0]) and a[2][1] == c[2][1]     # same path, same swimmer
        assert 0.0 < abs(c[4].map_bias_rad) <= math.radians(30) and 0.85 <= c[4].map_turn_scale <= 1.15
    # the same actions: the turns differ (the first burst's size by the drawn factor, the rest follow)
    turned = [(a[3], c[3]) for a, c in zip(plain, on) if max(a[3]) > 0.1]
    assert turned and all(not np.allclose(x[:len(y)], y[:len(x)]) for x, y in turned)


def test_map_noise_biases_each_turns_direction_and_scales_its_size():
    nominal = gym.make(ID, paths=[ONE_TURN]).unwrapped
    noisy = gym.make(ID, paths=[ONE_TURN], map_noise={"direction_deg": 60, "turn_scale": 0.3}).unwrapped
    nominal.reset(seed=4)
    noisy.reset(seed=4)
    b, s = noisy.map_bias_rad, noisy.map_turn_scale
    d, beta = nominal.episode.heading.copy(), 1.1
    a, n = nominal.swimmer.turn(d, 3.4, beta), noisy.swimmer.turn(d, 3.4, beta)
    assert n.theta_rad == pytest.approx(min(math.pi, s * a.theta_rad))
    assert math.cos(n.psi_rad - a.psi_rad - b) == pytest.approx(1.0)
    assert turn_seen(d, n.heading)[0] == pytest.approx(n.theta_rad)
    assert math.cos(turn_seen(d, n.heading)[1] - turn_seen(d, a.heading)[1] - b) == pytest.approx(1.0)
    # the displacement: its part along the heading kept, its lateral part rotated by b about the heading
    along_a, along_n = a.displacement @ d, n.displacement @ d
    assert along_n == pytest.approx(along_a)
    lat_a, lat_n = a.displacement - along_a * d, n.displacement - along_n * d
    e1, e2 = perpendicular_basis(d)
    rot = math.atan2(lat_n @ e2, lat_n @ e1) - math.atan2(lat_a @ e2, lat_a @ e1)
    assert np.linalg.norm(lat_n) == pytest.approx(np.linalg.norm(lat_a)) and math.cos(rot - b) == pytest.approx(1.0)


@pytest.mark.parametrize("bad", [{"direction_deg": 30}, {"direction_deg": 30, "turn_scale": 0.1, "x": 1},
                                 {"direction_deg": -1, "turn_scale": 0.1}, {"direction_deg": 181, "turn_scale": 0.1},
                                 {"direction_deg": 30, "turn_scale": 1.0}, {"direction_deg": np.nan, "turn_scale": 0.1},
                                 {"direction_deg": 30, "turn_scale": "big"}, [30, 0.1], 0.2])
def test_a_bad_map_noise_is_refused_in_one_line(bad):
    with pytest.raises(ValueError, match="map_noise") as err:
        gym.make(ID, map_noise=bad)
    assert "\n" not in str(err.value) and "0 <= S < 1" in str(err.value)
