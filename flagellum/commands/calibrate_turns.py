"""``flagellum calibrate-turns``: measure the turn map (Fig. 5d) for the planner; parallel, resumable."""

from __future__ import annotations

import argparse
from pathlib import Path

from flagellum.commands.common import (SCHEDULER_HELP, UsageError, build_config, ensure_dir, parse_number,
                                       parse_overrides, parse_workers)

NAME = "calibrate-turns"
HELP = "measure turning angle vs burst length (the planner's turn map, Fig. 5d); parallel, resumable"
DESCRIPTION = ("From steady swimming at --omega-l, burst at --omega-h for each t_c and each starting phase of "
               "the flagellum's rotation, return to --omega-l until the path is straight, and record theta, phi "
               "and the turn's direction relative to the flagellum's phase. Each turn is saved as it finishes "
               "(FILE.runs/results.jsonl; --resume measures only the missing ones); the map goes to FILE (JSON) "
               "and its plot to FILE with .png.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", metavar="FILE", type=Path,
                        help="turn map file (default: <preset>.json, 'custom.json' without --preset, in the user's "
                             "turn-map folder $FLAGELLUM_TURN_MAPS or ~/.local/share/flagellum/turn_maps, where "
                             "--controller rule and ppo look for it first)")
    parser.add_argument("--omega-l", metavar="RPM", default="10", help="low (cruise) motor speed, rpm (default 10)")
    parser.add_argument("--omega-h", metavar="RPM", default=None,
                        help="burst motor speed, rpm (default 150: turns of 0-140 deg in 1-3.75 s; 60 is the "
                             "paper's protocol, slower turns with more drift; see agents/turn_map.py)")
    parser.add_argument("--t-c", metavar="S", nargs="+",
                        help="burst lengths, s (default 1-10, in 0.125 s steps from 3 to 4)")
    parser.add_argument("--phases", metavar="DEG", nargs="+",
                        help="hover before the burst, degrees of one flagellum rotation (default 0 90 180 270)")
    parser.add_argument("--workers", metavar="N", help="local worker processes (default: one per core)")
    parser.add_argument("--scheduler", metavar="ADDR", help=SCHEDULER_HELP)
    parser.add_argument("--resume", action="store_true", help="keep the turns already measured for FILE")
    parser.add_argument("--no-progress", action="store_true", help="do not show the progress bar")


def run(args: argparse.Namespace) -> int:
    from agents.assets import user_turn_map_dir
    from agents.follow_plots import save, turn_map_figure
    from agents.turn_calibration import TurnsNotMeasured, calibrate_turns
    from agents.turn_map import DEFAULT_PHASES_DEG, DEFAULT_T_C_S, PLANNER_OMEGA_H_RPM
    from batch.store import SweepError

    params, numerics = build_config(parse_overrides(args.set), args.preset)
    out = args.out or user_turn_map_dir() / f"{args.preset or 'custom'}.json"
    if out.is_dir():
        raise UsageError(f"--out {str(out)!r} is a folder; allowed: a turn-map file to write (e.g. "
                         f"{str(out / ((args.preset or 'custom') + '.json'))!r})")
    wl = parse_number("--omega-l", args.omega_l, "a speed > 0 rpm", positive=True)
    wh = (PLANNER_OMEGA_H_RPM if args.omega_h is None
          else parse_number("--omega-h", args.omega_h, "a speed > --omega-l rpm", positive=True))
    tcs = ([parse_number("--t-c", v, "burst lengths in (0, 600] s", positive=True) for v in args.t_c]
           if args.t_c else list(DEFAULT_T_C_S))
    phases = ([parse_number("--phases", v, "angles in [0, 360) deg") for v in args.phases]
              if args.phases else list(DEFAULT_PHASES_DEG))
    workers, scheduler = parse_workers(args)
    ensure_dir("--out", out.parent)
    try:
        tmap = calibrate_turns(params, numerics, out, preset=args.preset, omega_l_rpm=wl, omega_h_rpm=wh,
                               t_c_values=tcs, phases_deg=phases, workers=workers, resume=args.resume,
                               progress=not args.no_progress, scheduler=scheduler)
    except (ValueError, SweepError, TurnsNotMeasured) as exc:
        raise UsageError(str(exc)) from None
    fig = save(turn_map_figure(tmap, f"turn map, {args.preset or 'custom'} preset, ω_l = {wl:g} rpm, "
                                     f"ω_h = {wh:g} rpm"), out.with_suffix(".png"))
    tc, th, spread = tmap.theta_curve()
    print(f"turn map: {out} (plot {fig})")
    print(f"{'t_c (s)':>8} {'theta (deg)':>12} {'spread':>7} {'psi (deg)':>10}")
    _, psi, _ = tmap.psi_curve()
    for row in zip(tc, th, spread, psi, strict=True):
        print(f"{row[0]:8.3g} {row[1]:12.1f} {row[2]:7.1f} {row[3]:10.1f}")
    print(f"max theta {tmap.max_theta_deg:.1f} deg; wobble period {tmap.period_s:.2f} s; "
          f"median relaxation {tmap.relax_s:.1f} s")
    return 0
