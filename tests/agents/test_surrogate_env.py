"""``FlagellumTurn-surrogate-v0`` (``agents.surrogate_turn_env``): made by ``gymnasium.make``, the spaces of
``FlagellumTurn-v0``, the env checker, seeding, the turn map replayed (theta at the map's burst lengths, tau
rescaling's direction), bad input named at construction, leaving the map's range reported in ``info``, and the
compiled candidate misses equal to the planner's NumPy formulas. No rod anywhere: a few seconds in all."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

import agents  # noqa: F401  (registers the ids)
from agents.assets import default_turn_map
from agents.candidate_miss import candidate_frames, candidate_miss, first_improving_distance, local_target
from agents.residual_planner import N_FEATURES
from agents.surrogate_calibration import SurrogateCalibration, calibration_file
from agents.surrogate_swimmer import FACTOR_RANGE, SurrogateSwimmer, TurnMapTable, burst_speed_exponent
from agents.turn_decision_env import INFO_KEYS
from agents.turn_geometry import angle_between, perpendicular_basis
from agents.turn_map import TurnMap
from agents.turn_planner import BEHIND_PENALTY_M, RulePlanner, candidate_misses, paper_line_miss
from flagellum_env.config import RandomizationConfig, draw_randomization
from flagellum_env.paths import path_from_waypoints

ID = "FlagellumTurn-surrogate-v0"
# 2 cm ahead, then a left turn of 90 degrees and 8 cm: one planned turn at least
ONE_TURN = path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], name="one_turn", reach_radius_m=0.015)


@pytest.fixture(scope="module")
def tmap() -> TurnMap:
    return TurnMap.load(default_turn_map("faithful"))


def _episode(env, seed, actions=None):
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), 0.0, dict(info))]
    k, done = 0, False
    while not done:
        a = np.zeros(2, np.float32) if actions is None else actions[k % len(actions)]
        obs, r, term, trunc, info = env.step(a)
        out.append((obs.copy(), r, dict(info)))
        k, done = k + 1, term or trunc
    return out


def test_make_gives_the_spaces_and_info_keys_of_flagellum_turn_v0():
    env = gym.make(ID)
    physics = gym.make("FlagellumTurn-v0")  # construction only: no steady start, no rod stepped
    assert env.observation_space == physics.observation_space and env.observation_space.shape == (N_FEATURES,)
    assert env.action_space == physics.action_space
    physics.close()
    obs, info = env.reset(seed=0, options={"path": ONE_TURN})
    assert env.observation_space.contains(obs) and np.any(obs != 0.0)
    assert set(INFO_KEYS) <= set(info) and info["out_of_range"] is False
    _, _, _, _, info = env.step(np.zeros(2, np.float32))
    assert set(INFO_KEYS) <= set(info) and info["turns"] == 1 and info["buckling_events"] == 1


def test_gymnasium_env_checker_passes():
    from gymnasium.utils.env_checker import check_env

    env = gym.make(ID, disable_env_checker=True).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)


def test_stable_baselines3_env_checker_passes():
    sb3_env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(ID)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_env_checker.check_env(env, warn=True)


def test_a_seed_fixes_the_episode_and_another_seed_changes_it():
    kw = {"env_kwargs": {"randomize": True, "reward": {"cross_track_per_cm_s": 0.05}}}
    actions = [np.array([0.5, -0.3], np.float32), np.array([-1.0, 1.0], np.float32)]
    a, b = _episode(gym.make(ID, **kw), 7, actions), _episode(gym.make(ID, **kw), 7, actions)
    assert len(a) == len(b)
    for (oa, ra, ia), (ob, rb, ib) in zip(a, b):
        assert np.array_equal(oa, ob) and ra == rb and ia == ib
    c = _episode(gym.make(ID, **kw), 8, actions)
    assert [x[1] for x in c] != [x[1] for x in a]


def test_the_surrogate_draws_the_physics_envs_swimmer_from_a_seed():
    """The same five draws as FlagellumSteer-v0 from a generator seeded alike (flagellum_env.config)."""
    env = gym.make(ID, env_kwargs={"randomize": True}).unwrapped
    env.reset(seed=11)
    params, _ = draw_randomization(env.params, RandomizationConfig(), seeding.np_random(11)[0])
    assert env.episode_params == params != env.params


def test_a_burst_of_a_map_t_c_turns_by_the_maps_theta(tmap):
    """At the map's burst lengths and phases the swimmer turns by the measured theta (to rounding); between the
    phases by a theta between the neighbours'."""
    sw = SurrogateSwimmer(tmap, SurrogateCalibration.load(calibration_file("faithful")), TurnMapTable(tmap))
    d = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    for p in tmap.points:
        out = sw.turn(d, p.t_c, math.radians(p.phase_deg))
        assert math.degrees(angle_between(d, out.heading)) == pytest.approx(p.theta_deg, abs=1e-6)
        assert np.linalg.norm(out.displacement) == pytest.approx(np.linalg.norm(p.offset_m), rel=1e-9)
        # the azimuth of the new heading about d is beta + psi
        e1, e2 = perpendicular_basis(d)
        if p.theta_deg > 5.0:
            az = math.atan2(out.heading @ e2, out.heading @ e1)
            assert math.remainder(az - math.radians(p.phase_deg + p.psi_deg), 2 * math.pi) == pytest.approx(0, abs=1e-6)
    th = {p.phase_deg: p.theta_deg for p in tmap.points if p.t_c == 3.5}
    mid = math.degrees(sw.turn(d, 3.5, math.radians(45.0)).theta_rad)
    assert min(th[0.0], th[90.0]) - 1e-9 <= mid <= max(th[0.0], th[90.0]) + 1e-9


