"""The online correction of the turn map (agents.online_turn_map) and the planner that uses it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from agents.adaptive_planner import AdaptivePlanner
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap, shift_reading
from agents.turn_map import TurnMap
from agents.turn_measurement import CruiseObservables, summarise_cruise

#: a frozen turn map (faithful preset, 150 rpm bursts, torque-free head): the numbers below were read off it
MAP_150_RPM = Path(__file__).parent / "data" / "turn_map_150rpm.json"

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
    return TurnMap.load(MAP_150_RPM)


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


def test_outcomes_are_shifted_and_spread_by_the_timing_error(faithful_map):
    cfg = OnlineMapConfig(prior_shift_std_s=0.6, fly_by_ratio=False)
    om = OnlineTurnMap(faithful_map, cfg)
    dt = 0.1
    out = om.outcomes(dt)
    t_all, th_all, _ = faithful_map.theta_curve()
    nodes = np.array([-math.sqrt(3.0), 0.0, math.sqrt(3.0)])
    assert out.t_fly.min() >= dt - 1e-12 and out.map_t.max() <= om.t_peak_s + 1e-9
    assert out.theta.shape == out.psi.shape == out.direction_std.shape == out.direction_anything.shape == (
        out.t_fly.size, 3)
    assert out.offset.shape == (out.t_fly.size, 3, 3) and out.weights.sum() == pytest.approx(1.0)
    # the middle point is the map's turn at the planned time; the others at +-sqrt(3) sigma, read over
    # the whole map (past the peak: the tumbling turns)
    k = int(np.argmin(np.abs(out.map_t - 7.0)))
    for j in range(3):
        want = np.interp(out.map_t[k] + nodes[j] * 0.6, np.r_[0.0, t_all], np.r_[0.0, th_all])
        assert math.degrees(out.theta[k, j]) == pytest.approx(want)
    last = out.theta[-1]
    assert math.degrees(last[1]) > 0.85 * faithful_map.max_theta_deg and last[2] < last[1]  # past the peak: less
    # certain and early-buckling swimmer: flown shorter for the same map time and turn
    om.shift_s, om.shift_var = 0.5, 1e-8
    out1 = om.outcomes(dt)
    k = int(np.argmin(np.abs(out1.map_t - 6.0)))
    assert out1.t_fly[k] == pytest.approx(out1.map_t[k] - 0.5)
    assert np.ptp(out1.theta[k]) < 1e-3  # (almost) no timing spread left
    assert math.degrees(out1.psi[k, 1]) % 360 == pytest.approx(faithful_map.psi_for(out1.map_t[k]) % 360, abs=1e-6)


def test_flying_by_ratio_the_timing_spread_is_the_bias(faithful_map):
    om = OnlineTurnMap(faithful_map)
    om.shift_var, om.bias_var = 0.9 ** 2, 0.2 ** 2
    assert om.timing_std_s == pytest.approx(0.2)
    assert OnlineTurnMap(faithful_map, OnlineMapConfig(fly_by_ratio=False)).timing_std_s == pytest.approx(1.1)


def test_config_is_validated():
    with pytest.raises(ValueError, match="prior_shift_std_s"):
        OnlineMapConfig(prior_shift_std_s=0.0)
    with pytest.raises(ValueError, match="large_turn_deg"):
        OnlineMapConfig(large_turn_deg=-1.0)
    with pytest.raises(ValueError, match="direction_std_deg"):
        OnlineMapConfig(direction_std_deg=0.0)


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
    # capped bursts and the swimmer of the retired coarse preset overshot the second waypoint and circled it (measured).
    path = path_from_waypoints([[0.02, 0.0, 0.0], [0.12, 0.173, 0.0]], name="one_turn_long", reach_radius_m=0.015)
    env = FlagellumSteerEnv(path=path, preset="faithful", control_dt=0.1)
    planner = make_controller("adaptive", env, "faithful")
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
    assert turns[0]["follows_model"] and planner.online_map.follows_model  # the map's swimmer, its turns as mapped


def test_direction_spread_grows_with_the_turn_until_turns_confirm_the_map(faithful_map):
    om = OnlineTurnMap(faithful_map, OnlineMapConfig(lift_after_turns=2, fly_by_ratio=False))

    def spread(theta_deg: float) -> tuple[float, float]:
        std, anything = om.direction_spread(np.radians(theta_deg))
        return round(math.degrees(float(std)), 9), round(float(anything), 9)

    assert spread(30.0) == spread(80.0) == (20.0, 0.0)
    assert spread(90.0) == (20.0, 0.5) and spread(100.0) == spread(160.0) == (20.0, 1.0)
    om.observe(7.0, 57.0, math.radians(5.0), planned_theta_deg=59.0)  # confirms (1 of 2)
    om.observe(4.0, 30.0, math.radians(40.0), planned_theta_deg=10.0)  # too small to say anything
    assert om.confirmed == 1 and spread(160.0) == (20.0, 1.0)
    om.observe(7.0, 66.0, math.radians(-8.0), planned_theta_deg=59.0)  # within 10 deg + 15 %
    # confirmed by turns of 59 deg: narrow up to 80 deg (the unconfirmed ramp's start) and ramping from there;
    # turns 20 deg beyond the largest confirming one
    assert om.map_confirmed and spread(30.0) == spread(80.0) == (10.0, 0.0)
    assert spread(90.0) == (10.0, 0.5) and spread(160.0) == (10.0, 1.0)
    om.observe(7.6, 118.0, math.radians(-3.0), planned_theta_deg=112.0)  # a larger turn confirms too
    assert om.confirmed == 3 and om.confirmed_upto_deg == pytest.approx(112.0)
    assert spread(132.0) == (10.0, 0.0) and spread(142.0) == (10.0, 0.5) and spread(160.0) == (10.0, 1.0)
    om.observe(7.0, 59.0, math.radians(30.0), planned_theta_deg=59.0)  # heading 30 deg off the prediction
    assert not om.map_confirmed and spread(160.0) == (20.0, 1.0)
    om.observe(7.0, 59.0, math.radians(2.0), planned_theta_deg=59.0)
    om.observe(7.0, 85.0, math.radians(2.0), planned_theta_deg=59.0)  # turned 26 deg more than planned
    assert om.confirmed == 0 and not om.map_confirmed
    never = OnlineTurnMap(faithful_map, OnlineMapConfig(lift_after_turns=0, fly_by_ratio=False))
    for _ in range(4):
        never.observe(7.0, 59.0, 0.0, planned_theta_deg=59.0)
    assert not never.map_confirmed


def test_a_cruise_like_the_maps_swimmer_is_taken_for_it_until_a_turn_contradicts_the_map(faithful_map):
    ref = _cruise(4.6e-3, -0.667)
    matched = OnlineTurnMap(faithful_map, OnlineMapConfig(fly_by_ratio=False))
    rec = matched.observe_cruise(_cruise(4.6e-3 * 1.004, -0.667 * 0.993), ref)  # within 1 % in both
    assert rec["cruise_matched"] and matched.follows_model
    matched.observe(4.0, 5.0, math.radians(40.0), planned_theta_deg=10.0)  # too small to say anything
    matched.observe(7.0, 61.0, math.radians(8.0), planned_theta_deg=59.0)  # as the map says
    assert matched.follows_model
    matched.observe(7.0, 59.0, math.radians(30.0), planned_theta_deg=59.0)  # 30 deg off: not the map's swimmer
    assert not matched.follows_model
    matched.observe(7.0, 59.0, math.radians(1.0), planned_theta_deg=59.0)  # for good, whatever follows
    assert not matched.follows_model
    for seen in (_cruise(4.6e-3 * 1.02, -0.667), _cruise(4.6e-3, -0.667 * 1.012)):  # one of them off by > 1 %
        off = OnlineTurnMap(faithful_map, OnlineMapConfig(fly_by_ratio=False))
        assert not off.observe_cruise(seen, ref)["cruise_matched"] and not off.follows_model
    om = OnlineTurnMap(faithful_map, OnlineMapConfig(cruise_match_tol=0.0))  # switched off
    assert not om.observe_cruise(ref, ref)["cruise_matched"] and not om.follows_model
    om.reset()
    assert not om.follows_model


def test_ratio_branch_inverts_and_a_burst_plan_targets_it(faithful_map):
    om = OnlineTurnMap(faithful_map)
    t, r = om._ratio
    assert r[0] == pytest.approx(OnlineMapConfig().ratio_valid) and np.all(np.diff(r) <= 0.0)
    for m in (5.5, 6.5, 7.4):
        assert om.map_time_for_ratio(om.ratio_for(m)) == pytest.approx(m)
        assert om.clock_reading(om.ratio_for(m)) == pytest.approx(m)
    assert om.ratio_for(3.0) is None and om.map_time_for_ratio(1.01) is None  # not buckled yet
    assert om.clock_reading(1.01) is None
    om.shift_s, om.bias_s = 0.4, 0.1
    plan = om.burst_plan(6.0)
    assert plan["map_t"] == pytest.approx(6.4) and plan["clock_map_t"] == pytest.approx(6.3)
    assert plan["max_burst_s"] > 6.0 - 0.1
    # past the map's recorded ratios the burst is still timed by the clock (from its last reading)
    assert om.burst_plan(om.t_peak_s)["clock_map_t"] == pytest.approx(om.t_peak_s + 0.4 - 0.1)
    assert OnlineTurnMap(faithful_map, OnlineMapConfig(fly_by_ratio=False)).burst_plan(6.0)["clock_map_t"] is None


def test_a_burst_planned_to_end_before_buckling_shows_is_flown_by_time(faithful_map):
    # L'/L leaves ratio_valid only at the map's first ratio time (~4.9 s at faithful): a burst planned to stop
    # before it would wait for a clock reading that never comes and be cut at its longest length instead
    # (development: small corrections planned at 4.2 s flew 4.9 s and turned ~10 deg instead of ~5)
    om = OnlineTurnMap(faithful_map)
    t_on = float(om._ratio[0][0])
    assert 4.0 < t_on < 6.0, "the map's buckling time moved: the test lost its subject"
    assert om.burst_plan(t_on - 0.7)["clock_map_t"] is None
    assert om.burst_plan(t_on + 0.1)["clock_map_t"] == pytest.approx(t_on + 0.1)
    om.shift_s, om.bias_s = 0.5, 0.0  # an early buckler: the same burst reaches the clock's range in map time
    assert om.burst_plan(t_on - 0.4)["clock_map_t"] == pytest.approx(t_on + 0.1)
    # flown by time, the burst lasts its planned steps
    planner = _burst_planner(faithful_map)
    ep = planner._new_episode()
    ep.turns.append({"t_c": 4.2, "burst_step": 0, "clock_map_t": None, "max_burst_s": 4.9})
    ep.burst_left = round(4.2 / 0.1) - 1
    assert _fly(planner, ep, [1.0] * 80) == 42 and ep.turns[-1]["stopped_by"] == "time"


def test_the_ratio_clock_says_nothing_where_the_ratio_pauses(faithful_map):
    # the faithful map's L'/L pauses at ~0.478 from 7.6 to 7.8 s while the turn grows from 102 to 128 deg
    om = OnlineTurnMap(faithful_map)
    t, r = om._ratio
    flat = [k for k in range(1, len(t)) if r[k - 1] - r[k] < om.config.clock_slope_per_s * (t[k] - t[k - 1])]
    assert any(t[k] > 7.55 for k in flat), "the map has no pause after 7.5 s: the test lost its subject"
    for k in flat:
        if r[k - 1] > r[k]:
            assert om.clock_reading(0.5 * (r[k - 1] + r[k])) is None
    for k in range(1, len(t)):
        if k not in flat:
            assert om.clock_reading(0.5 * (r[k - 1] + r[k])) == pytest.approx(0.5 * (t[k - 1] + t[k]))


def test_turn_flown_by_ratio_reads_shift_from_ratio_and_bias_from_angle(faithful_map):
    om = OnlineTurnMap(faithful_map)
    t_b, th_b = faithful_map.rising_branch()
    # the swimmer reached the map's ratio of 6.5 s after 6.0 s (buckles 0.5 s early) and turned
    # the map's angle at 6.7 s (the ratio-turn relation is off by 0.2 s)
    rec = om.observe(6.0, float(np.interp(6.7, t_b, th_b)), None, ratio_end=om.ratio_for(6.5))
    assert rec["shift_reading_s"] == pytest.approx(0.5, abs=1e-6)
    assert rec["bias_reading_s"] == pytest.approx(0.2, abs=1e-6)
    assert 0.4 < om.shift_s < 0.5 and 0.0 < om.bias_s < 0.2
    # the clock read during the burst instead of at its end: the same readings
    clocked = OnlineTurnMap(faithful_map).observe(6.0, float(np.interp(6.7, t_b, th_b)), None, ratio_end=0.47,
                                                  clock_shift_s=0.5)
    assert clocked["shift_reading_s"] == pytest.approx(0.5) and clocked["bias_reading_s"] == pytest.approx(0.2, abs=1e-6)
    # without a buckled ratio the angle reads the shift, as before
    plain = OnlineTurnMap(faithful_map)
    rec = plain.observe(6.0, float(np.interp(6.7, t_b, th_b)), None, ratio_end=1.02)
    assert rec["shift_reading_s"] == pytest.approx(0.7, abs=1e-6) and "bias_reading_s" not in rec


def _burst_planner(faithful_map):
    from agents.adaptive_planner import AdaptivePlanner
    from agents.turn_planner import ObservationLayout

    layout = ObservationLayout(slice(1, 4), slice(4, 13), slice(13, 37), 0.13, 1)
    return AdaptivePlanner(faithful_map, layout, 0.1, 0.015, lambda rpm: rpm, end_slice=slice(0, 1))


def _fly(planner, ep, ratios):
    obs = np.zeros(37)
    for k, r in enumerate(ratios, start=1):
        ep.step, obs[0] = k, r
        if not planner._continue_burst(ep, obs):
            return k
    return None


@pytest.mark.parametrize("clock_t, shift", [(6.6, 0.0), (6.6, 0.4), (7.4, -0.3), (7.7, 0.3), (7.75, -0.2)])
def test_burst_ends_when_the_ratio_clock_reaches_the_planned_map_time(faithful_map, clock_t, shift):
    # a swimmer that is the map shifted by ``shift`` (s > 0: buckles early): the burst ends at the step nearest
    # to clock_t - shift, also on a pause of L'/L (7.7 s), where the last reading before the pause times it
    planner = _burst_planner(faithful_map)
    om = OnlineTurnMap(faithful_map)
    ratios = [om.ratio_for(0.1 * k + shift) or 1.0 for k in range(1, 120)]
    ep = planner._new_episode()
    ep.turns.append({"t_c": clock_t - shift, "burst_step": 0, "clock_map_t": clock_t, "max_burst_s": clock_t - shift + 1.0})
    k = _fly(planner, ep, ratios)
    turn = ep.turns[-1]
    assert turn["stopped_by"] == "ratio" and k == round((clock_t - shift) / 0.1)
    assert turn["clock_shift_s"] == pytest.approx(shift, abs=0.03)


def test_burst_without_buckling_is_cut_at_the_longest_burst(faithful_map):
    planner = _burst_planner(faithful_map)
    ep = planner._new_episode()
    ep.turns.append({"t_c": 1.0, "burst_step": 0, "clock_map_t": 6.0, "max_burst_s": 1.2})
    assert _fly(planner, ep, [1.0] * 20) == 12 and ep.turns[-1]["stopped_by"] == "time"
    assert "clock_shift_s" not in ep.turns[-1]


def test_graded_miss_rewards_turning_towards_a_target_behind():
    from agents.turn_planner import paper_line_miss, graded_line_miss

    target = np.array([-0.1, 0.0, 0.0])
    angles = np.radians([0.0, 30.0, 60.0, 85.0])  # the target 180, 150, 120 and 95 deg off the heading
    dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros(4)], axis=1)
    starts = np.zeros((4, 3))
    graded = graded_line_miss(starts, dirs, target)
    assert np.all(np.diff(graded) < 0.0)  # the nearer the heading points to the target, the smaller
    assert np.ptp(paper_line_miss(starts, dirs, target)) == 0.0  # the rule planner's measure cannot tell them apart
    ahead = np.array([[1.0, 0.0, 0.0]])
    assert graded_line_miss(np.zeros((1, 3)), ahead, np.array([0.1, 0.02, 0.0]))[0] == pytest.approx(0.02)
    # continuous abeam
    abeam = graded_line_miss(np.zeros((2, 3)), np.array([[0.0, 1.0, 0.0], [1e-9, 1.0, 0.0]]), target)
    assert abeam[0] == pytest.approx(abeam[1], abs=1e-9)


def test_a_late_buckler_may_burst_past_the_planned_length(faithful_map):
    # planned 6.0 s of map time with a longest burst of 6.2 s; the swimmer buckles 1 s late (its L'/L leaves
    # 0.98 at ~5.9 s instead of ~4.9 s): seen buckling, the burst may go on, and ends by the ratio clock at 7.0 s
    planner = _burst_planner(faithful_map)
    om = OnlineTurnMap(faithful_map)
    ratios = [om.ratio_for(0.1 * k - 1.0) or 1.0 for k in range(1, 120)]
    ep = planner._new_episode()
    ep.turns.append({"t_c": 6.0, "burst_step": 0, "clock_map_t": 6.0, "max_burst_s": 6.2})
    k = _fly(planner, ep, ratios)
    turn = ep.turns[-1]
    assert 5.8 < turn["onset_s"] < 6.1 and turn["max_burst_s"] > 7.0
    assert (k, turn["stopped_by"]) == (70, "ratio") and turn["clock_shift_s"] == pytest.approx(-1.0, abs=0.03)


def _planner(faithful_map, **adaptive):
    from agents.adaptive_planner import AdaptiveConfig
    from agents.turn_planner import ObservationLayout

    layout = ObservationLayout(slice(1, 4), slice(4, 13), slice(13, 37), 0.13, 1)
    p = AdaptivePlanner(faithful_map, layout, 0.1, 0.015, lambda rpm: rpm, adaptive=AdaptiveConfig(**adaptive))
    ep = p._new_episode()
    ep.cruise_used = True
    return p, ep


D, NODE = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.006, 0.0])


def test_large_turns_only_where_any_direction_will_do(faithful_map):
    p, ep = _planner(faithful_map)
    behind = p._plan_turn(np.zeros(3), D, np.array([-0.15, 0.0, 0.0]), NODE, ep)
    p, ep = _planner(faithful_map)
    abeam = p._plan_turn(np.zeros(3), D, np.array([0.0, 0.15, 0.0]), NODE, ep)
    # straight behind, a turn near the branch's peak points back whatever its direction; abeam, a turn
    # beyond ~80 deg (whose direction is not predictable before turns confirm the map) loses
    assert behind["theta_deg"] > 120.0 and 40.0 < abeam["theta_deg"] <= 85.0
    # once turns confirmed the map (direction spread 10 deg) and the timing is known, abeam takes the full turn
    p, ep = _planner(faithful_map)
    ep.online.confirmed, ep.online.bias_var = 2, 0.02 ** 2
    full = p._plan_turn(np.zeros(3), D, np.array([0.0, 0.15, 0.0]), NODE, ep)
    assert full["theta_deg"] > abeam["theta_deg"] + 5.0 and full["predicted_miss_m"] < abeam["predicted_miss_m"]


def test_expected_miss_without_spread_is_the_rule_planners_miss(faithful_map):
    from agents.adaptive_planner import expected_misses
    from agents.online_turn_map import TurnOutcomes
    from agents.turn_planner import graded_line_miss

    p, ep = _planner(faithful_map)
    om = ep.online
    om.bias_var = 1e-12
    out = om.outcomes(0.1)
    sharp = TurnOutcomes(out.t_fly, out.map_t, out.theta, out.psi, out.offset, np.zeros_like(out.direction_std),
                         np.zeros_like(out.direction_anything), out.weights)
    beta = np.radians(np.arange(0.0, 360.0, 5.0))
    target = np.array([0.05, 0.1, 0.02])
    score = expected_misses(np.zeros(3), D, target, sharp, beta, graded_line_miss, None, 0.06, 0.085)
    k, j = 20, 7
    theta, psi, off = out.theta[k, 1], out.psi[k, 1], out.offset[k, 1]
    e1, e2 = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    from agents.turn_geometry import perpendicular_basis
    e1, e2 = perpendicular_basis(D)
    e_ref = np.cos(beta[j]) * e1 + np.sin(beta[j]) * e2
    heading = np.cos(theta) * D + np.sin(theta) * (np.cos(beta[j] + psi) * e1 + np.sin(beta[j] + psi) * e2)
    after = off[0] * D + off[1] * e_ref + off[2] * np.cross(D, e_ref)
    assert score[k, j] == pytest.approx(graded_line_miss(after[None], heading[None], target)[0], abs=1e-9)
    # a segment far away: every head position is out of the corridor
    far = expected_misses(np.zeros(3), D, target, sharp, beta, graded_line_miss,
                          (np.array([0.0, 0.5, 0.0]), np.array([0.1, 0.5, 0.0])), 0.06, 0.085)
    assert np.all(far >= score + 0.5)


def test_swim_on_then_turn_for_a_target_just_behind(faithful_map):
    target = np.array([-0.04, 0.02, 0.0])
    p, ep = _planner(faithful_map)
    assert p._plan_turn(np.zeros(3), D, target, NODE, ep) is None  # swims on first ...
    assert ep.swim_until is not None and 0.0 < ep.swim_until[0] <= p.adaptive.swim_on_m + 1e-12
    assert p._plan_turn(0.5 * ep.swim_until, D, target, NODE, ep) is None  # ... and keeps swimming
    scale = p._miss_scale(p._miss_if_off_course(np.zeros(3), D, target))  # one scale for the decision
    now = p._best_turn(np.zeros(3), D, target, ep, np.inf, scale)
    later = p._best_turn(ep.swim_until, D, target, ep, np.inf, scale)
    assert later["predicted_miss_m"] + p.adaptive.swim_cost * ep.swim_until[0] < now["predicted_miss_m"]
    off, ep_off = _planner(faithful_map, swim_on_m=0.0)
    assert off._plan_turn(np.zeros(3), D, target, NODE, ep_off) is not None  # never swims on: turns now
    assert ep_off.swim_until is None


def test_swim_on_stops_at_the_soft_corridor(faithful_map):
    # the farther on, the better the turn: the swimmer swims on as far as it may, which is where the next
    # cm would leave the soft corridor (6 cm from the segment), not the hard one (8.5 cm) or swim_near_m (9 cm:
    # 7.4 cm here)
    target = np.array([0.0, 0.05, 0.0])
    p, ep = _planner(faithful_map)
    ep.segment = (np.zeros(3), target.copy())  # the head swims along D, straight away from the segment
    p._best_turn = lambda head, d, tgt, ep_, miss0, scale: {"predicted_miss_m": -float(head[0])}
    assert p._swim_on_first(np.zeros(3), D, target, ep, {"predicted_miss_m": 0.05}, 0.03)
    soft = p.adaptive.corridor_soft * p.adaptive.corridor_m  # checked every cm: within a cm of it
    assert ep.swim_until[1:] == pytest.approx([0.0, 0.0], abs=1e-15)
    assert soft - 0.01 - 1e-9 <= ep.swim_until[0] <= soft




def test_saturating_miss_is_the_miss_when_small_and_bounded_by_its_scale():
    from agents.adaptive_planner import AdaptiveConfig, saturating_miss

    m = np.array([0.0, 1e-4, 0.01, 0.03, 0.1, 1.0])
    s = saturating_miss(m, 0.03)
    assert s[0] == 0.0 and s[1] == pytest.approx(1e-4, rel=2e-3)
    assert np.all(np.diff(s) > 0.0) and np.all(s < 0.03) and np.all(s <= m)
    assert s[-1] == pytest.approx(0.03, rel=1e-12)
    assert np.array_equal(saturating_miss(m, math.inf), m)
    for bad in (0.0, -0.01, float("nan")):
        with pytest.raises(ValueError, match="miss_scale_m"):
            AdaptiveConfig(miss_scale_m=bad)


def test_saturated_score_takes_the_full_turn_that_a_linear_one_caps(faithful_map):
    # a target 10 cm away, 70 deg off the heading, before any turn confirmed the map: scored by the miss
    # itself the planner keeps to a predictable smaller turn (the unlikely wide misses of the larger one weigh
    # on the mean); with misses bounded by their scale those cost no more than another turn, and it turns further
    target = 0.1 * np.array([math.cos(math.radians(70.0)), math.sin(math.radians(70.0)), 0.0])
    p, ep = _planner(faithful_map, miss_scale_m=math.inf)
    linear = p._plan_turn(np.zeros(3), D, target, NODE, ep)
    p, ep = _planner(faithful_map)
    saturated = p._plan_turn(np.zeros(3), D, target, NODE, ep)
    assert saturated["theta_deg"] > linear["theta_deg"] + 5.0
