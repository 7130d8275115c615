"""Figures of path following (Fig. 6b, 6c) and of the turn map (Fig. 5d); matplotlib object API."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from agents.path_following import EpisodeTrace
from agents.turn_map import TurnMap
from flagellum_env.render import set_equal_3d

CM = 100.0


def _direction_arrows(ax, xy: np.ndarray, color: str, n: int = 6) -> None:
    """``n`` arrows along the path ``xy`` ((M, 2)), evenly spaced by arc length, pointing the way it was swum."""
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if len(xy) < 3 or s[-1] <= 0.0:
        return
    for target in s[-1] * (np.arange(n) + 0.5) / n:
        i = int(np.clip(np.searchsorted(s, target), 1, len(xy) - 1))
        j = max(0, i - max(1, len(xy) // 200))
        if np.allclose(xy[i], xy[j]):
            continue
        ax.annotate("", xy=xy[i], xytext=xy[j], arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.2,
                                                              "mutation_scale": 14})


def path_figure(traces: Mapping[str, EpisodeTrace], title: str = "") -> Figure:
    """Target path (dashed) and each controller's head path, cm: the x-y view with the start (star), direction
    arrows and the end of each run (cross); a 3-D view; and the height z against the distance swum (its own,
    auto-scaled axis, so that the out-of-plane drift Δz/ΔL shows)."""
    fig = Figure(figsize=(17.0, 5.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 3, 1)
    ax3 = fig.add_subplot(1, 3, 2, projection="3d")
    axz = fig.add_subplot(1, 3, 3)
    first = next(iter(traces.values()))
    target = np.vstack([np.zeros((1, 3)), first.waypoints]) * CM
    ax.plot(target[:, 0], target[:, 1], "k--", lw=1.2, label="target")
    ax.scatter(target[1:, 0], target[1:, 1], c="k", s=14)
    ax3.plot(target[:, 0], target[:, 1], target[:, 2], "k--", lw=1.0)
    drawn: list[tuple[str, np.ndarray]] = []
    for k, (name, tr) in enumerate(traces.items()):
        h = tr.head * CM
        color = f"C{k}"
        same = next((other for other, oh in drawn if oh.shape == h.shape and np.array_equal(oh, h)), None)
        # a run identical to an earlier one would hide under it: draw it dotted and say so
        style = {"ls": ":", "lw": 2.4} if same else {"lw": 1.6}
        ax.plot(h[:, 0], h[:, 1], color=color, label=name if same is None else f"{name} (same path as {same})",
                **style)
        _direction_arrows(ax, h[:, :2], color)
        ax.plot(h[-1, 0], h[-1, 1], "x", color=color, ms=9, mew=2)
        ax3.plot(h[:, 0], h[:, 1], h[:, 2], color=color, **style)
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(h, axis=0), axis=1))])
        axz.plot(arc, h[:, 2] - h[0, 2], color=color, label=name, **style)
        drawn.append((name, h))
    ax.plot(0.0, 0.0, "*", color="tab:green", ms=15, mec="k", zorder=5, label="start")
    ax.plot([], [], "kx", ms=8, mew=2, label="end of each run")
    ax3.scatter([0.0], [0.0], [0.0], marker="*", s=150, color="tab:green", edgecolors="k")
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.legend(fontsize="small")
    ax.set_title("x-y plane (arrows: direction of swimming)")
    set_equal_3d(ax3, np.vstack([target] + [t.head * CM for t in traces.values()]))
    ax3.set_xlabel("x (cm)")
    ax3.set_ylabel("y (cm)")
    ax3.set_zlabel("z (cm)")
    ax3.set_title("3-D (equal axes)")
    axz.axhline(0.0, color="k", ls="--", lw=0.8)
    axz.set_xlabel("distance swum by the head ΔL (cm)")
    axz.set_ylabel("height above the start Δz (cm, own scale)")
    axz.set_title("out of the plane: Δz against ΔL")
    axz.grid(alpha=0.3)
    axz.legend(fontsize="small")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def omega_figure(traces: Mapping[str, EpisodeTrace], title: str = "") -> Figure:
    """Motor speed against time (the control signal, Fig. 6c) and L'/L below it."""
    fig = Figure(figsize=(10.0, 5.0))
    FigureCanvasAgg(fig)
    ax, ax2 = fig.subplots(2, 1, sharex=True)
    for name, tr in traces.items():
        ax.step(tr.t, tr.omega_rpm, where="pre", lw=1.0, label=name)
        ax2.plot(tr.t, tr.end_to_end_ratio, lw=1.0, label=name)
    ax.set_ylabel("motor speed ω (rpm)")
    ax2.set_ylabel("L'/L")
    ax2.set_xlabel("time (s)")
    ax.legend(fontsize="small")
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return fig


def turn_map_figure(tmap: TurnMap, title: str = "") -> Figure:
    """theta and phi against t_c (every phase as dots, the mean theta as a line) and psi; Fig. 5d."""
    fig = Figure(figsize=(11.0, 4.5))
    FigureCanvasAgg(fig)
    ax, axp = fig.subplots(1, 2)
    t_scale = tmap.params.viscous_time
    tc, th, _ = tmap.theta_curve()
    phases = sorted({p.phase_deg for p in tmap.points})
    for ph in phases:
        pts = sorted((p for p in tmap.points if p.phase_deg == ph), key=lambda p: p.t_c)
        t = [p.t_c for p in pts]
        ax.plot(t, [p.theta_deg for p in pts], "o", ms=3, color="tab:blue", alpha=0.6)
        ax.plot(t, [p.phi_deg for p in pts], "s", ms=3, alpha=0.7, label=f"φ, burst at phase {ph:g}°")
    if len(phases) > 1:  # the spread over phases: theta from its lowest to its highest value at each t_c
        lo = np.array([min(p.theta_deg for p in tmap.points if p.t_c == t) for t in tc])
        hi = np.array([max(p.theta_deg for p in tmap.points if p.t_c == t) for t in tc])
        ax.errorbar(tc, th, yerr=[th - lo, hi - th], fmt="-", color="tab:blue", lw=1.6, capsize=3,
                    label=f"θ, mean over {len(phases)} phases (bars: lowest to highest)")
    else:
        ax.plot(tc, th, "-", color="tab:blue", lw=1.6, label=f"θ (one phase, {phases[0]:g}°: no spread)")
    ax.axhline(154.0, color="gray", ls=":", lw=1.0, label="paper: max θ = 154°")
    ax.set_xlabel("burst length t_c (s)")
    ax.set_ylabel("angle (deg)")
    ax.legend(fontsize="x-small", loc="upper left")
    top = ax.secondary_xaxis("top", functions=(lambda t: t / t_scale, lambda tb: tb * t_scale))
    top.set_xlabel("t̄_c = t_c EI / (μ L⁴)")
    tc2, psi, spread = tmap.psi_curve()
    if len(phases) > 1:
        axp.errorbar(tc2, psi, yerr=spread, fmt="o-", ms=3, capsize=3)
        axp.set_title(f"turn direction relative to the phase node (bars: largest deviation over {len(phases)} "
                      "phases)", fontsize="small")
    else:
        axp.plot(tc2, psi, "o-", ms=3)
        axp.set_title(f"turn direction relative to the phase node (one phase, {phases[0]:g}°: no spread)",
                      fontsize="small")
    axp.set_xlabel("burst length t_c (s)")
    axp.set_ylabel("ψ: turn azimuth rel. to flagellum phase (deg)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def save(fig: Figure, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    return path
