"""``flagellum evaluate``: controllers x paths, in parallel and resumable; results.json and a table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from flagellum.commands.common import (DEFAULT_PRESET_ARG, SCHEDULER_HELP, UsageError, add_randomize_arguments,
                                       parse_int, parse_randomize, parse_workers)

NAME = "evaluate"
HELP = "run each controller on each path (parallel, resumable); write results.json and results.md"
DESCRIPTION = ("Every --controller on every path of --paths ('square', path files or folders of them), one "
               "episode each, saved as it finishes (DIR/results.jsonl; --resume runs only the missing ones). "
               "Writes DIR/results.json (per_path and aggregate) and DIR/results.md. Each controller is built once "
               "before any episode runs, so a missing or bad turn map or agent stops the command at once.")
ACCEPTS_SET = False  # the turn map fixes the swimmer: choose --preset
PRESET = DEFAULT_PRESET_ARG


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--paths", nargs="+", required=True,
                        help="'square', 'eval' (the 20 evaluation paths shipped with the package), path files (JSON) "
                             "or folders of them")
    parser.add_argument("--controller", action="append", required=True,
                        help="rule | rule:MAP.json | adaptive | adaptive:MAP.json | rule@line=W | adaptive@line=W (also weighing "
                             "how far a turn ends from the path's line, W m per m) | rule@cap=DEG | adaptive@cap=DEG (at most DEG "
                             "degrees per burst; combine as adaptive@line=2,cap=90) | horizon | horizon:MAP.json | ppo "
                             "| ppo:AGENT_DIR | ppo-scratch | ppo-scratch:AGENT_DIR | rllib:CHECKPOINT_DIR (repeatable)")
    parser.add_argument("--out", metavar="DIR", type=Path, default=Path("out/evaluate"), help="default out/evaluate")
    parser.add_argument("--workers", metavar="N", help="local worker processes (default: one per core)")
    parser.add_argument("--scheduler", metavar="ADDR", help=SCHEDULER_HELP)
    parser.add_argument("--resume", action="store_true", help="keep the episodes already in DIR")
    parser.add_argument("--report-only", action="store_true",
                        help="run nothing: write results.json/.md from the episodes already in DIR")
    add_randomize_arguments(parser, "; the k-th path uses env seed SEED0 + k")
    parser.add_argument("--seed0", metavar="N", default="0",
                        help="env seed of the first path, an integer >= 0 (default 0); with --randomize the k-th path's "
                             "swimmer is drawn with seed N + k, so swimmers no earlier run met come from seeds of your "
                             "choice")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def run(args: argparse.Namespace) -> int:
    from agents.evaluation import EpisodesNotRun, evaluate, resolve_paths
    from batch.store import SweepError

    try:
        paths = resolve_paths(args.paths)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    workers, scheduler = parse_workers(args)
    seed0 = parse_int("--seed0", args.seed0, 0)
    randomize = parse_randomize(args)
    overrides = None if randomize is None else {"randomize": randomize}
    try:
        results = evaluate(paths, args.controller, args.preset, args.out, workers=workers, scheduler=scheduler,
                           resume=args.resume, progress=not args.no_progress, report_only=args.report_only,
                           env_overrides=overrides, seed_per_path=overrides is not None, seed0=seed0)
    except (ValueError, SweepError) as exc:  # a bad controller name, a locked or used DIR
        raise UsageError(str(exc)) from None
    except EpisodesNotRun as exc:  # workers died: the partial summary is written, the status says it is partial
        print(f"flagellum: {exc}", file=sys.stderr)
        return 1
    print((args.out / "results.md").read_text(encoding="utf-8"))
    for c, agg in results["aggregate"].items():
        rate = "n/a" if agg["success_rate"] is None else f"{agg['success_rate']:.0%}"
        print(f"{c}: success rate {rate} over {agg['episodes']} paths")
    return 0
