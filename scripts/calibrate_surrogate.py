"""Measure what the turn map does not hold for ``FlagellumTurn-surrogate-v0`` and write it next to the map.

The turn map (agents/turn_maps/faithful.json) gives each burst's turn and head displacement but neither the
straight-swimming speed nor the motor's energy. This script runs ``FlagellumSteer-v0`` (the default preset, the
planner's 0.1 s control step, nominal swimmer, fixed one-waypoint path far ahead) for a few simulated seconds:

- ``cruise_speed_m_s``: the steady start's speed at omega_l (``FlagellumSteerEnv.steady_speed_m_s``, what sets the
  env's time budget ``time_factor * path length / speed``);
- ``cruise_power_w``: mean motor power |T omega| over ``--cruise`` s at omega_l (``info["energy_j"]`` / duration);
- ``cruise_end_to_end_ratio``: L'/L at the end of that cruise (what the observation shows at a decision);
- ``burst_energy_j``: cumulative motor energy of a burst at omega_h after each 0.1 s of it, (t_c, E) pairs up to
  ``--burst`` s (the burst's power changes once the flagellum buckles).

Cost: a few CPU seconds (the burst at 150 rpm runs ~9x real time on ``faithful``). Usage::

    python scripts/calibrate_surrogate.py [--out agents/turn_maps/faithful_surrogate.json] [--burst 5] [--cruise 10]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from agents.assets import default_turn_map
from agents.surrogate_calibration import CALIBRATION_FORMAT, calibration_file
from agents.turn_map import TurnMap
from flagellum_env.steer_env import FlagellumSteerEnv
from physics.presets import DEFAULT_PRESET


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default=DEFAULT_PRESET)
    ap.add_argument("--out", default=None, help="output JSON (default: next to the preset's turn map)")
    ap.add_argument("--burst", type=float, default=5.0, help="burst length measured, s")
    ap.add_argument("--cruise", type=float, default=10.0, help="cruise measured, s")
    args = ap.parse_args(argv)
    tmap = TurnMap.load(default_turn_map(args.preset))
    env = FlagellumSteerEnv(path=[[1.0, 0.0, 0.0]], preset=args.preset, control_dt=0.1,
                            omega_range_rpm=(tmap.omega_l_rpm, tmap.omega_h_rpm))
    t0 = time.process_time()
    env.reset(seed=0)
    lo, hi = np.array([-1.0], np.float32), np.array([1.0], np.float32)
    e_cruise, n_cruise = 0.0, round(args.cruise / 0.1)
    for _ in range(n_cruise):
        _, _, term, trunc, info = env.step(lo)
        e_cruise += info["energy_j"]
    cruise_ratio = float(info["end_to_end_ratio"])
    burst = [(0.0, 0.0)]
    for k in range(round(args.burst / 0.1)):
        _, _, term, trunc, info = env.step(hi)
        burst.append((round(0.1 * (k + 1), 6), burst[-1][1] + info["energy_j"]))
    out = {"format": CALIBRATION_FORMAT, "version": 1, "preset": args.preset,
           "omega_l_rpm": tmap.omega_l_rpm, "omega_h_rpm": tmap.omega_h_rpm,
           "cruise_speed_m_s": float(env.steady_speed_m_s),
           "cruise_power_w": e_cruise / (n_cruise * 0.1),
           "cruise_end_to_end_ratio": cruise_ratio,
           "burst_energy_j": burst,
           "meta": {"created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                    "cpu_s": round(time.process_time() - t0, 2), "script": "scripts/calibrate_surrogate.py",
                    "cruise_s": args.cruise, "burst_s": args.burst}}
    path = Path(args.out) if args.out else calibration_file(args.preset)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, path)
    print(f"wrote {path}: speed {out['cruise_speed_m_s']:.4g} m/s, cruise power {out['cruise_power_w']:.3g} W, "
          f"burst energy {burst[-1][1]:.3g} J in {args.burst:g} s, {out['meta']['cpu_s']} CPU s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
