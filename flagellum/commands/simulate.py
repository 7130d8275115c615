"""``flagellum simulate``: one swim at a constant speed or along a motor schedule."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from flagellum.commands.common import UsageError, build_config, parse_number, parse_overrides
from physics.run import (DEFAULT_NODE_RECORD_INTERVAL_S, DEFAULT_RECORD_INTERVAL_S, MAX_DURATION_S, RunResult,
                         run_simulation, validate_run_arguments)
from physics.schedule import MAX_RPM, MotorSchedule

NAME = "simulate"
HELP = "swim at a constant motor speed or along a schedule; write summary, trajectory and plot"
DESCRIPTION = ("Run the head + flagellum simulation and write DIR/summary.json, DIR/trajectory.npz and "
               "DIR/trajectory.png. Ctrl-C stops early and still writes what was computed.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    speed = parser.add_mutually_exclusive_group(required=True)
    speed.add_argument("--omega-rpm", metavar="W", help=f"constant motor speed, rpm (0 to {MAX_RPM:g})")
    speed.add_argument("--schedule", metavar="FILE", type=Path,
                       help="piecewise-constant speed: CSV 'time_s,omega_rpm' rows or JSON [[t, w], ...]")
    parser.add_argument("--duration", metavar="T", required=True, help=f"simulated time, s (> 0, <= {MAX_DURATION_S:g})")
    parser.add_argument("--head-radius", metavar="B",
                        help="head radius, m (0 = no head; same as --set head_radius=B)")
    parser.add_argument("--out", metavar="DIR", type=Path, default=Path("out/simulate"),
                        help="output directory (default: out/simulate)")
    parser.add_argument("--record-interval", metavar="S", default=str(DEFAULT_RECORD_INTERVAL_S),
                        help=f"head sampling interval, s (default: {DEFAULT_RECORD_INTERVAL_S:g})")
    parser.add_argument("--node-record-interval", metavar="S", default=str(DEFAULT_NODE_RECORD_INTERVAL_S),
                        help=f"full-shape snapshot interval, s (default: {DEFAULT_NODE_RECORD_INTERVAL_S:g})")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def _schedule(args: argparse.Namespace) -> MotorSchedule:
    try:
        if args.schedule is not None:
            return MotorSchedule.load(args.schedule)
        w = parse_number("--omega-rpm", args.omega_rpm, f"a finite speed >= 0 and <= {MAX_RPM:g} rpm")
        return MotorSchedule.constant(w)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    overrides = parse_overrides(args.set)
    if args.head_radius is not None:
        if "head_radius" in overrides:
            raise UsageError("--head-radius and --set head_radius both given; use one")
        parse_number("--head-radius", args.head_radius, "a radius >= 0 m (0 = no head)")
        overrides["head_radius"] = args.head_radius
    params, numerics = build_config(overrides, getattr(args, 'preset', None))
    schedule = _schedule(args)
    duration = parse_number("--duration", args.duration, f"a time > 0 and <= {MAX_DURATION_S:g} s", positive=True)
    if duration > MAX_DURATION_S:
        raise UsageError(f"--duration {args.duration!r} is not allowed; allowed: a time > 0 and <= {MAX_DURATION_S:g} s")
    record = parse_number("--record-interval", args.record_interval, "a finite time > 0 s", positive=True)
    node_record = parse_number("--node-record-interval", args.node_record_interval, "a finite time > 0 s",
                               positive=True)
    try:
        validate_run_arguments(numerics, duration, record, node_record, n_nodes=params.n_nodes)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    out: Path = args.out
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--out {str(out)!r}: cannot create the directory ({exc.strerror})") from None

    result = run_simulation(params, numerics, schedule, duration, record_interval_s=record,
                            node_record_interval_s=node_record, progress=not args.no_progress)
    t_end = _fmt(result.summary["sim_time_s"], ".4g", " s")
    if result.interrupted:
        print(f"interrupted at t = {t_end}; writing the partial results computed so far")
    elif result.error is not None:
        print(f"stopped at t = {t_end} by an error; writing the partial results computed so far")
    paths = write_outputs(result, out, params.head_radius, schedule)
    _report(result, paths)
    if result.error is not None:
        print(f"flagellum: simulation failed: {result.error}", file=sys.stderr)
        return 1
    return 130 if result.interrupted else 0


def write_outputs(result: RunResult, out: Path, head_radius_m: float,
                  schedule: MotorSchedule | None = None) -> dict[str, Path]:
    """summary.json, trajectory.npz and trajectory.png in ``out``; the plot's title describes ``schedule`` (else
    the mean motor speed)."""
    from flagellum.plots import save_trajectory_plot, schedule_label  # matplotlib only when needed

    paths = result.save(out)
    s = result.summary
    speed = (schedule_label(schedule, s["sim_time_s"]) if schedule is not None
             else f"mean omega = {_fmt(s['omega_rpm'], '.4g', ' rpm')}")
    title = f"t = {_fmt(s['sim_time_s'], '.3g', ' s')}, {speed}, b = {head_radius_m * 100:.3g} cm"
    paths["plot"] = save_trajectory_plot(result.trajectory, out / "trajectory.png", head_radius_m, title)
    return paths


def _fmt(v: float | None, spec: str, unit: str = "") -> str:
    return "n/a" if v is None else format(v, spec) + unit


def _report(result: RunResult, paths: dict[str, Path]) -> None:
    s = result.summary
    fmt = _fmt
    print(f"simulated {fmt(s['sim_time_s'], '.4g', ' s')} in {s['steps']} steps ({s['wall_time_s']:.1f} s wall)")
    print(f"displacement {fmt(s['displacement_m'], '.4g', ' m')}, L'/L {fmt(s['end_to_end_ratio'], '.4f')}, "
          f"distance per motor turn {fmt(s['distance_per_motor_turn_m'], '.4g', ' m')}")
    for key in ("summary", "trajectory", "plot"):
        print(f"wrote {paths[key]}")
