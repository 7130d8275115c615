"""Learning curves of several ``flagellum train`` runs in one figure: success and cross-track against decisions and
against training CPU hours, per tier.

Per run (a folder written by ``flagellum train``): the validation success (``eval/evaluations.npz``: the fixed
validation paths, nominal swimmer, deterministic policy) and, from ``episodes.csv``, the training episodes'
success and mean cross-track error in windows of ``--window`` episodes, one curve per tier the episodes were played
on (a fine-tune with surrogate episodes in the mix has two). The label of a run is ``LABEL=DIR`` or the folder's
name.

Usage::

    python scripts/plot_learning_curves.py --run "PPO=out/ppo_scratch_nominal" --run "SAC=out/sac_scratch_nominal" \\
        --out docs/figures/rl_learning_curves.png
    python scripts/plot_learning_curves.py --chain --run "1 nominal surrogate=out/sac_scratch_nominal" \\
        --run "2 randomised surrogate=out/sac_scratch_randomized" --run "3 faithful=out/sac_scratch_faithful" \\
        --window 50 --out docs/figures/rl_recipe.png
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np


def run_curves(folder: Path, window: int, tier: str | None = None) -> dict[str, np.ndarray]:
    """Validation (decisions, success) and windowed training (decisions, CPU h, success, cross-track m) of a run;
    ``tier``: only the training episodes played on that tier (``episodes.csv``'s tier column: a fine-tune with
    surrogate episodes in the mix). CPU hours are the wall hours times the run's env processes (``meta.json``'s
    ``n_envs``: each SubprocVecEnv worker is busy all the time; the learner's own share is left out)."""
    meta = json.loads((folder / "meta.json").read_text(encoding="utf-8")) if (folder / "meta.json").is_file() else {}
    processes = max(1, int(meta.get("run", {}).get("n_envs", 1)))
    with open(folder / "episodes.csv", newline="", encoding="utf-8") as f:
        every = list(csv.DictReader(f))
    dec_all = np.array([float(r["decisions"]) for r in every])
    cpu_all = np.array([float(r["wall_time_s"]) for r in every]) / 3600.0 * processes
    rows = [r for r in every if tier is None or r.get("tier") == tier]
    dec = np.array([float(r["decisions"]) for r in rows])
    cpu = np.array([float(r["wall_time_s"]) for r in rows]) / 3600.0 * processes
    ok = np.array([r["is_success"] == "True" for r in rows], float)
    cross = np.array([float(r["mean_cross_track_m"]) for r in rows])
    n = max(1, len(rows) // window)
    cut = [slice(k * window, min((k + 1) * window, len(rows))) for k in range(n)]
    out = {"train_decisions": np.array([dec[c][-1] for c in cut]), "train_cpu_h": np.array([cpu[c][-1] for c in cut]),
           "train_success": np.array([ok[c].mean() for c in cut]), "train_cross_m": np.array([cross[c].mean() for c in cut])}
    ev = folder / "eval" / "evaluations.npz"
    if ev.is_file():
        with np.load(ev) as d:
            out["val_decisions"] = d["timesteps"].astype(float)
            out["val_success"] = d["successes"].mean(axis=1) if "successes" in d else np.full(len(d["timesteps"]), np.nan)
            last = np.searchsorted(dec_all, out["val_decisions"], side="right") - 1
            out["val_cpu_h"] = cpu_all[np.clip(last, 0, len(cpu_all) - 1)]
    return out


def tiers_of(folder: Path) -> list[str | None]:
    """The tiers a run's training episodes were played on ([None]: one, or a log from before the column)."""
    with open(folder / "episodes.csv", newline="", encoding="utf-8") as f:
        found = sorted({r.get("tier") or "" for r in csv.DictReader(f)})
    return [t for t in found if t] if len(found) > 1 else [None]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", action="append", required=True, metavar="[LABEL=]DIR", help="a training run's folder")
    parser.add_argument("--window", type=int, default=500, help="training episodes per point (default 500)")
    parser.add_argument("--out", type=Path, required=True, help="the figure (.png)")
    parser.add_argument("--chain", action="store_true",
                        help="the runs are stages of one recipe (each init_from the last): each starts where the last "
                             "ended, in decisions and CPU hours")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    offset = {"decisions": 0.0, "cpu_h": 0.0}
    for spec in args.run:
        label, _, folder = spec.rpartition("=")
        folder = Path(folder)
        if not (folder / "episodes.csv").is_file():
            parser.error(f"--run {spec!r}: {str(folder)!r} holds no episodes.csv; allowed: a flagellum train folder")
        label = label or folder.name
        end = dict(offset)
        for k, tier in enumerate(tiers_of(folder)):
            c = run_curves(folder, args.window, tier)
            for x in offset:
                for part in ("train", "val"):
                    if f"{part}_{x}" in c:
                        c[f"{part}_{x}"] = c[f"{part}_{x}"] + offset[x]
                end[x] = max(end[x], float(c[f"train_{x}"][-1]))
            name = f"{label} ({tier})" if tier else label
            for col, x in ((0, "decisions"), (1, "cpu_h")):
                line, = ax[0, col].plot(c[f"train_{x}"], c["train_success"], label=f"{name}: training episodes")
                if "val_success" in c and k == 0:
                    ax[0, col].plot(c[f"val_{x}"], c["val_success"], "o--", color=line.get_color(), ms=3,
                                    label=f"{label}: validation paths")
                ax[1, col].plot(c[f"train_{x}"], 100 * c["train_cross_m"], color=line.get_color(), label=name)
        if args.chain:
            offset = end
    for col, name in ((0, "decisions (env steps)"), (1, "training CPU hours (wall x env processes)")):
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