def test_a_swimmer_that_buckles_earlier_turns_more_for_the_same_burst(tmap):
    """mu up (tau = mu L^4 / EI up) or the pitch down: the flagellum buckles earlier (the measured burst time law,
    scripts/calibrate_surrogate_shift.py), so a burst on the rising branch turns the swimmer further; a factor
    outside the calibrated range is refused naming the value."""
    cal, tab = SurrogateCalibration.load(calibration_file("faithful")), TurnMapTable(tmap)
    d = np.array([1.0, 0.0, 0.0])
    p = tmap.params
    nominal = SurrogateSwimmer(tmap, cal, tab).turn(d, 3.25, 0.0).theta_rad
    for changed in (p.replace(viscosity=p.viscosity * 1.05), p.replace(pitch=p.pitch * 0.97),
                    p.replace(youngs_modulus=p.youngs_modulus * 0.95, shear_modulus=p.shear_modulus * 0.95)):
        assert SurrogateSwimmer(tmap, cal, tab, changed).turn(d, 3.25, 0.0).theta_rad > nominal + math.radians(10.0)
    with pytest.raises(ValueError, match=r"viscosity = 4\.05 \(1\.5 x the map's\) is outside .*\[0\.85, 1\.15\]"):
        SurrogateSwimmer(tmap, cal, tab, p.replace(viscosity=p.viscosity * 1.5))
    with pytest.raises(ValueError, match=r"differs from the map's in \['rod_radius'\]"):
        SurrogateSwimmer(tmap, cal, tab, p.replace(rod_radius=p.rod_radius * 1.01))


def test_the_measured_exponents_of_e_and_mu_follow_tau_and_the_burst_speed_law(tmap):
    """E and mu enter as tau = mu L^4 / EI (equal and opposite exponents), and their size is alpha - 1 of the
    burst-speed law t_c ~ omega_h^-alpha between the faithful maps at 90 and 150 rpm (within 10 %)."""
    e = SurrogateCalibration.load(calibration_file("faithful")).burst_time_exponents
    assert e["viscosity"] == pytest.approx(-e["youngs_modulus"], rel=0.02)
    slow_file = Path(__file__).resolve().parents[2] / "results" / "turn_maps" / "burst_90.json"
    if not slow_file.is_file():
        pytest.skip("results/turn_maps/burst_90.json (the 90 rpm map) is not on this disk")
    alpha = burst_speed_exponent(TurnMap.load(slow_file), tmap)
    assert alpha.max() - alpha.min() < 0.15
    assert e["viscosity"] == pytest.approx(np.median(alpha) - 1.0, rel=0.1)


def test_the_turn_flown_is_the_one_the_planner_predicts_within_the_maps_phase_spread(tmap):
    """Through the env: each decided turn changes the heading by the planner's predicted theta (the map's mean over
    phases) up to the spread over phases (<= 2.1 deg on the rising branch, docs/planner.md)."""
    env = gym.make(ID, paths=[ONE_TURN]).unwrapped
    checked = 0
    for seed in range(3):
        env.reset(seed=seed)
        done = False
        while not done:
            d0 = env.heading.copy()
            _, _, term, trunc, _ = env.step(np.zeros(2, np.float32))
            done = term or trunc
            plan = env.last_turn
            if plan["predicted_theta_deg"] > 10.0:
                assert math.degrees(angle_between(d0, env.heading)) == pytest.approx(plan["predicted_theta_deg"],
                                                                                    abs=2.1)
                checked += 1
    assert checked >= 3


def test_the_action_cost_is_subtracted_per_decision():
    a = np.array([0.6, -0.8], np.float32)
    free = _episode(gym.make(ID, action_cost=0.0, paths=[ONE_TURN]), 3, [a])
    paid = _episode(gym.make(ID, action_cost=2.0, paths=[ONE_TURN]), 3, [a])
    for (_, rf, _), (_, rp, _) in zip(free[1:], paid[1:]):
        assert rf - rp == pytest.approx(2.0 * float(a.astype(np.float64) @ a.astype(np.float64)), rel=1e-6)


