"""``flagellum follow``: one controller follows one path; summary, path plot and ω(t) plot."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

from flagellum.commands.common import (DEFAULT_PRESET_ARG, UsageError, add_randomize_arguments, ensure_dir,
                                      parse_int, parse_number, parse_randomize, parse_workers)

NAME = "follow"
HELP = "drive FlagellumSteer-v0 along a path with a controller; write summary.json and plots (Fig. 6)"
DESCRIPTION = ("Follow --path (square = the paper's 0.25 m square, or a path file) with --controller (rule = the "
               "turn planner with the preset's turn map; rule:MAP.json; adaptive / adaptive:MAP.json: the planner "
               "correcting its map online; rule@line=W / adaptive@line=W: either one also weighing how far a turn "
               "ends from the path's line, W m per m, e.g. adaptive@line=2; @cap=DEG: at most DEG degrees per burst, "
               "larger turns in several, e.g. adaptive@line=2,cap=90; horizon / horizon:MAP.json: a two-move "
               "search over that corrected map; ppo / ppo:AGENT_DIR; rllib:CHECKPOINT_DIR: an agent trained "
               "with 'flagellum train --engine ray') and write "
               "DIR/summary.json, DIR/path.png (target vs achieved, x-y and 3-D), DIR/omega.png (ω(t), L'/L) "
               "and the per-step trace: DIR/trace.npz for one controller, DIR/trace_<controller>.npz (each "
               "controller's spec with other characters than letters, digits, '-' and '_' as '_') for several. "
               "Several controllers run at once, one worker process each (--workers); Ctrl-C or SIGTERM writes the "
               "episodes so far.")
ACCEPTS_SET = False  # the turn map fixes the swimmer: choose --preset
PRESET = DEFAULT_PRESET_ARG


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--path", default="square", help="'square' or a path file (JSON); default square")
    parser.add_argument("--controller", action="append", default=None,
                        help="rule | rule:MAP.json | adaptive | adaptive:MAP.json | rule@line=W | adaptive@line=W | "
                             "rule@cap=DEG | adaptive@cap=DEG | adaptive@line=W,cap=DEG | "
                             "horizon | horizon:MAP.json | ppo | ppo:AGENT_DIR | ppo-scratch | ppo-scratch:AGENT_DIR | rllib:CHECKPOINT_DIR (repeat to "
                             "compare on one plot; default rule)")
    parser.add_argument("--out", metavar="DIR", type=Path, default=Path("out/follow"), help="default out/follow")
    parser.add_argument("--reach-radius", metavar="M", help="waypoint reach radius, m (default: the path's or 0.015)")
    parser.add_argument("--seed", default="0", help="env seed, an integer >= 0 (default 0); with --randomize it draws "
                        "the swimmer")
    add_randomize_arguments(parser)
    parser.add_argument("--workers", help="controllers run at once, each in its own process (an integer >= 1; "
                        "default: one per controller, up to the cores; 1: one after the other in this process)")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def trace_name(spec: str, n_controllers: int) -> str:
    """``trace.npz`` for one controller, ``trace_<spec>.npz`` (spec made file-name safe) for several."""
    return "trace.npz" if n_controllers == 1 else f"trace_{re.sub(r'[^A-Za-z0-9_-]', '_', spec)}.npz"


def run(args: argparse.Namespace) -> int:
    from agents.evaluation import check_controllers, resolve_paths
    from agents.path_following import FollowTask, check_unique_controllers
    from physics.errors import is_interrupt
    from physics.run import stop_requests

    preset = args.preset
    try:
        path = resolve_paths([args.path], option="--path")[0]
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    overrides = {}
    if args.reach_radius is not None:
        overrides["reach_radius_m"] = parse_number("--reach-radius", args.reach_radius, "a radius > 0 m",
                                                   positive=True)
    seed = parse_int("--seed", args.seed, 0)
    randomize = parse_randomize(args)
    if randomize is not None:
        overrides["randomize"] = randomize
    specs = args.controller or ["rule"]
    workers, _ = parse_workers(args)
    if workers is None:
        from batch.backends import default_workers

        workers = min(len(specs), default_workers())
    try:
        check_unique_controllers(specs)
        check_controllers(specs, [path], preset, overrides)  # every controller builds, before any output
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    ensure_dir("--out", args.out)
    traces, summary = {}, {"path": path.to_dict(), "preset": preset, "seed": seed, "randomize": randomize,
                           "controllers": {}, "interrupted": False}
    interrupted = False
    parallel = workers > 1 and len(specs) > 1
    tasks = [FollowTask(spec, path, preset, tuple(sorted(overrides.items())), seed, progress=not args.no_progress,
                        position=k if parallel else None) for k, spec in enumerate(specs)]
    if parallel:
        return _run_parallel(args, tasks, path, preset, min(workers, len(specs)), summary)
    try:
        for task in tasks:
            spec = task.controller
            metrics, trace = task.run()
            traces[spec] = trace
            summary["controllers"][spec] = metrics
            with stop_requests() as stop:  # the trace of a finished (or interrupted) episode is written whole
                trace.save_npz(args.out / trace_name(spec, len(specs)))
            _report(spec, metrics)
            if metrics.get("interrupted") or stop.requested:
                interrupted = True
                break
    except BaseException as exc:  # Ctrl-C or SIGTERM between episodes: write what was computed
        if not is_interrupt(exc):
            raise
        interrupted = True
    return _write(args, specs, path, preset, traces, summary, interrupted)


def _run_parallel(args: argparse.Namespace, tasks: list, path, preset: str, workers: int, summary: dict) -> int:
    """The controllers' episodes (``tasks``) at once on ``workers`` processes
    (``agents.path_following.follow_controllers``)."""
    from agents.path_following import follow_controllers
    from physics.errors import is_interrupt
    from physics.run import stop_requests

    specs = [t.controller for t in tasks]
    traces, interrupted = {}, False
    try:
        episodes, interrupted = follow_controllers(tasks, workers)
    except BaseException as exc:  # a second Ctrl-C or SIGTERM: the episodes are lost, the summary says so
        if not is_interrupt(exc):
            raise
        episodes, interrupted = {}, True
    with stop_requests():  # the traces are written whole (a second signal stops at once)
        for spec, (metrics, trace) in episodes.items():
            traces[spec] = trace
            summary["controllers"][spec] = metrics
            trace.save_npz(args.out / trace_name(spec, len(specs)))
            _report(spec, metrics)
            interrupted = interrupted or bool(metrics.get("interrupted"))
    return _write(args, specs, path, preset, traces, summary, interrupted)


def _write(args: argparse.Namespace, specs: list[str], path, preset: str, traces: dict, summary: dict,
           interrupted: bool) -> int:
    """summary.json and the figures of the episodes in ``traces``; the exit status (130: interrupted)."""
    from agents.follow_plots import omega_figure, path_figure, save
    from physics.run import stop_requests

    with stop_requests() as stop:  # a signal while writing waits for the files (a second one stops at once)
        summary["interrupted"] = interrupted
        summary["not_run"] = [s for s in specs if s not in summary["controllers"]]
        written = ["summary.json"]
        if traces:
            title = f"{path.name} path, {preset} preset" + (" (interrupted)" if interrupted else "")
            save(path_figure(traces, title), args.out / "path.png")
            save(omega_figure(traces, title), args.out / "omega.png")
            written += ["path.png", "omega.png"]
        (args.out / "summary.json").write_text(json.dumps(summary, indent=1, default=float) + "\n",
                                               encoding="utf-8")
        if interrupted:
            print(f"interrupted; wrote what was computed: {args.out}/{', '.join(written)}"
                  + (f" (not run: {', '.join(summary['not_run'])})" if summary["not_run"] else ""))
        else:
            print(f"wrote {args.out}/{', '.join(written)}")
    return 130 if interrupted or stop.requested else 0


def _report(spec: str, metrics: dict) -> None:
    print(f"{spec}: {'interrupted, ' if metrics.get('interrupted') else ''}success {metrics['success']}, "
          f"waypoints {metrics['waypoints_reached']}/"
          f"{metrics['n_waypoints']}, mean cross-track {metrics['mean_cross_track_m'] * 100:.2f} cm, "
          f"max {metrics['max_cross_track_m'] * 100:.2f} cm, "
          + (f"max dz/dL {metrics['max_out_of_plane_ratio'] * 100:.2f} %, "
             if metrics['max_out_of_plane_ratio'] is not None else "")
          + f"{metrics['time_s']:.0f} s simulated in {metrics['wall_time_s']:.0f} s, "
            f"{metrics['buckling_events']} buckling events, {metrics['energy_J'] * 1e3:.2f} mJ")
