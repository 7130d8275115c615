"""``flagellum train``: train the PPO agent (stable-baselines3) from a YAML config; resumable."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from flagellum.commands.common import UsageError, ensure_dir

NAME = "train"
HELP = "train the PPO agent that corrects the turn planner (stable-baselines3, CPU); resumable"
DESCRIPTION = ("Train PPO from --config (rl-zoo3-style YAML, default agents/configs/ppo_residual_adaptive.yml, the shipped agent's) into "
               "--out: model.zip, vecnormalize.pkl, meta.json, config.yml, episodes.csv, eval/, checkpoints/, tb/ "
               "(tensorboard). --resume continues from the newest checkpoint. Use the result with "
               "--controller ppo:DIR.")
ACCEPTS_SET = False  # the turn map fixes the swimmer: edit the config's task
PRESET = (None, "the config's task.preset (an other value is refused)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from agents.assets import package_file

    parser.add_argument("--config", metavar="FILE", type=Path, default=package_file("configs", "ppo_residual_adaptive.yml"),
                        help="training config (YAML; default agents/configs/ppo_residual_adaptive.yml: the shipped agent's)")
    parser.add_argument("--out", metavar="DIR", type=Path, default=Path("out/train"), help="default out/train")
    parser.add_argument("--resume", action="store_true", help="continue the run in DIR from its newest checkpoint")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def run(args: argparse.Namespace) -> int:
    from agents.ppo_config import TrainConfig
    from agents.ppo_training import TrainingInterrupted, train

    try:
        config = TrainConfig.from_yaml(args.config)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.preset is not None and args.preset != config.preset:
        raise UsageError(f"--preset {args.preset} differs from the config's task.preset {config.preset!r}; "
                         "edit the config (the turn map and the agent belong to one preset)")
    ensure_dir("--out", args.out)
    try:
        result = train(config, args.out, resume=args.resume, progress=not args.no_progress,
                       config_text=args.config.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    except TrainingInterrupted as exc:
        r = exc.result
        print(f"flagellum: interrupted after {r.decisions} decisions; wrote {r.out_dir}/model.zip, vecnormalize.pkl "
              f"and a checkpoint; --resume continues from there", file=sys.stderr)
        return 130
    budget = " (stopped by the wall-time budget)" if result.stopped_by_budget else ""
    print(f"trained {result.decisions} decisions in {result.wall_time_s / 60:.1f} min{budget}; wrote "
          f"{result.out_dir}/model.zip and vecnormalize.pkl; use it with --controller ppo:{result.out_dir}")
    return 0