@pytest.mark.parametrize("kwargs, named", [
    ({"preset": "paper"}, "preset='paper'"),
    ({"preset": "coarse"}, "preset 'coarse' was retired"),
    ({"planner": "adaptive"}, "planner='adaptive'"),
    ({"render_mode": "rgb_array"}, "render_mode='rgb_array'"),
    ({"env_kwargs": {"randomize": {"viscosity": 0.3}}}, "viscosity=0.3"),
    ({"env_kwargs": {"params": {"viscosity": 3.0}}}, "'viscosity': 3.0"),
    ({"env_kwargs": {"omega_range_rpm": (10.0, 100.0)}}, "(10.0, 100.0)"),
    ({"env_kwargs": {"control_dt": -1.0}}, "control_dt=-1.0"),
    ({"limits": {"max_dtc_fraction": 2.0}}, "max_dtc_fraction"),
    ({"bogus": 1}, "bogus"),
])
def test_bad_input_is_one_line_naming_the_value(kwargs, named):
    with pytest.raises(ValueError) as exc:
        gym.make(ID, **kwargs)
    msg = str(exc.value)
    assert named in msg and "\n" not in msg and ("allowed" in msg or "must" in msg or "known" in msg or "; use " in msg)


def test_a_burst_beyond_the_maps_burst_lengths_is_reported_in_info(tmap, tmp_path):
    """A map cut at the rising branch's peak (3.75 s) and corrections of +50 %: the corrected bursts read the map
    beyond its longest burst, which ``info`` reports (and the nominal map does not)."""
    doc = json.loads(default_turn_map("faithful").read_text())
    doc["points"] = [p for p in doc["points"] if p["t_c"] <= 3.75]
    cut = tmp_path / "cut.json"
    cut.write_text(json.dumps(doc))
    kw = {"paths": [ONE_TURN], "limits": {"max_dtc_fraction": 0.5}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = _episode(gym.make(ID, turn_map=str(cut), **kw), 0, [np.array([1.0, 0.0], np.float32)])
    info = out[-1][2]
    assert info["out_of_range"] is True and "beyond its calibrated burst lengths [0, 3.75] s" in \
        info["out_of_range_reason"]
    nominal = _episode(gym.make(ID, **kw), 0, [np.array([1.0, 0.0], np.float32)])
    assert all(step[2]["out_of_range"] is False for step in nominal)


def test_the_compiled_candidate_misses_are_the_planners_numpy_formulas(tmap):
    planner = RulePlanner(tmap, None, 0.1, 0.015, None)
    _, theta, psi, off = planner._candidates
    beta = planner._burst_phases
    rng = np.random.default_rng(0)
    for _ in range(20):
        head, target = rng.normal(0, 0.05, 3), rng.normal(0, 0.1, 3)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        e1, e2 = perpendicular_basis(d)
        fast = candidate_miss(candidate_frames(theta, psi, off, beta), *local_target(head, d, e1, e2, target),
                              BEHIND_PENALTY_M)
        slow, _ = candidate_misses(head, d, theta, psi, off, beta, target, paper_line_miss)
        np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)


def test_the_first_improving_distance_is_where_a_candidate_first_gets_below_the_threshold(tmap):
    """On targets ahead and off the line: below the threshold at x (and at 0 if x = 0), above it just before."""
    planner = RulePlanner(tmap, None, 0.1, 0.015, None)
    _, theta, psi, off = planner._candidates
    beta = planner._burst_phases
    head, d = np.zeros(3), np.array([1.0, 0.0, 0.0])
    e1, e2 = perpendicular_basis(d)

    frames = candidate_frames(theta, psi, off, beta)

    def best(at, target):
        return candidate_miss(frames, *local_target(head + at * d, d, e1, e2, target), BEHIND_PENALTY_M).min()

    later = 0  # with the real map the best turn improves at once or not before the target is abeam
    for ahead in (0.02, 0.04, 0.08, 0.16):
        for lateral in (0.01, 0.02, 0.04):
            target = np.array([ahead, lateral, 0.3 * lateral])
            lat = float(np.hypot(lateral, 0.3 * lateral))
            threshold = lat - 0.005
            x = first_improving_distance(frames, *local_target(head, d, e1, e2, target), BEHIND_PENALTY_M,
                                         threshold, 0.0, ahead)
            if x == 0.0:
                assert best(0.0, target) <= threshold
            elif math.isfinite(x):
                later += 1
                assert best(x - 2e-4, target) > threshold >= best(x + 1e-7, target) - 1e-12
            else:
                assert all(best(a, target) > threshold for a in np.linspace(0.0, ahead, 41))
    # one candidate whose answer is known: a 90 deg turn towards e1 = +z with no displacement, the target 10 cm
    # ahead and 5 cm up: the turned ray misses it by |0.1 - x|, below 4.5 cm from x = 5.5 cm on
    one = (np.array([math.pi / 2]), np.array([0.0]), np.zeros((1, 3)), np.array([0.0]))
    target = np.array([0.1, 0.0, 0.05])
    assert np.allclose(e1, [0.0, 0.0, 1.0])
    x = first_improving_distance(candidate_frames(*one), *local_target(head, d, e1, e2, target), BEHIND_PENALTY_M,
                                 0.045, 0.0, 0.1)
    assert x == pytest.approx(0.055, abs=1e-12)


def test_the_calibrated_range_holds_the_physics_envs_randomisation():
    lo, hi = FACTOR_RANGE
    r = RandomizationConfig()
    for f in (r.youngs_modulus, r.viscosity, r.head_radius, r.geometry):
        assert lo <= 1.0 - f and 1.0 + f <= hi
