"""Off-screen pictures of the swimmer and its path (matplotlib's Agg canvas, no display needed).

A frame has two panels in the start frame, in cm: the top view (x-y) and the side view (x-z).
Each shows the path (dashed, waypoints reached in green, pending in red, the target's reach
radius as a circle), the head's trail (blue), the flagellum (black) and the head (grey disc).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle

CM = 1e-2
_VIEWS = (("top view", 0, 1, "x (cm)", "y (cm)"), ("side view", 0, 2, "x (cm)", "z (cm)"))


@dataclass(frozen=True)
class Scene:
    """Everything a frame shows; positions in the start frame, m.

    vertices: (k + 1, 3) origin then waypoints; trail: (m, 3) past head positions;
    nodes: (n, 3) swimmer nodes (node 0 the head centre when head_radius_m > 0).
    """

    vertices: np.ndarray
    n_reached: int
    reach_radius_m: float
    trail: np.ndarray
    nodes: np.ndarray
    head_radius_m: float
    time_s: float
    motor_speed_rpm: float
    end_to_end_ratio: float
    buckled: bool
    path_name: str


def _legend_handles() -> list:
    """What each mark of a frame is (the same in both views)."""
    from matplotlib.lines import Line2D

    return [Line2D([], [], ls="--", color="0.6", lw=1.0, label="path"),
            Line2D([], [], ls="", marker="x", color="k", ms=5, label="start"),
            Line2D([], [], ls="", marker="o", color="tab:green", ms=5, label="waypoint reached"),
            Line2D([], [], ls="", marker="o", mfc="none", color="tab:red", ms=5, label="waypoint to reach"),
            Line2D([], [], ls=":", color="tab:red", lw=0.8, label="reach radius (target)"),
            Line2D([], [], color="tab:blue", lw=1.0, label="head trail"),
            Line2D([], [], color="k", lw=1.5, label="flagellum"),
            Line2D([], [], ls="", marker="o", color="0.55", ms=7, label="head")]


class Renderer:
    """Draws ``Scene``s into RGB arrays of shape (height, width, 3), uint8."""

    def __init__(self, width: int = 640, height: int = 480, dpi: int = 100) -> None:
        self.width, self.height = int(width), int(height)
        self.figure = Figure(figsize=(self.width / dpi, self.height / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.figure)
        self.axes = self.figure.subplots(1, 2)
        self.figure.legend(handles=_legend_handles(), loc="lower center", ncol=4, fontsize=7, frameon=False,
                           handlelength=1.8, columnspacing=1.2)

    def draw(self, scene: Scene) -> np.ndarray:
        """The frame of ``scene``: (height, width, 3) uint8."""
        for ax, (title, i, j, xl, yl) in zip(self.axes, _VIEWS):
            ax.clear()
            self._panel(ax, scene, i, j)
            ax.set_title(title, fontsize=9)
            ax.set_xlabel(xl, fontsize=8)
            ax.set_ylabel(yl, fontsize=8)
            ax.tick_params(labelsize=7)
        state = "buckled" if scene.buckled else "straight"
        self.figure.suptitle(f"{scene.path_name}: t = {scene.time_s:.1f} s, motor {scene.motor_speed_rpm:.0f} rpm, "
                             f"L'/L = {scene.end_to_end_ratio:.2f} ({state}), "
                             f"waypoints {scene.n_reached}/{len(scene.vertices) - 1}", fontsize=9)
        self.figure.subplots_adjust(left=0.1, right=0.98, bottom=0.24, top=0.88, wspace=0.35)
        self.canvas.draw()
        rgba = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[..., :3])

    def _panel(self, ax, scene: Scene, i: int, j: int) -> None:
        v = scene.vertices / CM
        ax.plot(v[:, i], v[:, j], ls="--", color="0.6", lw=1.0, zorder=1)
        ax.plot(v[0, i], v[0, j], marker="x", color="k", ms=5, zorder=2)
        wp = v[1:]
        done, todo = wp[:scene.n_reached], wp[scene.n_reached:]
        ax.plot(done[:, i], done[:, j], "o", color="tab:green", ms=5, zorder=3)
        ax.plot(todo[:, i], todo[:, j], "o", mfc="none", color="tab:red", ms=5, zorder=3)
        if len(todo):
            ax.add_patch(Circle((todo[0, i], todo[0, j]), scene.reach_radius_m / CM, fill=False,
                                color="tab:red", lw=0.8, ls=":", zorder=3))
        if len(scene.trail) > 1:
            t = scene.trail / CM
            ax.plot(t[:, i], t[:, j], color="tab:blue", lw=1.0, zorder=4)
        x = scene.nodes / CM
        first = 1 if scene.head_radius_m > 0 else 0
        ax.plot(x[first:, i], x[first:, j], color="k", lw=1.5, zorder=5)
        if scene.head_radius_m > 0:
            ax.add_patch(Circle((x[0, i], x[0, j]), scene.head_radius_m / CM, color="0.55", alpha=0.8, zorder=6))
        # a square window around path, trail and swimmer, the same scale on both axes
        pts = np.vstack([v, x, scene.trail / CM if len(scene.trail) else v[:1]])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        half = 0.5 * max(hi[i] - lo[i], hi[j] - lo[j], 1.0) * 1.1 + scene.head_radius_m / CM
        ci, cj = 0.5 * (lo[i] + hi[i]), 0.5 * (lo[j] + hi[j])
        ax.set_xlim(ci - half, ci + half)
        ax.set_ylim(cj - half, cj + half)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, lw=0.3, alpha=0.5)

    def close(self) -> None:
        self.figure.clear()


class HumanWindow:
    """Shows frames in an interactive matplotlib window (``render_mode="human"``)."""

    def __init__(self, fps: float) -> None:
        import matplotlib.pyplot as plt

        self._plt = plt
        self.fps = fps
        self._fig = None
        self._image = None

    def show(self, frame: np.ndarray) -> None:
        plt = self._plt
        if self._fig is None or not plt.fignum_exists(self._fig.number):
            plt.ion()
            self._fig, ax = plt.subplots(figsize=(frame.shape[1] / 100, frame.shape[0] / 100), dpi=100)
            ax.set_axis_off()
            self._fig.subplots_adjust(0, 0, 1, 1)
            self._image = ax.imshow(frame)
        else:
            self._image.set_data(frame)
        self._fig.canvas.draw_idle()
        plt.pause(1.0 / self.fps)

    def close(self) -> None:
        if self._fig is not None:
            self._plt.close(self._fig)
            self._fig = None


def set_equal_3d(ax, points_cm: np.ndarray) -> None:
    """Equal scaling on x, y, z: a cube around all points (cm)."""
    lo, hi = points_cm.min(axis=0), points_cm.max(axis=0)
    centre = (lo + hi) / 2.0
    half = max(float((hi - lo).max()) / 2.0, 1e-3) * 1.05
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
