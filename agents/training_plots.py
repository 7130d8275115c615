"""Figure of a PPO training run: training episodes and validation evaluations against decisions."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def read_episodes(file: Path) -> dict[str, np.ndarray]:
    """Columns of ``episodes.csv`` (``agents.ppo_training``) as float arrays (booleans as 0/1)."""
    with open(file, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    cols: dict[str, np.ndarray] = {}
    for key in ("decisions", "wall_time_s", "return", "is_success", "mean_cross_track_m"):
        cols[key] = np.array([1.0 if r[key] == "True" else 0.0 if r[key] == "False" else float(r[key] or "nan")
                              for r in rows])
    return cols


def rolling_mean(y: np.ndarray, window: int) -> np.ndarray:
    """Mean of the last ``window`` values at each index (fewer at the start)."""
    c = np.cumsum(np.insert(np.asarray(y, float), 0, 0.0))
    idx = np.arange(1, len(y) + 1)
    lo = np.maximum(idx - window, 0)
    return (c[idx] - c[lo]) / (idx - lo)


def training_figure(run_dir: Path, title: str = "", window: int = 10) -> Figure:
    """Three panels against decisions: episode return, success and mean cross-track error (cm)
    of the training episodes (dots, rolling mean of ``window``), and the validation evaluations."""
    ep = read_episodes(run_dir / "episodes.csv")
    fig = Figure(figsize=(13.0, 4.0))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3)
    x = ep["decisions"]
    for ax, key, label, scale in ((axes[0], "return", "episode return", 1.0),
                                  (axes[1], "is_success", "success (training episodes)", 1.0),
                                  (axes[2], "mean_cross_track_m", "mean cross-track error (cm)", 100.0)):
        y = ep[key] * scale
        ax.plot(x, y, ".", ms=3, alpha=0.4, color="C0", label="training episode")
        if len(y):
            ax.plot(x, rolling_mean(y, window), "-", color="C0", label=f"rolling mean of {window}")
        ax.set_xlabel("decisions (turns planned)")
        ax.set_ylabel(label)
    ev = run_dir / "eval" / "evaluations.npz"
    if ev.is_file():
        with np.load(ev) as d:
            t = d["timesteps"]
            axes[0].plot(t, d["results"].mean(axis=1), "s-", color="C1", label="validation (deterministic)")
            if "successes" in d and d["successes"].size:
                axes[1].plot(t, d["successes"].mean(axis=1), "s-", color="C1", label="validation success rate")
    for ax in axes:
        ax.legend(fontsize="x-small")
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
