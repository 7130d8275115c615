"""Plots of path following: a run identical to an earlier one is drawn so that both can be seen, and says so."""

from __future__ import annotations

import numpy as np

from agents.follow_plots import path_figure
from agents.path_following import EpisodeTrace


def _trace(shift: float = 0.0) -> EpisodeTrace:
    t = np.linspace(0.0, 10.0, 6)
    head = np.stack([t * 0.001, t * shift, 0 * t], axis=1)
    return EpisodeTrace(t=t, head=head, omega_rpm=10 + 0 * t, end_to_end_ratio=1 + 0 * t, cross_track_m=0 * t,
                        waypoint_index=0 * t, waypoints=np.array([[0.01, 0.0, 0.0]]))


def test_an_identical_run_is_dotted_and_labelled():
    fig = path_figure({"rule": _trace(), "ppo": _trace(), "ppo:other": _trace(0.001)})
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert "ppo (same path as rule)" in lines and lines["ppo (same path as rule)"].get_linestyle() == ":"
    assert lines["rule"].get_linestyle() == "-" and lines["ppo:other"].get_linestyle() == "-"


def test_the_path_figure_marks_the_start_the_direction_and_shows_the_height_on_its_own_scale():
    tr = _trace()
    tr.head[:, 2] = np.linspace(0.0, 2e-5, len(tr.t))  # 2 mm of drift over 1 cm: invisible on equal axes
    fig = path_figure({"rule": tr})
    xy, _, z_panel = fig.axes[:3]
    assert "start" in [ln.get_label() for ln in xy.get_lines()]
    assert any(a.arrow_patch is not None for a in xy.texts)  # direction arrows
    lo, hi = z_panel.get_ylim()
    assert hi - lo < 0.01 and hi >= 2e-3  # cm: the drift fills the z panel
