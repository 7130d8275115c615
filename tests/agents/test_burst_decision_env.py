"""FlagellumBurst-v0 (agents/burst_decision_env.py): the burst action design on the rod, twin of
FlagellumBurst-surrogate-v0; and FlagellumTurn-v0 unchanged by the code the two envs now share.

Cheap on purpose: the default preset ("faithful") swims straight at ~100x real time, so short paths and small
time budgets keep each test to seconds; the one burst (3.5 s) costs ~2 CPU s.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import agents  # noqa: F401  (registers the ids)
from agents.burst_decision_env import BurstDecisionEnv
from agents.turn_geometry import angle_between, azimuth, wrap_angle
from agents.turn_planner import PlannerConfig
from flagellum_env.paths import path_from_waypoints

ID, SURROGATE_ID = "FlagellumBurst-v0", "FlagellumBurst-surrogate-v0"
DATA = Path(__file__).parent / "data"
ONE_TURN = path_from_waypoints([[0.12, 0.0, 0.0], [0.12, 0.15, 0.0]], name="one_turn", reach_radius_m=0.015)
INFO = {"path", "is_success", "waypoints_reached", "mean_cross_track_m", "time_s", "energy_J", "buckling_events",
        "turns", "out_of_range"}
#: A heading is measured over one wobble period at 0.1 s steps; the planner takes one within this of the target as
#: on course (PlannerConfig.min_turn_deg), so two such measurements agree to within it on a straight swim.
HEADING_TOL_DEG = PlannerConfig().min_turn_deg


def test_make_gives_the_twin_with_the_surrogates_spaces():
    env = gym.make(ID).unwrapped
    twin = gym.make(SURROGATE_ID).unwrapped
    assert isinstance(env, BurstDecisionEnv) and env.preset == "faithful" and env.control_dt == 0.1
    assert env.observation_space == twin.observation_space and env.action_space == twin.action_space
    assert env.limits == twin.limits


def test_gymnasium_check_env_passes():
    # the checker wants no truncation at the first step: the path's own budget holds any one decision
    env = gym.make(ID, paths=[ONE_TURN], render_mode="rgb_array", disable_env_checker=True).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings count as failures
        check_env(env, skip_render_check=False)
    env.close()


def test_no_burst_swims_straight_for_the_cruise_asked():
    env = gym.make(ID, paths=[ONE_TURN]).unwrapped
    obs, info = env.reset(seed=0)
    assert set(info) == INFO and info["turns"] == 0 and not info["out_of_range"]
    assert info["time_s"] == pytest.approx((env.flight.period_steps + 1) * env.control_dt)  # the reset's heading
    d0, t0 = env.heading.copy(), env.time_s
    obs, reward, term, trunc, info = env.step(np.array([-1.0, 1.0, 0.3, -1.0]))  # no burst, 2 s of cruise
    assert not (term or trunc) and info["turns"] == 0 and reward > 0.0  # progress along the first segment
    assert env.time_s - t0 == pytest.approx(2.0, rel=1e-9)
    assert math.degrees(angle_between(d0, env.heading)) < HEADING_TOL_DEG
    assert not obs[27:].any()   # no burst: nothing in the history


def test_a_burst_turns_the_heading_as_the_map_says():
    """A 3.5 s burst at the default preset: the map (agents/turn_maps/faithful.json) turns 85-87 deg at that t_c,
    towards the azimuth beta + psi about the heading before it; the twin measures each heading to within
    ``HEADING_TOL_DEG`` and hits beta to within its hover's phase error."""
    env = gym.make(ID, paths=[ONE_TURN]).unwrapped
    env.reset(seed=0)
    d0, t_c, beta = env.heading.copy(), 3.5, 0.25 * math.pi
    obs, _, term, trunc, info = env.step(np.array([t_c / env.limits.t_c_max_s, math.cos(beta), math.sin(beta), -1.0]))
    assert not (term or trunc) and info["turns"] == 1
    points = [p for p in env.turn_map.points if p.t_c == t_c]
    theta = math.degrees(angle_between(d0, env.heading))
    assert min(p.theta_deg for p in points) - 2 * HEADING_TOL_DEG <= theta
    assert theta <= max(p.theta_deg for p in points) + 2 * HEADING_TOL_DEG
    psi = math.degrees(wrap_angle(azimuth(env.heading, d0) - beta))
    slack = math.degrees(abs(env.last_burst["phase_error_rad"])) + 2 * HEADING_TOL_DEG
    assert min(p.psi_deg for p in points) - slack <= psi <= max(p.psi_deg for p in points) + slack
    assert obs[27] == pytest.approx(t_c / env.limits.t_c_max_s) and obs[28] == pytest.approx(theta / 180, rel=1e-5)
    # the turn's direction relative to the commanded beta (a turn > 10 deg: full weight), then an empty history
    assert obs[29:31] == pytest.approx([math.cos(math.radians(psi)), math.sin(math.radians(psi))], abs=1e-5)
    assert not obs[31:].any()
    # the relaxation waited at least two periods and at most max_relax_factor x the map's relaxation
    relax = env.last_burst["relax_s"]
    assert 2 * env.flight.period_steps * env.control_dt - 1e-9 <= relax <= 3.0 * env.turn_map.relax_s + env.control_dt


