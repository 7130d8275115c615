"""How each randomised parameter moves the burst's turn: the buckling-time shift per parameter for the surrogate.

The turn map is the nominal swimmer's. For a swimmer that differs, the turn of a burst of t_c is to first order the
map's turn at t_c + s (agents/online_turn_map.py: a parameter error moves when the flagellum buckles). This script
measures s for each parameter ``FlagellumSteer-v0`` randomises (E with G, mu, the head radius b, the helix pitch and
radius) scaled by 1 -+ ``--fraction``, one at a time: a turn of the default preset (``measure_turn``, burst of
``--t-c`` s at phase 0 from the swimmer's own steady start) read back on the map's rising branch,
s = t_c_map(theta) - t_c. The central difference gives ds / d ln(factor) per parameter; divided by t_c it is the
exponent e of a power law t_map = t_c prod(factor^e) (``burst_time_exponents`` in the surrogate calibration, which
``agents.surrogate_swimmer`` applies).

Each turn is appended to ``--cache`` (JSONL) and not run again (resumable). Cost: a steady start per swimmer (up to a
minute or so of CPU when not cached) and ~2 CPU s per turn.

Usage::

    python scripts/calibrate_surrogate_shift.py [--fraction 0.05] [--t-c 3.3] [--write]

Measured (the shipped calibration): ds/dln f = E -4.09, mu +4.11, b +0.95, pitch -7.06, helix radius +7.11 s at
t_c = 3.3 s (E and mu as tau = mu L^4 / EI: the burst-speed law of agents.surrogate_swimmer gives +-4.32).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

from agents.assets import default_turn_map
from agents.surrogate_calibration import calibration_file
from agents.turn_calibration import SETTLE_TURNS
from agents.turn_map import TurnMap
from agents.turn_measurement import measure_turn
from flagellum_env.steady_start import get_steady_start
from physics.params import RPM_TO_RAD_S
from physics.presets import DEFAULT_PRESET

#: factor name -> the SwimmerParams fields it scales (as ``flagellum_env.config.draw_randomization``)
FACTORS = {"youngs_modulus": ("youngs_modulus", "shear_modulus"), "viscosity": ("viscosity",),
           "head_radius": ("head_radius",), "pitch": ("pitch",), "helix_radius": ("helix_radius",)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fraction", type=float, default=0.05)
    ap.add_argument("--t-c", type=float, default=3.3)
    ap.add_argument("--cache", type=Path, default=Path("results/bench/surrogate_shift.jsonl"))
    ap.add_argument("--write", action="store_true", help="write the fit into the surrogate calibration file")
    args = ap.parse_args(argv)
    tmap = TurnMap.load(default_turn_map(DEFAULT_PRESET))
    done = {}
    if args.cache.is_file():
        for line in args.cache.read_text().splitlines():
            rec = json.loads(line)
            done[(rec["factor"], rec["scale"], rec["t_c"])] = rec
    for name, fields in FACTORS.items():
        for scale in (1.0 - args.fraction, 1.0 + args.fraction):
            key = (name, round(scale, 6), args.t_c)
            if key in done:
                continue
            c0 = time.process_time()
            params = tmap.params.replace(**{f: getattr(tmap.params, f) * scale for f in fields})
            start = get_steady_start(params, tmap.numerics, tmap.omega_l_rpm * RPM_TO_RAD_S,
                                     SETTLE_TURNS * 60.0 / tmap.omega_l_rpm)
            res = measure_turn(start.new_simulator(), tmap.omega_l_rpm, tmap.omega_h_rpm, args.t_c, 0.0,
                               phase_node=tmap.phase_node)
            rec = {"factor": name, "scale": key[1], "t_c": args.t_c, "theta_deg": res.theta_deg,
                   "psi_deg": res.psi_deg, "shift_s": tmap.t_c_for(res.theta_deg) - args.t_c,
                   "on_branch": res.theta_deg < tmap.max_theta_deg, "cpu_s": round(time.process_time() - c0, 1)}
            args.cache.parent.mkdir(parents=True, exist_ok=True)
            with args.cache.open("a") as f:
                f.write(json.dumps(rec) + "\n")
            done[key] = rec
            print(f"{name} x {scale:g}: theta {res.theta_deg:.1f} deg, shift {rec['shift_s']:+.3f} s "
                  f"({rec['cpu_s']} CPU s)", flush=True)
    lo, hi = round(1.0 - args.fraction, 6), round(1.0 + args.fraction, 6)
    nominal = tmap.t_c_for(_map_theta(tmap, args.t_c)) - args.t_c
    slopes = {}
    for name in FACTORS:
        a, b = done[(name, lo, args.t_c)], done[(name, hi, args.t_c)]
        slopes[name] = (b["shift_s"] - a["shift_s"]) / (math.log(hi) - math.log(lo))
        print(f"{name}: ds/dln(f) = {slopes[name]:+.2f} s (shift {a['shift_s']:+.3f} at x{lo:g}, "
              f"{b['shift_s']:+.3f} at x{hi:g}; on the rising branch: {a['on_branch'] and b['on_branch']})")
    print(f"nominal read-back shift {nominal:+.4f} s (the map's own interpolation)")
    if args.write:
        path = calibration_file(DEFAULT_PRESET)
        doc = json.loads(path.read_text(encoding="utf-8"))
        doc["burst_time_exponents"] = {k: v / args.t_c for k, v in slopes.items()}
        doc["burst_time_exponents_meta"] = {"script": "scripts/calibrate_surrogate_shift.py",
                                            "fraction": args.fraction, "t_c": args.t_c, "phase_deg": 0.0,
                                            "shift_s_per_log_factor": slopes}
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        os.replace(tmp, path)
        print(f"wrote burst_time_exponents (ds/dln f / t_c) into {path}")
    return 0


def _map_theta(tmap: TurnMap, t_c: float) -> float:
    """The map's mean theta at t_c on the rising branch, deg."""
    import numpy as np
    t, y = tmap.rising_branch()
    return float(np.interp(t_c, t, y))


if __name__ == "__main__":
    raise SystemExit(main())
