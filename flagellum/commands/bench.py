"""``flagellum bench``: measure the speed/accuracy ladder against the paper preset."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from flagellum_bench.fidelity import BURST_RPM, BURST_TC, QUICK_REFERENCE, TURN_TCS
from flagellum.commands.common import SCHEDULER_HELP, UsageError, ensure_dir, parse_workers

NAME = "bench"
HELP = "measure speed and accuracy of the fidelity configurations against the paper preset"
DESCRIPTION = ("Runs every configuration of the fidelity ladder on the same tasks (swim speed at 10 rpm, "
               "L'/L after 100 s at 90 rpm; with --full also turning angles and the buckling threshold), "
               "in parallel (local processes, or a Dask cluster with --scheduler) and resumably, and reports "
               "real-time factors and relative errors against 'paper' (with --quick: against 'reference'). "
               "The ladder fixes every configuration, so bench takes neither --set nor --preset.")
ACCEPTS_SET = False
PRESET = None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true",
                        help="every tier in one run, one row each (minutes): each preset's steady 10 rpm real-time "
                             "factor (after the helix has settled) and swim speed, bursts of "
                             f"{', '.join(f'{t:g}' for t in (*TURN_TCS, BURST_TC))} s at {BURST_RPM:g} rpm (turn "
                             f"angles; real-time factor and L'/L of the {BURST_TC:g} s one), the relaxation after it, "
                             "the rule planner's CPU and wall time on one held-out path, env steps/s under its actions "
                             f"and a random policy, errors against {QUICK_REFERENCE!r}; and the turn-level surrogate's "
                             "episode on that path, decisions/s and its map's error between samples")
    parser.add_argument("--full", action="store_true", help="the ladder with all metrics (turning angles, omega_b): "
                                                            "hours")
    parser.add_argument("--json", default=None,
                        help="where to write the JSON report (default out/bench/quick.json with --quick, else "
                             "out/bench/fidelity.json; the .md (and .png) reports go beside it)")
    parser.add_argument("--results", default=None,
                        help="task results file (JSONL, resumable); default: next to --json")
    parser.add_argument("--workers", metavar="N", help="local worker processes (default: one per core)")
    parser.add_argument("--scheduler", metavar="ADDR", help=SCHEDULER_HELP)
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def run(args: argparse.Namespace) -> int:
    from flagellum_bench.fidelity import (FULL_METRICS, LADDER, QUICK_METRICS, REPORT_NOTES, missing_tasks,
                                    rows_from, run_fidelity)
    from flagellum_bench.report import write_report
    from batch.store import SweepError

    workers, scheduler = parse_workers(args)
    if args.quick and args.full:
        raise UsageError("--quick and --full both given; allowed: one of them (or neither: the ladder's cheap metrics)")
    metrics = FULL_METRICS if args.full else QUICK_METRICS
    out = Path(args.json or ("out/bench/quick.json" if args.quick else "out/bench/fidelity.json"))
    results = Path(args.results) if args.results else out.with_suffix(".results.jsonl")
    ensure_dir("--json", out.parent)
    ensure_dir("--results", results.parent)
    for option, f in (("--json", out), ("--results", results)):
        if f.is_dir():
            raise UsageError(f"{option} {str(f)!r} is a directory; allowed: a file path")
    t0 = time.perf_counter()
    if args.quick:
        return _run_quick(out, results, workers, scheduler, not args.no_progress, t0)
    try:
        done = run_fidelity(results, LADDER, metrics, workers=workers, progress=not args.no_progress,
                            scheduler=scheduler)
    except SweepError as exc:  # BackendError: no dask.distributed, or the scheduler cannot be reached
        raise UsageError(str(exc)) from None
    rows = rows_from(done)
    write_report(rows, out, out.with_suffix(".md"), out.with_suffix(".png"),
                 "flagellum bench" + (" --full" if args.full else ""),
                 time.perf_counter() - t0, missing=missing_tasks(done, LADDER, metrics), notes=REPORT_NOTES)
    for r in rows:
        err = r["errors"].get("swim_per_turn_10rpm")
        rtf = r["real_time_factor"]
        print(f"{r['config']:45s} RTF {rtf if rtf is None else round(rtf, 2)!s:>8}  "
              f"swim-speed error {'—' if err is None else f'{100 * err:.2f} %'}")
    print(f"wrote {out}, {out.with_suffix('.md')}, {out.with_suffix('.png')}")
    return 0


def _run_quick(out: Path, results: Path, workers, scheduler, progress: bool, t0: float) -> int:
    import json

    from flagellum_bench.fidelity import quick_configs, quick_rows, quick_tasks, run_fidelity
    from flagellum_bench.quick_report import quick_markdown, quick_pareto_plot
    from batch.store import SweepError

    configs = quick_configs()
    tasks = quick_tasks(configs)
    try:
        done = run_fidelity(results, configs, workers=workers, progress=progress, scheduler=scheduler, tasks=tasks)
    except SweepError as exc:
        raise UsageError(str(exc)) from None
    rows = quick_rows(done, configs)
    out.write_text(json.dumps(rows, indent=1) + "\n")
    missing = [f"{c.name}: {m}" for c, m in tasks if (c.name, m) not in done]
    quick_pareto_plot(rows, out.with_suffix(".png"))
    out.with_suffix(".md").write_text(quick_markdown(rows, time.perf_counter() - t0, missing,
                                                     figure=out.with_suffix(".png").name))
    for r in rows:
        print(f"{r['config']:10s} " + "  ".join(f"{k} {_fmt(r[k])}" for k in
                                                ("real_time_factor", "burst_real_time_factor", "episode_wall_s",
                                                 "decisions_per_cpu_s"))
              + "  errors " + ", ".join(f"{k} {100 * v:.2f} %" for k, v in r["errors"].items()))
    print(f"wrote {out}, {out.with_suffix('.md')}, {out.with_suffix('.png')}")
    return 0


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.3g}"
