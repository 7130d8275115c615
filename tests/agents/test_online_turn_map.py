"""The online correction of the turn map (agents.online_turn_map) and the planner that uses it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.assets import default_turn_map
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap, shift_reading
from agents.turn_map import TurnMap
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
    cfg = OnlineMapConfig(caution=2.0, prior_shift_std_s=0.6)
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

    # one turn, then a segment long enough for the heading to settle (the turn is observed)
    path = path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.12, 0.0]], name="one_turn_long", reach_radius_m=0.015)
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
