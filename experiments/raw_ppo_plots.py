"""Learning curve of a from-scratch PPO run (``experiments.raw_ppo``): return and success rate per update."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


#: progress.csv columns of a raw-PPO run (``experiments.raw_ppo``: SB3's logger) and of the runs made before it
#: logged through SB3 (scripts/train_raw_ppo.py's run folder), with what the return and success columns average.
RAW_PPO_COLUMNS = {
    "sb3": ({"steps": "time/total_timesteps", "wall": "run/wall_s", "return": "rollout/ep_rew_mean",
             "success": "rollout/success_rate"}, "mean over the session's last 100 episodes (SB3)"),
    "before": ({"steps": "env_steps", "wall": "wall_s", "return": "ep_return_mean", "success": "success_rate"},
               "mean of the episodes that ended in the update"),
}


def read_raw_progress(file: Path) -> tuple[dict[str, np.ndarray], str]:
    """Steps, wall seconds, return and success rate per update of a raw-PPO ``progress.csv`` and what the last two
    average; FileNotFoundError / ValueError (one line) when there is nothing to read."""
    if not file.is_file():
        raise FileNotFoundError(f"{str(file)!r} does not exist; train first")
    with open(file, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{str(file)!r} holds no update yet")
    for columns, meaning in RAW_PPO_COLUMNS.values():
        if all(c in rows[0] for c in (columns["steps"], columns["wall"])):
            return ({k: np.array([float(r.get(c) or "nan") for r in rows]) for k, c in columns.items()}, meaning)
    raise ValueError(f"{str(file)!r} is not a raw-PPO progress file (no {RAW_PPO_COLUMNS['sb3'][0]['steps']} column)")


def raw_ppo_figure(run_dir: Path, title: str = "") -> Figure:
    """Mean episode return and success rate of each PPO update against env steps and against training wall
    hours, from ``run_dir/progress.csv``."""
    d, meaning = read_raw_progress(run_dir / "progress.csv")
    fig = Figure(figsize=(10.0, 6.5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, sharey="row")
    for j, (xlabel, x) in enumerate((("env steps", d["steps"]), ("training wall time (h)", d["wall"] / 3600.0))):
        for i, (ylabel, y) in enumerate((("episode return", d["return"]), ("success rate", d["success"]))):
            ax = axes[i, j]
            ax.plot(x, y, "o-", ms=3, color="C0", label=meaning)
            ax.set_xlabel(xlabel)
            ax.grid(alpha=0.3)
            if j == 0:
                ax.set_ylabel(ylabel)
    axes[1, 0].set_ylim(-0.05, 1.05)
    axes[0, 0].legend(fontsize="x-small")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
