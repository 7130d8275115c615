"""``flagellum evaluate``: controllers x paths, in parallel and resumable; results.json and a table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from flagellum.commands.common import (DEFAULT_PRESET_ARG, SCHEDULER_HELP, UsageError, parse_int, parse_number,
                                       parse_workers)

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
                        help="rule | rule:MAP.json | adaptive | adaptive:MAP.json | horizon | horizon:MAP.json | ppo | ppo:AGENT_DIR (repeatable)")
    parser.add_argument("--out", metavar="DIR", type=Path, default=Path("out/evaluate"), help="default out/evaluate")
    parser.add_argument("--workers", metavar="N", help="local worker processes (default: one per core)")
    parser.add_argument("--scheduler", metavar="ADDR", help=SCHEDULER_HELP)
    parser.add_argument("--resume", action="store_true", help="keep the episodes already in DIR")
    parser.add_argument("--report-only", action="store_true",
                        help="run nothing: write results.json/.md from the episodes already in DIR")
    parser.add_argument("--randomize", metavar="F",
                        help="model error: each path's swimmer has E, mu and b drawn within +-F (a fraction, e.g. "
                             "0.05) and the helix pitch and radius within +-G (--randomize-geometry, default 0.4 F), "
                             "while the controllers keep the nominal turn map; the k-th path uses env seed SEED0 + k")
    parser.add_argument("--randomize-geometry", metavar="G",
                        help="with --randomize: the helix pitch and radius within +-G (a fraction in [0, 0.5]; "
                             "default 0.4 F)")
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
    overrides = None
    if args.randomize is not None:
        f = parse_number("--randomize", args.randomize, "a fraction in (0, 0.5]", positive=True)
        if f > 0.5:
            raise UsageError(f"--randomize {args.randomize!r} is not allowed; allowed: a fraction in (0, 0.5]")
        g = 0.4 * f
        if args.randomize_geometry is not None:
            g = parse_number("--randomize-geometry", args.randomize_geometry, "a fraction in [0, 0.5]")
            if not 0.0 <= g <= 0.5:
                raise UsageError(f"--randomize-geometry {args.randomize_geometry!r} is not allowed; allowed: a "
                                 "fraction in [0, 0.5]")
        overrides = {"randomize": {"youngs_modulus": f, "viscosity": f, "head_radius": f, "geometry": g,
                                   "obs_noise_std": 0.0}}
    elif args.randomize_geometry is not None:
        raise UsageError("--randomize-geometry needs --randomize")
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
