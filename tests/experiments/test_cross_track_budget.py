import numpy as np
import pytest

from experiments.cross_track_budget import budget_of_episodes, cross_track_split


def _trace():
    """Two segments of 10 steps of 1 s: segment 0 cruises 2 s, turns 2 s (burst, then relaxing), cruises 2 s,
    turns again 1 s, cruises 3 s; segment 1 never turns."""
    t = np.arange(21.0)
    om = np.full(21, 10.0)
    ee = np.ones(21)
    om[2] = 150.0
    ee[3] = 0.7  # relaxing
    om[6] = 150.0
    wi = np.array([0] * 10 + [1] * 11)
    x = np.zeros(21)
    x[:11] = [1, 1, 1, 3, 2, 2, 2, 2, 1, 1, 4]
    x[11:] = 4.0
    return t, x, om, ee, wi


def test_the_parts_sum_to_the_integral_and_fall_where_the_turns_are():
    t, x, om, ee, wi = _trace()
    s = cross_track_split(t, x, om, ee, wi)
    assert s["before"] == pytest.approx(1 + 1 + 4 * 10)   # steps 0-1, and segment 1 (10 steps of 4)
    assert s["turning"] == pytest.approx(2 + 2.5 + 2)                       # steps 2-3 and step 6
    assert s["between"] == pytest.approx(2 + 2)                             # steps 4-5
    assert s["after"] == pytest.approx(1.5 + 1 + 2.5)                       # steps 7-9
    assert sum(s[p] for p in ("before", "turning", "between", "after")) == pytest.approx(s["total_m_s"])
    assert s["total_m_s"] == pytest.approx(np.trapezoid(x, t))
    # the first turn done exactly: its 2 + 2.5, then from x = 2 at t = 4 straight to the waypoint at t = 10
    assert s["ideal_first_turn_m_s"] == pytest.approx(2 + 4.5 + 0.5 * 2 * 6 + 40)
    b = budget_of_episodes([s, s])
    assert b["mean_m"] == pytest.approx(s["total_m_s"] / 20)
    assert b["turning_m"] == pytest.approx(6.5 / 20)


def test_bad_traces_are_refused():
    with pytest.raises(ValueError, match="equal lengths"):
        cross_track_split(np.arange(3.0), np.zeros(2), np.zeros(3), np.ones(3), np.zeros(3))
    with pytest.raises(ValueError, match="no episodes"):
        budget_of_episodes([])
