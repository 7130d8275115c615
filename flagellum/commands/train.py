"""``flagellum train``: train a PPO agent from a YAML config, with stable-baselines3 on this machine (the default)
or with Ray RLlib on a Ray cluster (``--engine ray``, the package's [ray] extra); resumable."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from flagellum.commands.common import UsageError, ensure_dir

NAME = "train"
HELP = ("train an agent: PPO correcting the turn planner, or PPO/SAC from scratch (stable-baselines3 on the "
        "CPU, or Ray RLlib with --engine ray); resumable")
DESCRIPTION = ("Train from --config into --out. --engine sb3 (the default; rl-zoo3-style YAML, default "
               "agents/configs/ppo_residual_adaptive.yml, the shipped residual agent's; algorithm: ppo or sac; "
               "task.design: residual or burst, docs/rl.md): model.zip, vecnormalize.pkl, "
               "meta.json, config.yml, episodes.csv, eval/, checkpoints/, tb/ (tensorboard); use the result with "
               "--controller ppo:DIR (residual) or ppo-scratch:DIR (burst). --engine ray (RLlib PPO, env runners on a local Ray or on the cluster at "
               "--address; default config agents/configs/rllib_ppo_surrogate.yml; keys: docs/ray.md): run.json, "
               "config.yml, progress.csv, checkpoints/; use a FlagellumTurn or FlagellumBurst run with --controller "
               "rllib:DIR. "
               "--resume continues from the newest checkpoint; Ctrl-C or SIGTERM saves one and exits.")
ACCEPTS_SET = False  # the turn map fixes the swimmer: edit the config's task
PRESET = (None, "the config's task.preset (an other value is refused); not used with --engine ray (the config's "
                "env_id and env_kwargs)")
#: Default config of each engine (package data, agents/configs/).
DEFAULT_CONFIGS = {"sb3": "ppo_residual_adaptive.yml", "ray": "rllib_ppo_surrogate.yml"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--engine", choices=tuple(DEFAULT_CONFIGS), default="sb3",
                        help="sb3: stable-baselines3 on this machine (default); ray: Ray RLlib, env runners spread "
                             "over a Ray cluster (needs the package's [ray] extra)")
    parser.add_argument("--config", metavar="FILE", type=Path, default=None,
                        help="training config (YAML; default agents/configs/ppo_residual_adaptive.yml, the shipped "
                             "agent's, for sb3; agents/configs/rllib_ppo_surrogate.yml for ray)")
    parser.add_argument("--out", metavar="DIR", type=Path, default=Path("out/train"), help="default out/train")
    parser.add_argument("--resume", action="store_true", help="continue the run in DIR from its newest checkpoint")
    parser.add_argument("--address", metavar="ADDR", default=None,
                        help="--engine ray: the Ray cluster to run on, 'auto' (the one 'ray start' started on this "
                             "machine) or HOST:PORT of its head (default: the config's address; none: a local Ray "
                             "started by this command)")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def run(args: argparse.Namespace) -> int:
    from agents.assets import package_file

    config_file = args.config if args.config is not None else package_file("configs", DEFAULT_CONFIGS[args.engine])
    if args.engine == "ray":
        return _run_ray(args, config_file)
    if args.address is not None:
        raise UsageError(f"--address {args.address!r} is not allowed with --engine sb3 (it trains on this machine); "
                         "allowed: --address with --engine ray")
    from agents.ppo_config import TrainConfig
    from agents.ppo_training import TrainingInterrupted, train

    try:
        config = TrainConfig.from_yaml(config_file)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.preset is not None and args.preset != config.preset:
        raise UsageError(f"--preset {args.preset} differs from the config's task.preset {config.preset!r}; "
                         "edit the config (the turn map and the agent belong to one preset)")
    ensure_dir("--out", args.out)
    try:
        result = train(config, args.out, resume=args.resume, progress=not args.no_progress,
                       config_text=config_file.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    except TrainingInterrupted as exc:
        r = exc.result
        print(f"flagellum: interrupted after {r.decisions} decisions; wrote {r.out_dir}/model.zip, vecnormalize.pkl "
              f"and a checkpoint; --resume continues from there", file=sys.stderr)
        return 130
    budget = " (stopped by the wall-time budget)" if result.stopped_by_budget else ""
    use = (f"use it with --controller ppo:{result.out_dir}" if config.design == "residual" else
           f"fly it in FlagellumBurst-* with scripts/evaluate_burst_agent.py --agent {result.out_dir}")
    print(f"trained {result.decisions} decisions in {result.wall_time_s / 60:.1f} min{budget}; wrote "
          f"{result.out_dir}/model.zip and vecnormalize.pkl; {use}")
    return 0


def _run_ray(args: argparse.Namespace, config_file: Path) -> int:
    """``--engine ray``: agents.rllib_training."""
    from agents.rllib_config import RayTrainConfig, rllib_controller_env_ids

    try:
        import ray  # noqa: F401
    except ImportError:
        raise UsageError("--engine ray needs Ray RLlib, which is not installed; allowed: install the package's [ray] "
                         "extra: pip install '.[ray]' in a clone (or 'flagellum-swimmer[ray]')") from None
    if args.preset is not None:
        raise UsageError(f"--preset {args.preset} is not used with --engine ray; allowed: the config's env_id and "
                         "env_kwargs (e.g. env_kwargs: {preset: fast})")
    try:
        config = RayTrainConfig.from_yaml(config_file)
        if args.address is not None:
            config = config.with_address(args.address)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    ensure_dir("--out", args.out)
    from agents.rllib_training import TrainingInterrupted, train

    try:
        result = train(config, args.out, resume=args.resume, progress=not args.no_progress,
                       config_text=config_file.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    except TrainingInterrupted as exc:
        r = exc.result
        print(f"flagellum: interrupted after {r.iterations} iterations ({r.env_steps} env steps); newest checkpoint "
              f"{r.checkpoint}; --resume continues from there", file=sys.stderr)
        return 130
    budget = " (stopped by the wall-time budget)" if result.stopped_by_budget else ""
    use = (f"; use it with --controller rllib:{result.out_dir}" if config.env_id in rllib_controller_env_ids()
           else "")
    print(f"trained {result.iterations} iterations ({result.env_steps} env steps) in {result.wall_time_s / 60:.1f} "
          f"min, {result.cpu_time_s / 60:.1f} CPU min{budget}; checkpoint {result.checkpoint}{use}")
    return 0
