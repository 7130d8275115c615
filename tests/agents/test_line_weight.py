"""PlannerConfig.line_weight: turns scored by how far they end from the path's line (rule and adaptive planner)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.adaptive_planner import AdaptivePlanner, turn_ends
from agents.assets import default_turn_map
from agents.path_following import controller_kind, controller_options, make_controller
from agents.turn_map import TurnMap
from agents.turn_planner import ObservationLayout, PlannerConfig, RulePlanner, line_distance
from flagellum_env.paths import path_from_waypoints
from flagellum_env.steer_env import FlagellumSteerEnv

LAYOUT = ObservationLayout(slice(1, 4), slice(4, 13), slice(13, 37), 0.13, 1)
D, NODE = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.006, 0.0])
# 3 cm beside the segment (0,0,0) -> (0.3,0,0), heading parallel to it: swimming on misses the target by 3 cm
HEAD, TARGET = np.array([0.05, 0.03, 0.0]), np.array([0.3, 0.0, 0.0])


@pytest.fixture(scope="module")
def faithful_map() -> TurnMap:
    return TurnMap.load(default_turn_map("faithful"))


@pytest.mark.parametrize("bad", [-0.5, math.nan, math.inf])
def test_line_weight_must_be_a_finite_number_at_least_zero(bad):
    with pytest.raises(ValueError, match="line_weight"):
        PlannerConfig(line_weight=bad)


def test_line_distance():
    a, b = np.array([1.0, 0.0, 0.0]), np.array([3.0, 0.0, 0.0])
    pts = np.array([[0.0, 0.0, 0.0], [5.0, 3.0, 4.0], [2.0, -0.2, 0.0]])
    assert line_distance(pts, a, b) == pytest.approx([0.0, 5.0, 0.2])   # a line, not the segment: 5 beyond b
    assert line_distance(pts[1], a, a) == pytest.approx(math.sqrt(16.0 + 9.0 + 16.0))  # a point: from a
    assert line_distance(pts[:, None], a, b).shape == (3, 1)


def _end_of(planner: RulePlanner, plan: dict) -> np.ndarray:
    """Where the rule planner predicts the head after ``plan`` (the map's displacement of its burst)."""
    t_c, _, _, off = planner._candidates
    i = int(np.argmin(abs(t_c - plan["t_c"])))
    return turn_ends(np.asarray(plan["head"]), np.asarray(plan["heading"]), off[i], np.array([plan["burst_phase"]]))[0]


def _rule(faithful_map, w: float) -> tuple[RulePlanner, object]:
    p = RulePlanner(faithful_map, LAYOUT, 0.1, 0.015, lambda rpm: rpm, PlannerConfig(line_weight=w))
    ep = p._new_episode()
    ep.segment = (np.zeros(3), TARGET.copy())
    return p, ep


def test_rule_planner_with_line_weight_ends_its_turn_nearer_the_line(faithful_map):
    p0, ep0 = _rule(faithful_map, 0.0)
    p4, ep4 = _rule(faithful_map, 4.0)
    plain, lined = p0._plan_turn(HEAD, D, TARGET, NODE, ep0), p4._plan_turn(HEAD, D, TARGET, NODE, ep4)
    assert "line_score_m" not in plain and plain["predicted_miss_m"] < 0.01  # the paper's rule: at the target
    d_plain = float(line_distance(_end_of(p0, plain), *ep0.segment))
    d_lined = float(line_distance(_end_of(p4, lined), *ep4.segment))
    assert d_lined < d_plain - 0.003
    # its score is what it says: the miss plus the weighted distance of its end from the line
    assert lined["line_score_m"] == pytest.approx(lined["predicted_miss_m"] + 4.0 * d_lined, abs=1e-9)
    assert lined["line_score_straight_m"] == pytest.approx(lined["miss_straight_m"] + 4.0 * 0.03, abs=1e-9)
    # without a segment (a direct call) the weight has nothing to measure against: the paper's rule
    p4b = RulePlanner(faithful_map, LAYOUT, 0.1, 0.015, lambda rpm: rpm, PlannerConfig(line_weight=4.0))
    assert p4b._plan_turn(HEAD, D, TARGET, NODE) == plain


def test_line_weight_acts_only_when_swimming_on_misses_the_target(faithful_map):
    # heading straight at the target from 4 cm beside the line: on course, so neither rule turns (the line
    # weight re-scores the turns a miss asks for; it does not start turns of its own)
    head = np.array([0.0, 0.04, 0.0])
    d = (TARGET - head) / np.linalg.norm(TARGET - head)
    for w in (0.0, 4.0):
        p, ep = _rule(faithful_map, w)
        assert p._plan_turn(head, d, TARGET, NODE, ep) is None


def _adaptive(faithful_map, w: float):
    p = AdaptivePlanner(faithful_map, LAYOUT, 0.1, 0.015, lambda rpm: rpm, PlannerConfig(line_weight=w))
    ep = p._new_episode()
    ep.cruise_used = True
    ep.online.confirmed, ep.online.bias_var = 2, 0.02 ** 2  # off the map's own rule: _best_turn decides
    ep.segment = (np.zeros(3), TARGET.copy())
    return p, ep


def test_adaptive_planner_with_line_weight_ends_its_turn_nearer_the_line(faithful_map):
    p0, ep0 = _adaptive(faithful_map, 0.0)
    p4, ep4 = _adaptive(faithful_map, 4.0)
    assert not ep0.online.follows_model  # _best_turn decides, not the map's own rule
    miss0 = p0._miss_if_off_course(HEAD, D, TARGET)
    scale = p0._miss_scale(miss0)
    plain = p0._best_turn(HEAD, D, TARGET, ep0, miss0, scale)
    lined = p4._best_turn(HEAD, D, TARGET, ep4, miss0, scale)
    assert plain is not None and lined is not None

    def expected_line_distance(p, ep, plan):
        out = ep.online.outcomes(0.1)
        i = int(np.argmin(abs(np.maximum(out.t_fly, 0.1) - plan["t_c"])))
        ends = turn_ends(HEAD, D, out.offset[i], np.array([plan["burst_phase"]]))[:, 0]   # (K, 3)
        return float(out.weights @ line_distance(ends, *ep.segment))

    assert expected_line_distance(p4, ep4, lined) < expected_line_distance(p0, ep0, plain) - 0.003


def test_controller_spec_carries_the_line_weight():
    assert controller_kind("adaptive@line=2") == "adaptive" and controller_options("adaptive@line=2") == {"line": 2.0}
    assert controller_options("rule@line=0.5:some/map.json") == {"line": 0.5}
    assert controller_options("rule") == {} and controller_options("ppo:agents/x@y") == {}
    env = FlagellumSteerEnv(path=path_from_waypoints([[0.05, 0.0, 0.0]]), preset="faithful", control_dt=0.1)
    assert make_controller("rule@line=3", env, "faithful").config.line_weight == 3.0
    assert make_controller("rule", env, "faithful").config.line_weight == 0.0
    for bad, fragment in [("horizon@line=1", "none for 'horizon'"), ("rule@line=x", "line='x'"),
                          ("adaptive@bend=1", "option 'bend=1'")]:
        with pytest.raises(ValueError, match=fragment):
            controller_kind(bad)


def test_a_residual_agent_may_correct_a_planner_with_a_line_weight():
    from agents.residual_planner import AdaptiveResidualPlanner, base_planner
    from agents.turn_decision_env import TurnDecisionEnv

    kind, cls, config = base_planner("adaptive@line=2")
    assert (kind, cls, config.line_weight) == ("adaptive", AdaptiveResidualPlanner, 2.0)
    assert base_planner("rule")[2] is None
    for bad in ("horizon", "adaptive:map.json", "rule@line=-2", "ppo"):
        with pytest.raises(ValueError, match=f"planner={bad!r} is not allowed"):
            base_planner(bad)
    env = TurnDecisionEnv(preset="faithful", planner="adaptive@line=2")
    assert isinstance(env.planner, AdaptiveResidualPlanner) and env.planner.config.line_weight == 2.0
    with pytest.raises(ValueError, match="planner='rule@bend=1' is not allowed"):
        TurnDecisionEnv(preset="faithful", planner="rule@bend=1")


def test_the_line_agents_config_differs_from_the_shipped_agents_in_the_planner_alone():
    import dataclasses

    from agents.assets import package_file
    from agents.ppo_config import TrainConfig

    line = TrainConfig.from_yaml(package_file("configs", "ppo_residual_line.yml"))
    shipped = TrainConfig.from_yaml(package_file("configs", "ppo_residual_adaptive.yml"))
    assert line.planner == "adaptive@line=2" and line.max_wall_time_s <= 7200
    differ = [f.name for f in dataclasses.fields(TrainConfig) if getattr(line, f.name) != getattr(shipped, f.name)]
    assert differ == ["name", "source", "planner"]  # source: the file it came from
