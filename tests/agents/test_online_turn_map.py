"""The online correction of the turn map (agents.online_turn_map) and the planner that uses it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.assets import default_turn_map
from agents.adaptive_planner import AdaptivePlanner
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap, shift_reading
from agents.turn_map import TurnMap
from agents.turn_planner import RulePlanner
from flagellum_env.turn_measurement import CruiseObservables, summarise_cruise

# a rising branch: 0 deg at 0 s, 10 deg at 4 s, then 30 deg/s up to 130 deg at 8 s
T_BRANCH = np.array([0.0, 4.0, 8.0])
TH_BRANCH = np.array([0.0, 10.0, 130.0])


def _theta(t: float) -> float:
    return float(np.interp(t, T_BRANCH, TH_BRANCH))


@pytest.mark.parametrize("shift", [-0.8, -0.3, 0.0, 0.4, 0.9])
def test_shift_reading_inverts_the_branch(shift):
    cfg = OnlineMapConfig()
    t_c = 6.0
    s, std = shift_reading(T_BRANCH, TH_BRANCH, t_c, _theta(t_c + shift), cfg)
    assert s == pytest.approx(shift, abs=1e-12)
    theta = _theta(t_c + shift)
    assert std == pytest.approx((cfg.theta_noise_deg + cfg.theta_noise_fraction * theta) / 30.0)


def test_shift_reading_small_turn_says_nothing_and_beyond_the_peak_is_the_peak():
    cfg = OnlineMapConfig(min_theta_deg=6.0)
    assert shift_reading(T_BRANCH, TH_BRANCH, 6.0, 5.0, cfg) is None
    s, _ = shift_reading(T_BRANCH, TH_BRANCH, 6.0, 175.0, cfg)
    assert s == pytest.approx(2.0)  # the peak (8 s) minus the burst: a lower bound
    s, _ = shift_reading(T_BRANCH, TH_BRANCH, 6.0, 8.0, cfg)  # on the flat part: 8 deg at 3.2 s
    assert s == pytest.approx(3.2 - 6.0)


@pytest.fixture(scope="module")
def faithful_map() -> TurnMap:
    return TurnMap.load(default_turn_map("faithful"))


def test_readings_converge_to_the_swimmers_shift(faithful_map):
    om = OnlineTurnMap(faithful_map, OnlineMapConfig(prior_shift_std_s=0.6))
    assert om.shift_s == 0.0 and om.shift_std_s == pytest.approx(0.6)
    t_b, th_b = faithful_map.rising_branch()
    true_shift = 0.45
    stds = []
    for t_c in (5.5, 6.0, 6.5, 6.0):
        om.observe(t_c, float(np.interp(t_c + true_shift, t_b, th_b)))
        stds.append(om.shift_std_s)
    assert all(b < a for a, b in zip(stds, stds[1:]))  # every reading adds information
    assert om.shift_s == pytest.approx(true_shift, abs=0.05)  # the prior (0) pulls a little
    assert om.predicted_theta_deg(6.0) == pytest.approx(float(np.interp(6.0 + om.shift_s, t_b, th_b)))


def test_direction_offset_is_a_circular_mean(faithful_map):
    om = OnlineTurnMap(faithful_map)
    om.observe(6.5, 40.0, math.radians(175.0))
    # the next prediction used the offset of 175 deg; it was 10 deg short of the truth (-175 deg)
    om.observe(6.5, 40.0, math.radians(10.0))
    assert math.degrees(om.psi_offset_rad) == pytest.approx(180.0, abs=1e-9) or \
        math.degrees(om.psi_offset_rad) == pytest.approx(-180.0, abs=1e-9)
    small = OnlineTurnMap(faithful_map)
    small.observe(6.0, 10.0, math.radians(90.0))  # too small a turn for a direction reading
    assert small.psi_offset_rad == 0.0


def test_candidates_are_shifted_and_capped_below_the_peak(faithful_map):
    cfg = OnlineMapConfig(caution=2.0, prior_shift_std_s=0.6, max_turn_deg=180.0, fly_by_ratio=False)
    om = OnlineTurnMap(faithful_map, cfg)
    dt = 0.1
    t0, th0, psi0, off0 = om.candidates(dt)
    assert t0.max() <= om.t_peak_s - 2.0 * 0.6 + 1e-9 and t0.min() >= dt - 1e-12
    assert np.all(np.diff(th0) >= 0.0) and off0.shape == (t0.size, 3)
    # certain and early-buckling swimmer: flown shorter, allowed up to the peak
    om.shift_s, om.shift_var = 0.5, 1e-6
    t1, th1, psi1, _ = om.candidates(dt)
    assert om.t_peak_s - dt - 2e-3 < t1[-1] + 0.5 <= om.t_peak_s  # within a step of the peak
    assert math.degrees(th1[-1]) > 0.85 * faithful_map.max_theta_deg
    assert t1.min() >= dt - 1e-12
    # same map time -> same turn, flown 0.5 s shorter
    k = int(np.argmin(np.abs(t1 + 0.5 - 6.0)))
    assert math.degrees(th1[k]) == pytest.approx(float(np.interp(t1[k] + 0.5, *faithful_map.rising_branch())))
    assert math.degrees(psi1[k]) % 360 == pytest.approx(faithful_map.psi_for(t1[k] + 0.5) % 360, abs=1e-6)


def test_config_is_validated():
    with pytest.raises(ValueError, match="prior_shift_std_s"):
        OnlineMapConfig(prior_shift_std_s=0.0)
    with pytest.raises(ValueError, match="caution"):
        OnlineMapConfig(caution=-1.0)


def test_summarise_cruise_recovers_rate_and_its_error():
    rng = np.random.default_rng(1)
    t = np.arange(91) * 0.1
    az = np.angle(np.exp(1j * (-0.667 * t + 0.3)))  # wrapped, as measured
    clean = summarise_cruise(np.full(91, 4.6e-3), az, 0.1)
    assert clean.rotation_rate == pytest.approx(-0.667, abs=1e-9) and clean.rotation_rate_std < 1e-9
    assert clean.strain == pytest.approx(4.6e-3) and clean.samples == 91
    noisy = summarise_cruise(4.6e-3 + 1e-4 * rng.standard_normal(91), az + 0.05 * rng.standard_normal(91), 0.1)
    expected_std = 0.05 * math.sqrt(12.0 / 91) / 9.0  # sigma sqrt(12 / (n T^2)) for a least-squares slope
    assert noisy.rotation_rate_std == pytest.approx(expected_std, rel=0.3)
    assert abs(noisy.rotation_rate + 0.667) < 4 * expected_std
    assert noisy.strain_sem == pytest.approx(1e-4 / math.sqrt(91), rel=0.3)
    with pytest.raises(ValueError, match="at least 3"):
        summarise_cruise(np.zeros(2), np.zeros(2), 0.1)


def _cruise(strain: float, rate: float, strain_sem: float = 0.0, rate_std: float = 0.0) -> CruiseObservables:
    return CruiseObservables(strain, strain_sem, rate, rate_std, 91)


def test_cruise_reading_moves_the_prior_and_noisy_readings_weigh_less(faithful_map):
    cfg = OnlineMapConfig(prior_shift_std_s=1.0, strain_shift_s=10.0, rate_shift_s=8.0, cruise_residual_std_s=0.3)
    ref = _cruise(4.6e-3, -0.667)
    clean = OnlineTurnMap(faithful_map, cfg)
    rec = clean.observe_cruise(_cruise(4.6e-3 * 1.05, -0.667 * 1.02), ref)
    assert rec["shift_reading_s"] == pytest.approx(10.0 * 0.05 + 8.0 * 0.02)
    w0, w = 1.0, 1 / 0.3 ** 2
    assert clean.shift_s == pytest.approx(w * 0.66 / (w0 + w))
    assert clean.shift_std_s == pytest.approx((w0 + w) ** -0.5)
    # sensor noise: standard errors of 1e-3 on L'/L and 0.05 rad/s on the rate swamp the signal
    noisy = OnlineTurnMap(faithful_map, cfg)
    noisy.observe_cruise(_cruise(4.6e-3 * 1.05, -0.667 * 1.02, 1e-3, 0.05), ref)
    assert noisy.shift_std_s > 0.9 and abs(noisy.shift_s) < 0.25 * clean.shift_s
    few = CruiseObservables(4.6e-3, 0.0, -0.667, 0.0, 5)
    assert OnlineTurnMap(faithful_map, cfg).observe_cruise(few, ref) is None  # too few samples


def test_adaptive_planner_reads_the_nominal_swimmer_as_nominal_and_learns_from_its_turns():
    from agents.path_following import make_controller, run_episode
    from flagellum_env.paths import path_from_waypoints
    from flagellum_env.steer_env import FlagellumSteerEnv

    # one turn of 60 deg (within the planner's 80 deg cap for one burst), then a segment long enough
    # for the heading to settle (the turn is observed). A 90 deg turn 2 cm from the start needs two
    # capped bursts and the coarse swimmer overshoots the second waypoint (measured; see
    # docs/robust_steering.md for the circling it then does).
    path = path_from_waypoints([[0.02, 0.0, 0.0], [0.12, 0.173, 0.0]], name="one_turn_long", reach_radius_m=0.015)
    env = FlagellumSteerEnv(path=path, preset="coarse", control_dt=0.1)
    planner = make_controller("adaptive", env, "coarse")
    metrics, _ = run_episode(env, planner, path)
    assert metrics["success"], metrics
    readings = planner.online_map.readings
    cruise = readings[0]
    # the env starts from the very steady state the reference was measured on (float32 observations)
    assert abs(cruise["strain_relative_change"]) < 1e-3 and abs(cruise["rate_relative_change"]) < 1e-3
    assert abs(cruise["shift_reading_s"]) < 0.02
    turns = planner.turns
    assert turns and "observed_theta_deg" in turns[0]
    assert len(readings) == 1 + sum("observed_theta_deg" in t for t in turns)
    assert turns[0]["shift_std_s"] < OnlineMapConfig().prior_shift_std_s  # the cruise reading informed it


def test_candidates_never_plan_more_than_max_turn(faithful_map):
    om = OnlineTurnMap(faithful_map, OnlineMapConfig(max_turn_deg=60.0))
    om.shift_var = 1e-8  # certain: only the angle cap binds
    _, theta, _, _ = om.candidates(0.1)
    assert math.degrees(theta.max()) <= 60.0 + 1e-9 and math.degrees(theta.max()) > 50.0


def test_confirming_turns_lift_the_cap_and_a_surprise_restores_it(faithful_map):
    om = OnlineTurnMap(faithful_map, OnlineMapConfig(max_turn_deg=60.0, lift_after_turns=2, fly_by_ratio=False))
    om.shift_var = 1e-8  # certain: only the angle cap binds while it applies

    def largest() -> float:
        return math.degrees(om.candidates(0.1)[1].max())

    assert largest() <= 60.0 + 1e-9
    om.observe(7.0, 57.0, math.radians(5.0), planned_theta_deg=59.0)  # confirms (1 of 2)
    om.observe(4.0, 30.0, math.radians(40.0), planned_theta_deg=10.0)  # too small to say anything
    assert largest() <= 60.0 + 1e-9 and om.confirmed == 1
    om.observe(7.0, 66.0, math.radians(-8.0), planned_theta_deg=59.0)  # within 10 deg + 15 %
    assert om.cap_lifted and largest() > 120.0
    om.observe(7.0, 59.0, math.radians(30.0), planned_theta_deg=59.0)  # heading 30 deg off the prediction
    assert not om.cap_lifted and largest() <= 60.0 + 1e-9
    om.observe(7.0, 59.0, math.radians(2.0), planned_theta_deg=59.0)
    om.observe(7.0, 85.0, math.radians(2.0), planned_theta_deg=59.0)  # turned 26 deg more than planned
    assert om.confirmed == 0 and not om.cap_lifted
    never = OnlineTurnMap(faithful_map, OnlineMapConfig(max_turn_deg=60.0, lift_after_turns=0, fly_by_ratio=False))
    never.shift_var = 1e-8
    for _ in range(4):
        never.observe(7.0, 59.0, 0.0, planned_theta_deg=59.0)
    assert math.degrees(never.candidates(0.1)[1].max()) <= 60.0 + 1e-9


def test_ratio_branch_inverts_and_a_burst_plan_targets_it(faithful_map):
    om = OnlineTurnMap(faithful_map)
    t, r = om._ratio
    assert r[0] == pytest.approx(OnlineMapConfig().ratio_valid) and np.all(np.diff(r) < 0.0)
    for m in (5.5, 6.5, 7.2):
        assert om.map_time_for_ratio(om.ratio_for(m)) == pytest.approx(m)
    assert om.ratio_for(3.0) is None and om.map_time_for_ratio(1.01) is None  # not buckled yet
    om.shift_s, om.bias_s = 0.4, 0.1
    plan = om.burst_plan(6.0)
    assert plan["map_t"] == pytest.approx(6.4)
    assert plan["target_ratio"] == pytest.approx(om.ratio_for(6.3))
    assert plan["max_burst_s"] > 6.0 - 0.1


def test_turn_flown_by_ratio_reads_shift_from_ratio_and_bias_from_angle(faithful_map):
    om = OnlineTurnMap(faithful_map)
    t_b, th_b = faithful_map.rising_branch()
    # the swimmer reached the map's ratio of 6.5 s after 6.0 s (buckles 0.5 s early) and turned
    # the map's angle at 6.7 s (the ratio-turn relation is off by 0.2 s)
    rec = om.observe(6.0, float(np.interp(6.7, t_b, th_b)), None, ratio_end=om.ratio_for(6.5))
    assert rec["shift_reading_s"] == pytest.approx(0.5, abs=1e-6)
    assert rec["bias_reading_s"] == pytest.approx(0.2, abs=1e-6)
    assert 0.4 < om.shift_s < 0.5 and 0.0 < om.bias_s < 0.2
    # without a buckled ratio the angle reads the shift, as before
    plain = OnlineTurnMap(faithful_map)
    rec = plain.observe(6.0, float(np.interp(6.7, t_b, th_b)), None, ratio_end=1.02)
    assert rec["shift_reading_s"] == pytest.approx(0.7, abs=1e-6) and "bias_reading_s" not in rec


def _burst_planner(faithful_map):
    from agents.adaptive_planner import AdaptivePlanner
    from agents.turn_planner import ObservationLayout

    layout = ObservationLayout(slice(1, 4), slice(4, 13), slice(13, 37), 0.13, 1)
    return AdaptivePlanner(faithful_map, layout, 0.1, 0.015, lambda rpm: rpm, end_slice=slice(0, 1))


@pytest.mark.parametrize("t_c, ratios, target, stop_after, why", [
    (0.6, [1.0, 0.9, 0.8, 0.7, 0.6, 0.5], 0.71, 4, "ratio"),      # 0.70 is nearest to 0.71
    (0.6, [1.0, 0.9, 0.8, 0.7, 0.6, 0.5], 0.76, 3, "ratio"),      # 0.80 is nearer to 0.76 than 0.70 would be
    (1.0, [1.0] * 20, 0.7, 12, "time"),                           # never buckles: cut at the longest burst
    (1.0, [0.5] * 20, 0.7, 5, "ratio"),                           # low from the start: not before half the plan
])
def test_burst_ends_at_the_ratio_crossing_or_the_longest_burst(faithful_map, t_c, ratios, target, stop_after, why):
    planner = _burst_planner(faithful_map)
    ep = planner._new_episode()
    ep.turns.append({"t_c": t_c, "burst_step": 0, "target_ratio": target, "max_burst_s": 1.2})
    obs = np.zeros(37)
    for k, r in enumerate(ratios, start=1):
        ep.step = k
        obs[0] = r
        if not planner._continue_burst(ep, obs):
            break
    assert (k, ep.turns[-1]["stopped_by"]) == (stop_after, why)
    assert ep.turns[-1]["burst_s"] == pytest.approx(0.1 * stop_after)


def test_graded_miss_rewards_turning_towards_a_target_behind():
    from agents.turn_planner import _line_miss, graded_line_miss

    target = np.array([-0.1, 0.0, 0.0])
    angles = np.radians([0.0, 30.0, 60.0, 85.0])  # the target 180, 150, 120 and 95 deg off the heading
    dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros(4)], axis=1)
    starts = np.zeros((4, 3))
    graded = graded_line_miss(starts, dirs, target)
    assert np.all(np.diff(graded) < 0.0)  # the nearer the heading points to the target, the smaller
    assert np.ptp(_line_miss(starts, dirs, target)) == 0.0  # the rule planner's measure cannot tell them apart
    ahead = np.array([[1.0, 0.0, 0.0]])
    assert graded_line_miss(np.zeros((1, 3)), ahead, np.array([0.1, 0.02, 0.0]))[0] == pytest.approx(0.02)
    # continuous abeam
    abeam = graded_line_miss(np.zeros((2, 3)), np.array([[0.0, 1.0, 0.0], [1e-9, 1.0, 0.0]]), target)
    assert abeam[0] == pytest.approx(abeam[1], abs=1e-9)


def _coarse_adaptive(**kw):
    from flagellum_env.paths import path_from_waypoints
    from flagellum_env.steer_env import FlagellumSteerEnv

    path = path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], name="one_turn", reach_radius_m=0.015)
    env = FlagellumSteerEnv(path=path, preset="coarse", control_dt=0.2)
    tmap = TurnMap.load(default_turn_map("coarse"))
    base = RulePlanner.for_env(env, tmap)
    return AdaptivePlanner(tmap, base.layout, base.control_dt, base.reach_radius_m, base.action_of, **kw)


def test_swim_on_then_turn_for_a_target_just_behind_once_large_turns_are_allowed(faithful_map):
    base = _coarse_adaptive()
    d, node = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.006, 0.0])
    target = np.array([-0.06, 0.02, 0.03])

    def planner(swim_on_m: float, lifted: bool):
        p = AdaptivePlanner(faithful_map, base.layout, 0.1, 0.015, base.action_of, swim_on_m=swim_on_m,
                            online=OnlineMapConfig(lift_after_turns=2))
        ep = p._new_episode()
        ep.cruise_used = True
        if lifted:  # two confirming turns seen, the ratio-turn bias known to 0.05 s
            ep.online.confirmed, ep.online.bias_var = 2, 0.05 ** 2
        return p, ep

    p, ep = planner(0.08, lifted=True)
    hit = p.config.hit_fraction * p.reach_radius_m
    now = RulePlanner._plan_turn(p, np.zeros(3), d, target, node, ep)
    assert now is not None and now["predicted_miss_m"] > hit and now["theta_deg"] > 100.0
    plan = dict(now)
    assert p._swim_on_first(np.zeros(3), d, target, node, ep, plan)
    later = RulePlanner._plan_turn(p, plan["swim_on_m"] * d, d, target, node, ep)
    assert 0.0 < plan["swim_on_m"] <= 0.08 and later["predicted_miss_m"] <= hit
    assert p._plan_turn(np.zeros(3), d, target, node, ep) is None  # so it cruises on this step
    off, ep_off = planner(0.0, lifted=True)
    assert not off._swim_on_first(np.zeros(3), d, target, node, ep_off, dict(now))
    capped, ep_capped = planner(0.08, lifted=False)  # turns of at most 80 deg never hit a target behind
    plan = RulePlanner._plan_turn(capped, np.zeros(3), d, target, node, ep_capped)
    assert plan["theta_deg"] <= 80.0 + 1e-9 and not capped._swim_on_first(np.zeros(3), d, target, node, ep_capped,
                                                                            dict(plan))
