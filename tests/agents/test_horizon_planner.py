"""The receding-horizon planner: its move search on a synthetic turn map, and one real episode."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from agents.horizon_planner import HorizonConfig, Situation, TurnModel, search
from agents.turn_geometry import perpendicular_basis


def _model(time_std: float = 0.05, psi_std_deg: float = 3.0, offset=(0.01, 0.0, 0.0), peak_deg: float = 180.0,
           peak_s: float = 8.0, tumble_deg: float | None = None) -> TurnModel:
    """theta rising linearly to ``peak_deg`` at ``peak_s`` (then, if ``tumble_deg`` is given, falling to it 1 s
    later while the direction swings round by 180 deg: the tumble past the peak), direction psi = 0 on the
    rising branch (the turn goes where the phase node points), a constant offset."""
    grid = np.arange(0.0, peak_s + 1.0 + 1e-9, 0.05)
    theta = np.radians(np.where(grid <= peak_s, peak_deg * grid / peak_s, peak_deg))
    if tumble_deg is not None:
        theta = np.where(grid <= peak_s, theta,
                         np.radians(peak_deg + (tumble_deg - peak_deg) * (grid - peak_s)))
    psi = np.zeros_like(grid)
    if tumble_deg is not None:
        psi = np.where(grid <= peak_s, 0.0, np.pi * np.clip(grid - peak_s, 0.0, 1.0))
    off = np.tile(np.asarray(offset, float), (len(grid), 1))
    off[0] = 0.0
    cand = np.arange(0.25, peak_s + 1e-9, 0.25)
    return TurnModel(grid, theta, psi, off, cand, np.full(len(cand), time_std),
                     math.radians(psi_std_deg))


def _sit(target, after=None, head=(0.0, 0.0, 0.0), planar=False) -> Situation:
    return Situation(head=np.asarray(head, float), heading=np.array([1.0, 0.0, 0.0]), target=np.asarray(target, float),
                     after=None if after is None else np.asarray(after, float), segment_start=np.zeros(3),
                     reach_m=0.015, planar=planar)


def _turn_direction(choice) -> np.ndarray:
    """Unit direction across the old heading (+x) the first burst turns towards."""
    e1, e2 = perpendicular_basis(np.array([1.0, 0.0, 0.0]))
    return math.cos(choice.azimuth) * e1 + math.sin(choice.azimuth) * e2


def test_target_straight_ahead_is_cruised_to():
    choice = search(_sit([0.15, 0.002, 0.0], after=[0.3, 0.0, 0.0]), _model(), HorizonConfig())
    assert not choice.burst
    assert choice.straight_cost < 0.005


def test_target_directly_behind_gives_a_turn_around_sequence():
    model = _model(peak_deg=100.0, peak_s=8.0)    # one burst turns at most 100 deg: two are needed
    choice = search(_sit([-0.15, 0.0, 0.0]), model, HorizonConfig())
    assert choice.burst and choice.cruise_m == 0.0
    assert choice.second is not None
    theta2 = model.at(np.array([choice.second[1]]))[0][0]
    assert math.degrees(choice.theta + theta2) > 150.0  # the two bursts turn the swimmer around
    assert math.degrees(choice.theta) > 60.0


def test_target_beside_is_turned_to_in_one_burst_where_the_map_fits():
    choice = search(_sit([0.02, 0.12, 0.0]), _model(offset=(0.005, 0.0, 0.0)), HorizonConfig())
    assert choice.burst
    assert 70.0 < math.degrees(choice.theta) < 110.0
    assert _turn_direction(choice)[1] > 0.95                 # towards +y


def test_uncertain_map_prefers_a_smaller_turn_than_a_certain_one():
    # a branch that tumbles past its peak (90 deg at 6 s, then down to 10 deg): aim for a target at ~85 deg
    kw = dict(peak_deg=90.0, peak_s=6.0, tumble_deg=10.0, offset=(0.005, 0.0, 0.0))
    sit = _sit([0.01, 0.12, 0.0])
    sure = search(sit, _model(time_std=0.02, **kw), HorizonConfig())
    unsure = search(sit, _model(time_std=0.6, **kw), HorizonConfig())
    assert sure.burst and unsure.burst
    assert math.degrees(sure.theta) > 75.0
    assert math.degrees(unsure.theta) < math.degrees(sure.theta) - 10.0


def test_planar_penalty_keeps_a_turn_around_in_the_plane():
    # straight behind: every turn direction is as good for the distance; on a planar path only the in-plane ones
    model = _model(peak_deg=180.0)
    choice = search(_sit([-0.15, 0.0, 0.0], planar=True), model, HorizonConfig())
    assert choice.burst
    assert abs(_turn_direction(choice)[2]) < math.sin(math.radians(15.0))


def test_planar_penalty_picks_the_phase_whose_offset_cancels_z_drift():
    # the burst displaces the head 2 cm along heading x (phase-node direction): an in-plane turn to the left
    # lifts the head by 2 cm, one to the right lowers it; the head is 1.5 cm above the plane
    model = _model(offset=(0.01, 0.0, 0.02), peak_deg=180.0)
    head = (0.0, 0.0, 0.015)
    choice = search(_sit([-0.15, 0.0, 0.0], head=head, planar=True), model, HorizonConfig())
    assert choice.burst
    direction = _turn_direction(choice)
    assert abs(direction[2]) < math.sin(math.radians(20.0))
    assert direction[1] < 0.0                                  # to the right: the offset points down
    # without the planar penalty the choice is free; with it the predicted head ends nearer the plane
    e_ref = direction                                          # psi = 0: the turn goes along the phase node
    z_after = head[2] + 0.02 * np.cross([1.0, 0.0, 0.0], e_ref)[2]
    assert abs(z_after) < 0.01


def test_search_is_cheap():
    from agents.assets import default_turn_map
    from agents.online_turn_map import OnlineTurnMap
    from agents.turn_map import TurnMap

    cfg = HorizonConfig()
    online = OnlineTurnMap(TurnMap.load(default_turn_map("faithful")))
    model = TurnModel.from_online(online, cfg.map_time_step_s, cfg.min_turn_deg, cfg.psi_prior_std_deg, 0.1,
                                  cfg.time_floor_s)
    sit = _sit([0.05, 0.12, 0.0], after=[0.05, 0.25, 0.0], planar=True)
    search(sit, model, cfg)
    t0 = time.process_time()
    for _ in range(3):
        search(sit, model, cfg)
    assert (time.process_time() - t0) / 3 < 0.5   # s of CPU per search (~0.05 s measured); a turn takes ~50 s


def test_config_is_validated():
    with pytest.raises(ValueError, match="cruise_m"):
        HorizonConfig(cruise_m=(0.01, 0.02))
    with pytest.raises(ValueError, match="beam"):
        HorizonConfig(beam=0)


def test_horizon_episode_on_the_faithful_preset():
    from agents.path_following import make_controller, run_episode
    from flagellum_env.paths import path_from_waypoints
    from flagellum_env.steer_env import FlagellumSteerEnv

    # a 60 deg turn 2 cm ahead, then 12 cm: long enough for the turn to be observed
    path = path_from_waypoints([[0.02, 0.0, 0.0], [0.08, 0.104, 0.0]], name="one_turn", reach_radius_m=0.015)
    env = FlagellumSteerEnv(path=path, preset="faithful", control_dt=0.1)
    planner = make_controller("horizon", env, "faithful")
    t0 = time.process_time()
    metrics, _ = run_episode(env, planner, path)
    cpu = time.process_time() - t0
    assert metrics["success"], metrics
    assert planner.turns and "observed_theta_deg" in planner.turns[0]
    stats = planner.search_stats
    assert stats["searches"] >= 1
    assert stats["search_s"] < 0.25 * cpu       # the search costs well under the simulation
