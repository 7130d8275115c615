"""Figures of a run (matplotlib object API, no pyplot, so it works without a display)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from flagellum_env.render import set_equal_3d
from physics.run import Trajectory
from physics.schedule import MotorSchedule

M_TO_CM = 100.0


def trajectory_figure(traj: Trajectory, head_radius_m: float = 0.0, title: str | None = None) -> Figure:
    """3-D head path and the final flagellum shape, in cm, equal axis scaling.

    ``head_radius_m`` > 0 draws the head as a wire sphere around the first node (the head centre), so
    the head path inside it stays visible.
    """
    fig = Figure(figsize=(7.0, 6.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    path = traj.head_positions * M_TO_CM
    final = traj.node_positions[-1] * M_TO_CM
    rod = final[1:] if head_radius_m > 0 else final
    ax.plot(path[:, 0], path[:, 1], path[:, 2], color="tab:blue", lw=1.5, label="head path")
    ax.scatter(*path[0], color="tab:green", s=20, label="start")
    ax.plot(rod[:, 0], rod[:, 1], rod[:, 2], color="tab:orange", lw=2.0,
            label=f"flagellum at t = {traj.node_times[-1]:.3g} s")
    points = [path, final]
    if head_radius_m > 0:
        b = head_radius_m * M_TO_CM
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, np.pi, 12))
        c = final[0]
        ax.plot_wireframe(c[0] + b * np.cos(u) * np.sin(v), c[1] + b * np.sin(u) * np.sin(v),
                          c[2] + b * np.cos(v), color="tab:gray", alpha=0.35, linewidth=0.4)
        ax.scatter(*path[-1], color="tab:blue", s=20, label="head centre at the end")
        points.append(np.array([c - b, c + b]))
    set_equal_3d(ax, np.vstack(points))
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_zlabel("z (cm)")
    ax.legend(loc="upper left", fontsize="small")
    if title:
        ax.set_title(title)
    return fig


def schedule_label(schedule: MotorSchedule, duration_s: float | None = None, max_steps: int = 4) -> str:
    """The motor schedule in words for a plot title: "omega = 60 rpm" for a constant speed, "omega: 10 → 90 rpm at
    t = 10 s" for steps (those that start before ``duration_s``); more than ``max_steps`` steps are summarised."""
    steps = [(t, w) for t, w in schedule.steps if duration_s is None or t < duration_s or t == 0.0]
    if len(steps) == 1:
        return f"omega = {steps[0][1]:.4g} rpm"
    speeds = " → ".join(f"{w:.4g}" for _, w in steps[:max_steps])
    times = ", ".join(f"{t:.4g}" for t, _ in steps[1:max_steps])
    if len(steps) > max_steps:
        return f"omega: {speeds} → … rpm at t = {times}, … s ({len(steps)} steps)"
    return f"omega: {speeds} rpm at t = {times} s"


def save_trajectory_plot(traj: Trajectory, path: str | Path, head_radius_m: float = 0.0,
                         title: str | None = None) -> Path:
    """Write ``trajectory_figure`` to ``path`` (PNG, 150 dpi); returns the path."""
    path = Path(path)
    trajectory_figure(traj, head_radius_m, title).savefig(path, dpi=150)
    return path
