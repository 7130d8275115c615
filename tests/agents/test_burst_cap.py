"""PlannerConfig.burst_cap_deg (``@cap=DEG`` in a controller spec): the largest turn one burst is planned for."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.assets import default_turn_map
from agents.online_turn_map import OnlineTurnMap
from agents.path_following import controller_kind, controller_options
from agents.residual_planner import base_planner
from agents.turn_map import TurnMap
from agents.turn_planner import ObservationLayout, PlannerConfig, RulePlanner

LAYOUT = ObservationLayout(slice(1, 4), slice(4, 13), slice(13, 37), 0.13, 1)
D, NODE = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.006, 0.0])


@pytest.fixture(scope="module")
def faithful_map() -> TurnMap:
    return TurnMap.load(default_turn_map("faithful"))


def test_the_spec_option_becomes_the_config():
    assert controller_options("adaptive@line=2,cap=90") == {"line": 2.0, "cap": 90.0}
    assert PlannerConfig.from_options({"line": 2.0, "cap": 90.0}) == PlannerConfig(line_weight=2.0, burst_cap_deg=90.0)
    assert PlannerConfig.from_options({}) is None and PlannerConfig().burst_cap_deg == math.inf
    assert base_planner("adaptive@cap=80")[2] == PlannerConfig(burst_cap_deg=80.0)


@pytest.mark.parametrize("spec, match", [("rule@cap=0", "cap='0'"), ("adaptive@cap=-5", "cap='-5'"),
                                         ("adaptive@cap=nan", "cap='nan'"), ("ppo@cap=90", "'cap=90'"),
                                         ("rule@cap=90,cap=80", "cap='80'")])
def test_bad_caps_are_refused_naming_the_value(spec, match):
    with pytest.raises(ValueError, match=match):
        controller_kind(spec)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, "90"])
def test_the_config_refuses_a_cap_that_is_not_positive(bad):
    with pytest.raises(ValueError, match="burst_cap_deg"):
        PlannerConfig(burst_cap_deg=bad)


def _rule(turn_map: TurnMap, cap: float) -> RulePlanner:
    return RulePlanner(turn_map, LAYOUT, 0.1, 0.015, lambda rpm: rpm, PlannerConfig(burst_cap_deg=cap))


def test_the_rule_planner_plans_no_burst_beyond_the_cap(faithful_map):
    _, theta_free, _, _ = _rule(faithful_map, math.inf)._candidates
    _, theta_cap, _, _ = _rule(faithful_map, 90.0)._candidates
    assert math.degrees(theta_free.max()) > 120.0            # the map's rising branch reaches ~138 deg
    assert math.degrees(theta_cap.max()) <= 90.0 and theta_cap.size < theta_free.size
    assert np.array_equal(theta_cap, theta_free[:theta_cap.size])  # the same candidates, cut at the cap
    # a target 140 deg off the heading: uncapped, one large burst; capped, a first burst of at most the cap
    target = 0.2 * np.array([math.cos(math.radians(140.0)), math.sin(math.radians(140.0)), 0.0])
    head = np.zeros(3)
    free = _rule(faithful_map, math.inf)._plan_turn(head, D, target, NODE)
    capped = _rule(faithful_map, 90.0)._plan_turn(head, D, target, NODE)
    assert free["theta_deg"] > 110.0 and capped["theta_deg"] <= 90.0


def test_a_cap_below_the_first_candidate_keeps_the_smallest_turn(faithful_map):
    _, theta, _, _ = _rule(faithful_map, 1e-3)._candidates
    assert theta.size == 1


def test_the_adaptive_planners_outcomes_stop_at_the_cap(faithful_map):
    online = OnlineTurnMap(faithful_map)
    free, capped = online.outcomes(0.1), online.outcomes(0.1, math.radians(90.0))
    assert capped.map_t.size < free.map_t.size
    np.testing.assert_array_equal(capped.map_t, free.map_t[:capped.map_t.size])
    t, theta, _ = faithful_map.theta_curve()                               # the map's mean turn, deg
    nominal = np.interp(capped.map_t, np.r_[0.0, t], np.r_[0.0, theta])
    assert nominal.max() <= 90.0 and np.interp(free.map_t, np.r_[0.0, t], np.r_[0.0, theta]).max() > 120.0
