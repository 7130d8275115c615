"""The turns each action design reaches per decision (issue 49, item 1), read from the default preset's turn map.

A turn is a burst at omega_h of t_c seconds (Huang & Jawed 2020, Sec. 3): theta(t_c) rises steeply from ~2 s to
its peak (the map's rising branch) and then falls and scatters (deep post-buckling, where the swimmer tumbles on).
Its direction is the phase node's azimuth at the burst's start plus psi(t_c) (Fig. 5e), so an action design also
sets how finely a turn's direction can be chosen: the phase node turns once per wobble period at omega_l.

Designs compared (rows):

- ``FlagellumSteer-v0`` holding omega for ``control_dt`` (2 s by default; 0.5 s and 0.1 s, the planners' step,
  as arguments): a burst is a run of consecutive steps at omega_h, so t_c is a multiple of control_dt, and the
  phase at which it starts is a multiple of control_dt too; t_c past the peak is reachable (one more step at
  omega_h);
- ``FlagellumBurst-*`` (``agents.burst_design``): one action sets t_c (0.1 s steps, up to ``BurstLimits.t_c_max_s``)
  and the phase, which the env waits for to the control step (0.1 s).

Per design: the turn angles (phase-mean theta of the map, linear between its burst lengths) of every burst length
on the rising branch, the largest gap between neighbouring reachable turns from 0 to the largest, the azimuth step
of the turn's direction (360 deg x step / period), the decisions a 90 deg turn takes (its burst's steps and, on
average, half a period of hover before it), and whether a burst can go past the peak (into post-buckling). The
map holds bursts at omega_h only; FlagellumSteer-v0's continuous omega also reaches speeds between omega_l and
omega_h, which buckle later or not at all and are not counted here. Prints a table; ``--json`` writes it.

Usage::

    python scripts/action_resolution.py [--json docs/action_resolution.json]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from agents.assets import default_turn_map
from agents.burst_design import BurstLimits
from agents.turn_map import TurnMap
from physics.presets import DEFAULT_PRESET

PLANNER_STEP_S = 0.1


def reachable_turns(tmap: TurnMap, step_s: float, t_max: float | None = None) -> dict:
    """The turns of bursts of whole ``step_s`` steps on the map's rising branch (module docstring)."""
    t_rise, th_rise = tmap.rising_branch()
    tcs, theta, _ = tmap.theta_curve()
    t_peak = float(t_rise[-1])
    n = np.arange(1, int(math.floor((t_peak if t_max is None else min(t_max, t_peak)) / step_s + 1e-9)) + 1)
    t = n * step_s
    th = np.interp(t, np.concatenate([[0.0], tcs]), np.concatenate([[0.0], theta]))
    turns = np.unique(np.round(np.concatenate([[0.0], th]), 6))
    gaps = np.diff(turns)
    past_peak = t_max is None or t_max > t_peak + 1e-9
    return {"step_s": step_s, "bursts": [round(float(x), 3) for x in t], "turns_deg": [round(float(x), 1) for x in th],
            "largest_turn_deg": float(turns[-1]), "largest_gap_deg": float(gaps.max()) if gaps.size else 0.0,
            "turns_over_10_deg": int((turns > 10.0).sum()), "past_peak": bool(past_peak), "t_peak_s": t_peak,
            "theta_peak_deg": float(th_rise[-1])}


def designs(tmap: TurnMap) -> list[dict]:
    """One row per action design (module docstring)."""
    period = tmap.period_s
    rows = []
    for dt in (2.0, 0.5, PLANNER_STEP_S):
        r = reachable_turns(tmap, dt)
        # a 90 deg turn: its burst steps plus, on average, half a period of hover to its phase
        r.update(design=f"FlagellumSteer-v0, omega held {dt:g} s", azimuth_step_deg=360.0 * dt / period,
                 decisions_per_turn=math.ceil(tmap.t_c_for(90.0) / dt) + round(0.5 * period / dt))
        rows.append(r)
    lim = BurstLimits()
    r = reachable_turns(tmap, PLANNER_STEP_S, lim.t_c_max_s)
    r.update(design="FlagellumBurst-*, one burst command", azimuth_step_deg=360.0 * PLANNER_STEP_S / period,
             decisions_per_turn=1, past_peak=lim.t_c_max_s > r["t_peak_s"])
    rows.append(r)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, default=None, help="write the rows to this JSON file")
    args = parser.parse_args(argv)
    tmap = TurnMap.load(default_turn_map(DEFAULT_PRESET))
    rows = designs(tmap)
    print(f"turn map: {DEFAULT_PRESET} at {tmap.omega_h_rpm:g} rpm; rising branch to {rows[0]['theta_peak_deg']:.0f} "
          f"deg at t_c = {rows[0]['t_peak_s']:g} s; wobble period {tmap.period_s:.2f} s")
    print("| design | turns > 10 deg | largest turn (deg) | largest gap (deg) | azimuth step (deg) | decisions per turn "
          "| past the peak |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['design']} | {r['turns_over_10_deg']} | {r['largest_turn_deg']:.0f} | {r['largest_gap_deg']:.0f} "
              f"| {r['azimuth_step_deg']:.1f} | {r['decisions_per_turn']} | {'yes' if r['past_peak'] else 'no'} |")
    if args.json is not None:
        args.json.write_text(json.dumps({"preset": DEFAULT_PRESET, "rows": rows}, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
