"""Bursts ended by L'/L (``BurstLimits.burst_end = "ratio"``): the ratio clock (agents/online_turn_map.RatioClock), the
rod's flight (agents/burst_flight.py) and the surrogate's model of it (agents/surrogate_swimmer.py).

The rod tests fly one burst each at the default preset (~2 CPU s each)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import agents  # noqa: F401  (registers the ids)
from agents.burst_design import BurstLimits, burst_limits, decode_burst_action
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap, RatioClock
from agents.surrogate_swimmer import RATIO_CLOCK_COEFFICIENT
from agents.turn_geometry import angle_between
from flagellum_env.paths import path_from_waypoints

FAR = path_from_waypoints([[1.0, 0.0, 0.0]], name="far_ahead", reach_radius_m=0.015)
#: +-10 % on E, mu, b and +-4 % on the helix, as ``flagellum evaluate --randomize 0.1``
RANDOMIZE = {"youngs_modulus": 0.1, "viscosity": 0.1, "head_radius": 0.1, "geometry": 0.04, "obs_noise_std": 0.0}
ROD_KWARGS = {"paths": [FAR], "env_kwargs": {"randomize": RANDOMIZE, "off_path_m": 1.0, "max_sim_time_s": 5000.0}}


def test_the_clock_is_the_maps_falling_ratio_and_the_online_maps():
    env = gym.make("FlagellumBurst-surrogate-v0").unwrapped
    clock, online = RatioClock(env.turn_map), OnlineTurnMap(env.turn_map, OnlineMapConfig())
    assert 2.0 < clock.start_s < 3.0   # the default's flagellum buckles ~2.4 s into a 150 rpm burst
    assert clock.ratio_for(clock.start_s - 0.01) is None and clock.ratio_for(clock.start_s) == pytest.approx(0.98)
    ts = np.linspace(clock.start_s, 3.7, 30)
    ratios = [clock.ratio_for(t) for t in ts]
    assert all(np.diff(ratios) < 0.0)   # a clock: L'/L falls steadily over the bursts the design flies
    assert ratios == [online.ratio_for(t) for t in ts]


def test_burst_end_is_a_limit_and_a_bad_one_is_refused_in_one_line():
    assert BurstLimits().burst_end == "time" and burst_limits({"burst_end": "ratio"}).burst_end == "ratio"
    assert decode_burst_action([0.8, 1.0, 0.0, 0.0], BurstLimits(burst_end="ratio"), 0.1).burst_end == "ratio"
    with pytest.raises(ValueError, match="burst_end='clock' is not allowed; allowed: \\['time', 'ratio'\\]") as err:
        gym.make("FlagellumBurst-surrogate-v0", limits={"burst_end": "clock"})
    assert "\n" not in str(err.value)


def test_the_surrogate_turns_a_ratio_burst_nearly_as_the_map_says_for_any_swimmer():
    env = gym.make("FlagellumBurst-surrogate-v0", env_kwargs={"randomize": RANDOMIZE}).unwrapped
    start = env.table.clock.start_s
    seen = 0
    for seed in range(40):
        env.reset(seed=seed)
        sw = env.swimmer
        ln_f = math.log(sw.time_factor)
        if abs(ln_f) < 0.05:
            continue
        seen += 1
        for t_c in (2.0, 3.0, 3.5):
            fly_t, map_t = sw.burst_times(t_c, "time")
            assert (fly_t, map_t) == (t_c, sw.map_time(t_c))
            fly_r, map_r = sw.burst_times(t_c, "ratio")
            if t_c < start:   # too short for the clock: flown by time
                assert (fly_r, map_r) == (fly_t, map_t)
                continue
            # the clock ends the burst when the swimmer reaches (about) the map's state: much of the timing error goes
            assert abs(map_r - t_c) < 0.5 * abs(map_t - t_c)
            assert map_r - t_c == pytest.approx(RATIO_CLOCK_COEFFICIENT * (t_c - start) * ln_f)
            assert fly_r == pytest.approx(map_r / sw.time_factor)   # the swimmer's own time to that map state
            d = np.array([1.0, 0.0, 0.0])
            assert sw.turn(d, t_c, 0.3, "ratio").map_time_s == pytest.approx(map_r)
    assert seen >= 20


def test_a_ratio_burst_on_the_rod_stops_where_l_over_l_reaches_the_maps():
    """The nominal swimmer: the map's own L'/L, so the clock stops within a control step of t_c."""
    env = gym.make("FlagellumBurst-v0", paths=[FAR], limits={"burst_end": "ratio"},
                   env_kwargs={"off_path_m": 1.0, "max_sim_time_s": 5000.0}).unwrapped
    env.reset(seed=0)
    t_c = 3.0
    env.step(np.array([t_c / env.limits.t_c_max_s, 1.0, 0.0, -1.0]))
    burst = env.last_burst
    target = RatioClock(env.turn_map).ratio_for(t_c)
    assert burst["stopped_by"] == "ratio" and abs(burst["burst_s"] - t_c) <= env.control_dt + 1e-9
    assert abs(burst["end_ratio"] - target) < 0.03   # L'/L falls ~0.025 per 0.1 s here


def test_a_ratio_burst_turns_a_swimmer_off_the_model_closer_to_the_map_than_a_timed_one():
    """Seed 30001 at +-10 % buckles early (ln F ~ +0.15): flown by time its 3 s burst turns ~104 deg against the map's
    38 deg; ended by the clock, shorter and near the map's turn (scripts/measure_ratio_clock.py measures 24)."""
    turns = {}
    for end in ("time", "ratio"):
        env = gym.make("FlagellumBurst-v0", limits={"burst_end": end}, **ROD_KWARGS).unwrapped
        env.reset(seed=30001)
        d0 = env.heading.copy()
        env.step(np.array([3.0 / env.limits.t_c_max_s, 1.0, 0.0, -1.0]))
        turns[end] = (math.degrees(angle_between(d0, env.heading)), env.last_burst)
    map_theta = float(np.interp(3.0, *env.turn_map.theta_curve()[:2]))
    assert turns["time"][1]["stopped_by"] == "time" and turns["time"][1]["burst_s"] == pytest.approx(3.0)
    assert turns["ratio"][1]["stopped_by"] == "ratio" and turns["ratio"][1]["burst_s"] < 3.0 - 1e-9
    assert abs(turns["ratio"][0] - map_theta) < 0.5 * abs(turns["time"][0] - map_theta)
