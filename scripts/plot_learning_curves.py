"""Learning curves of several ``flagellum train`` runs in one figure: success and cross-track against decisions and
against training wall hours.

Per run (a folder written by ``flagellum train``): the validation success (``eval/evaluations.npz``: the fixed
validation paths, nominal swimmer, deterministic policy) and, from ``episodes.csv``, the training episodes'
success and mean cross-track error in windows of ``--window`` episodes. The label of a run is ``LABEL=DIR`` or the
folder's name.

Usage::

    python scripts/plot_learning_curves.py --run "PPO=out/ppo_scratch_nominal" --run "SAC=out/sac_scratch_nominal" \\
        --out docs/figures/rl_learning_curves.png
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np


def run_curves(folder: Path, window: int) -> dict[str, np.ndarray]:
    """Validation (decisions, success) and windowed training (decisions, wall h, success, cross-track m) of a run."""
    with open(folder / "episodes.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    dec = np.array([float(r["decisions"]) for r in rows])
    wall = np.array([float(r["wall_time_s"]) for r in rows]) / 3600.0
    ok = np.array([r["is_success"] == "True" for r in rows], float)
    cross = np.array([float(r["mean_cross_track_m"]) for r in rows])
    n = max(1, len(rows) // window)
    cut = [slice(k * window, min((k + 1) * window, len(rows))) for k in range(n)]
    out = {"train_decisions": np.array([dec[c][-1] for c in cut]), "train_wall_h": np.array([wall[c][-1] for c in cut]),
           "train_success": np.array([ok[c].mean() for c in cut]), "train_cross_m": np.array([cross[c].mean() for c in cut])}
    ev = folder / "eval" / "evaluations.npz"
    if ev.is_file():
        with np.load(ev) as d:
            out["val_decisions"] = d["timesteps"].astype(float)
            out["val_success"] = d["successes"].mean(axis=1) if "successes" in d else np.full(len(d["timesteps"]), np.nan)
            last = np.searchsorted(dec, out["val_decisions"], side="right") - 1
            out["val_wall_h"] = wall[np.clip(last, 0, len(wall) - 1)]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", action="append", required=True, metavar="[LABEL=]DIR", help="a training run's folder")
    parser.add_argument("--window", type=int, default=500, help="training episodes per point (default 500)")
    parser.add_argument("--out", type=Path, required=True, help="the figure (.png)")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    for spec in args.run:
        label, _, folder = spec.rpartition("=")
        folder = Path(folder)
        if not (folder / "episodes.csv").is_file():
            parser.error(f"--run {spec!r}: {str(folder)!r} holds no episodes.csv; allowed: a flagellum train folder")
        c = run_curves(folder, args.window)
        label = label or folder.name
        for col, x in ((0, "decisions"), (1, "wall_h")):
            line, = ax[0, col].plot(c[f"train_{x}"], c["train_success"], label=f"{label}: training episodes")
            if "val_success" in c:
                ax[0, col].plot(c[f"val_{x}"], c["val_success"], "o--", color=line.get_color(), ms=3,
                                label=f"{label}: validation paths")
            ax[1, col].plot(c[f"train_{x}"], 100 * c["train_cross_m"], color=line.get_color(), label=label)
    for col, name in ((0, "decisions (env steps)"), (1, "training wall time (h)")):
        ax[0, col].set_ylabel("success rate")
        ax[1, col].set_ylabel("mean cross-track (cm), training episodes")
        ax[1, col].set_xlabel(name)
        ax[0, col].set_ylim(-0.02, 1.02)
    ax[0, 0].legend(fontsize=7)
    ax[1, 0].legend(fontsize=7)
    fig.suptitle("Learning from scratch on FlagellumBurst (burst actions, no planner)")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