def test_the_same_seed_draws_the_surrogates_swimmer_and_path():
    kwargs = {"env_kwargs": {"randomize": True, "reward": {"cross_track_per_cm_s": 0.05}}}
    env, twin = gym.make(ID, **kwargs).unwrapped, gym.make(SURROGATE_ID, **kwargs).unwrapped
    for seed in (3, 11):
        _, info = env.reset(seed=seed)
        _, twin_info = twin.reset(seed=seed)
        assert env.episode_params == twin.episode_params != env.base.params
        assert np.array_equal(env.base.path.waypoints, twin.path.waypoints)
        assert set(info) == set(twin_info)


def test_an_episode_that_ends_in_the_reset_ends_at_the_first_step():
    env = gym.make(ID, paths=[ONE_TURN], env_kwargs={"max_sim_time_s": 3.0}).unwrapped
    recorded: list[float] = []
    step = env.base.step

    def recording(action):
        out = step(action)
        recorded.append(out[1])
        return out

    env.base.step = recording
    env.reset(seed=0)
    _, reward, term, trunc, info = env.step(np.array([1.0, 1.0, 0.0, 1.0]))
    assert trunc and not term and info["turns"] == 0 and info["time_s"] == pytest.approx(3.0)
    assert reward == pytest.approx(sum(recorded), rel=1e-12)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3))


@pytest.mark.parametrize("kwargs, match", [
    ({"planner": "rule"}, r"unknown argument\(s\) \['planner'\] for FlagellumBurst-v0; known arguments: preset"),
    # the surrogate's randomised map has no meaning on the rod
    ({"map_noise": {"direction_deg": 30, "turn_scale": 0.15}},
     r"unknown argument\(s\) \['map_noise'\] for FlagellumBurst-v0; known arguments: preset"),
    ({"map_noise": None}, r"unknown argument\(s\) \['map_noise'\] for FlagellumBurst-v0"),
    ({"preset": "quick"}, "preset='quick'"), ({"render_mode": "human"}, "render_mode='human'"),
    ({"limits": {"t_c_max": 4.0}}, "unknown limits key"), ({"limits": {"t_c_max_s": -1.0}}, "t_c_max_s"),
    ({"env_kwargs": {"path": "square"}}, "'path'"), ({"env_kwargs": {"control_dt": -1.0}}, "control_dt=-1.0"),
    ({"turn_map": "no_such_map.json"}, "no_such_map.json"), ({"paths": "square"}, "paths='square'"),
    ({"random_path": {"n_waypoint": 2}}, "n_waypoint")])
def test_bad_arguments_are_refused_in_one_line(kwargs, match):
    with pytest.raises(ValueError, match=match) as err:
        BurstDecisionEnv(**kwargs)
    assert "\n" not in str(err.value)


def test_a_bad_action_is_refused():
    env = gym.make(ID, paths=[ONE_TURN], env_kwargs={"max_sim_time_s": 8.0}).unwrapped
    env.reset(seed=0)
    for bad in ([0.1, 0.2, 0.3], [0.1, np.nan, 0.0, 0.0], "abc"):
        with pytest.raises(ValueError, match="four finite numbers"):
            env.step(bad)


def test_flagellum_turn_is_bit_identical_to_before_the_shared_code():
    """FlagellumTurn-v0 (faithful, a randomised swimmer, a short two-turn path, two fixed corrections) as recorded
    at e5953da (tests/agents/data/turn_env_faithful_seed3.json). It replaces the recording on the retired coarse preset
    made at 5c2c9bf, before the base env and info were shared with FlagellumBurst-v0; that one was still reproduced
    bit for bit at e5953da, and this one was recorded there, so together they hold the shared code unchanged."""
    ref = json.loads((DATA / "turn_env_faithful_seed3.json").read_text())
    env = gym.make("FlagellumTurn-v0", preset="faithful",
                   paths=[path_from_waypoints(ref["path"], name="p", reach_radius_m=0.015)],
                   env_kwargs={"reward": {"cross_track_per_cm_s": 0.05},
                               "randomize": {"youngs_modulus": 0.1}}).unwrapped
    obs, info = env.reset(seed=ref["seed"])
    got = [{"obs": obs.tolist(), "info": info}]
    for a in ref["actions"]:
        obs, r, te, tr, info = env.step(np.array(a, np.float32))
        got.append({"obs": obs.tolist(), "reward": r, "terminated": te, "truncated": tr, "info": info})
    assert json.loads(json.dumps(got)) == ref["steps"]
