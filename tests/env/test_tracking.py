"""Waypoint bookkeeping (progress, cross-track error, reaching in order) and buckling events."""

from __future__ import annotations

import numpy as np
import pytest

from flagellum_env.paths import path_from_waypoints
from flagellum_env.tracking import BucklingMonitor, PathTracker


@pytest.fixture
def tracker() -> PathTracker:
    # origin -> (0.1, 0, 0) -> (0.1, 0.1, 0)
    return PathTracker(path_from_waypoints([[0.1, 0, 0], [0.1, 0.1, 0]]), reach_radius_m=0.01)


def test_progress_is_projection_onto_the_current_segment(tracker):
    assert tracker.progress(np.array([0.03, 0.02, 0.0])) == pytest.approx(0.03)
    assert tracker.cross_track_error(np.array([0.03, 0.02, 0.0])) == pytest.approx(0.02)
    assert tracker.progress(np.array([-0.05, 0.0, 0.0])) == 0.0  # clipped behind the start


def test_waypoints_are_reached_in_order_within_the_radius(tracker):
    assert tracker.update(np.array([0.1, 0.1, 0.0])) == 0  # the second is not the target yet
    assert tracker.update(np.array([0.095, 0.005, 0.0])) == 1
    assert tracker.index == 1
    assert tracker.progress(np.array([0.1, 0.04, 0.0])) == pytest.approx(0.14)
    assert tracker.update(np.array([0.1, 0.095, 0.0])) == 1
    assert tracker.done
    assert tracker.progress(np.zeros(3)) == pytest.approx(0.2)


def test_targets_repeat_the_last_waypoint(tracker):
    tracker.update(np.array([0.1, 0.0, 0.0]))
    assert np.array_equal(tracker.targets(2), [[0.1, 0.1, 0.0], [0.1, 0.1, 0.0]])


def test_buckling_events_count_with_hysteresis():
    m = BucklingMonitor(threshold=0.9, release=0.95)
    for r in [1.0, 1.05, 0.89, 0.5, 0.92, 0.3, 0.96, 1.0, 0.85, 1.0]:
        m.update(r)
    assert m.events == 2
    assert not m.buckled


def test_the_trackers_distances_are_numpys_norms_bit_for_bit():
    rng = np.random.default_rng(3)
    path = path_from_waypoints(rng.normal(0.0, 0.05, (4, 3)))
    tracker = PathTracker(path, 0.01)
    assert tracker.path_length_m == path.length_m
    for p in rng.normal(0.0, 0.05, (20, 3)):
        _, closest = tracker._projection(p)
        assert tracker.cross_track_error(p) == float(np.linalg.norm(p - closest))
        assert tracker.distance_to_target(p) == float(np.linalg.norm(p - path.waypoints[tracker._segment()]))
