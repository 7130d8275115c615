"""``flagellum sweep``: a parameter sweep from a YAML/TOML file, in parallel and resumable."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from flagellum.commands.common import PARAMETER_DEFAULTS, SCHEDULER_HELP, UsageError, parse_overrides, parse_workers
from batch.sweep import (RESULTS_FILE, SweepConfig, SweepConfigError, SweepError, SweepIncomplete,
                             SweepInterrupted, load_sweep_config, run_sweep)
from batch.backends import default_workers

NAME = "sweep"
HELP = "run a parameter sweep (YAML/TOML file) on all cores or a Dask cluster; resumable"
DESCRIPTION = ("Run one constant-speed swim per point of the sweep in FILE (see examples/sweep_small.yaml), "
               "in parallel, and append each finished point to DIR/results.jsonl at once (trajectories in "
               "DIR/points/). Ctrl-C keeps the finished points; --resume runs only the missing ones. "
               "--set NAME=VALUE adds to the file's 'fixed' parameters.")

MAX_TABLE_ROWS = 40
_COLUMNS = (("displacement_m", "displacement_m", ".4g"), ("distance_per_motor_turn_m", "per_turn_m", ".4g"),
            ("end_to_end_ratio", "L'/L", ".4f"), ("mean_motor_power_W", "power_W", ".3g"))


PRESET = (None, "the sweep file's preset:, else " + PARAMETER_DEFAULTS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", metavar="FILE", type=Path, required=True,
                        help="sweep file: .yaml, .yml or .toml")
    parser.add_argument("--out", metavar="DIR", type=Path,
                        help="output directory (default: out/sweep/<FILE name without extension>)")
    parser.add_argument("--workers", metavar="N",
                        help=f"local worker processes, one simulation each (default: one per core, "
                             f"{default_workers()} here)")
    parser.add_argument("--resume", action="store_true",
                        help="keep the results already in DIR and run only the missing points")
    parser.add_argument("--retry-failed", action="store_true",
                        help="with --resume, also run again the points that ended in an error")
    parser.add_argument("--scheduler", metavar="ADDR", help=SCHEDULER_HELP)
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def _load(args: argparse.Namespace) -> SweepConfig:
    """The sweep file with ``--set`` values added to its ``fixed`` parameters."""
    overrides = parse_overrides(args.set)
    try:
        config = load_sweep_config(args.config)
    except SweepConfigError as exc:
        raise UsageError(str(exc)) from None
    swept = [name for name in overrides if name in config.sweep]
    if swept:
        raise UsageError(f"--set {swept[0]}: {swept[0]} is swept in {args.config}; "
                         "give it either under 'sweep' or with --set")
    if args.preset is not None:
        if config.preset is not None and config.preset != args.preset:
            raise UsageError(f"--preset {args.preset} conflicts with preset: {config.preset} in {args.config}")
        config = dataclasses.replace(config, preset=args.preset)
    try:
        return config.with_fixed(overrides) if overrides else config
    except SweepConfigError as exc:
        raise UsageError(f"--set: {exc}") from None


def run(args: argparse.Namespace) -> int:
    config = _load(args)
    workers, _ = parse_workers(args)
    if args.retry_failed and not args.resume:
        raise UsageError("--retry-failed needs --resume")
    out: Path = args.out if args.out is not None else Path("out/sweep") / args.config.stem
    def announce() -> None:  # once the folder and the scheduler are checked: errors come without it
        print(f"sweep: {len(config)} points ({config.mode} over {', '.join(config.sweep)}), "
              f"{config.duration_s:g} s each -> {out}", flush=True)

    try:
        records = run_sweep(config, out, workers=workers, resume=args.resume, progress=not args.no_progress,
                            scheduler=args.scheduler, retry_failed=args.retry_failed, on_start=announce)
    except SweepInterrupted as exc:
        print(f"flagellum: interrupted; {len(exc.results)} of {exc.total} points are saved in "
              f"{out / RESULTS_FILE}; run again with --resume to finish", file=sys.stderr)
        return 130
    except SweepIncomplete as exc:
        print(f"flagellum: {exc}", file=sys.stderr)
        return 1
    except (SweepError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    if len(records) <= MAX_TABLE_ROWS:
        print(format_table(records, list(config.sweep)))
    print(f"wrote {out / RESULTS_FILE} ({len(records)} points)")
    failed = [r for r in records if r["status"] != "ok"]
    if failed:
        print(f"flagellum: {len(failed)} of {len(records)} points ended in an error (first: point "
              f"{failed[0]['index']}: {failed[0]['error'].splitlines()[0]}); see 'error' in {out / RESULTS_FILE}",
              file=sys.stderr)
        return 1
    return 0


def format_table(records: list[dict[str, Any]], names: list[str]) -> str:
    """One row per point: index, swept values, status and the main summary numbers."""
    head = ["#", *names, "status", *(title for _, title, _ in _COLUMNS), "wall_s"]
    rows = []
    for r in records:
        s = r.get("summary") or {}
        cells = [str(r["index"]), *(_cell(r["values"].get(n), "g") for n in names), r["status"],
                 *(_cell(s.get(key), spec) for key, _, spec in _COLUMNS), _cell(r.get("wall_time_s"), ".1f")]
        rows.append(cells)
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(head)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in [head, *rows])


def _cell(value: Any, spec: str) -> str:
    if value is None:
        return "n/a"
    return format(value, spec) if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)
