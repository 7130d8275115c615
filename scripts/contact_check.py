"""Does the buckled swimmer stay physical, and what does contact cost?

    python scripts/contact_check.py [--runs balanced:90:100 paper:90:100 ...] [--workers 2]

A run is PRESET:RPM:SECONDS[:off]; besides today's presets, ``balanced`` is a retired preset
(``paper`` at h = 20 ms, Newton tolerance 1e-5), kept here so the recorded runs can be repeated.
The runs named ``fast:150:25`` in docs/contact_check.json were recorded at the configuration later named
``coarse`` (N = 45, 10 ms implicit Euler; not today's ``fast``), since retired: the 150 rpm case now runs at
``faithful``.
                                    [--out docs/contact_check.json]

Each run (PRESET:RPM:SECONDS[:off]) starts from rest at a constant motor speed, with contact on
(or off with the ``:off`` suffix, contact and the near-field kernel both off) and records after every
``--check-every`` steps the smallest rod-rod gap (centre-line distance of non-adjacent edges minus
2 r0) and head gap (distance of an edge to the head centre minus b - r0), the number of flagellum
nodes inside the head sphere, the CPU time (``time.process_time``) and the real-time factor.
A run that ends in a SimulationError records the error and when it happened. Results are appended
to ``<out>.jsonl`` as they finish (re-running skips the runs already there) and collected in
``<out>``; a table is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

DEFAULT_RUNS = ["balanced:10:20", "balanced:10:20:off", "balanced:90:100", "balanced:90:100:off",
                "faithful:150:25", "faithful:150:25:off", "paper:10:5", "paper:10:5:off", "paper:90:100"]
#: retired presets these runs still use: name -> (today's preset, numerics changed on top of it)
RETIRED_PRESETS = {"balanced": ("paper", {"dt": 0.02, "newton_tol": 1e-5})}


def run_one(spec: str, check_every: int) -> dict:
    import math

    import numpy as np

    from physics.errors import SimulationError
    from physics.params import RPM_TO_RAD_S
    from physics.presets import apply_preset
    from physics.simulator import Simulator

    parts = spec.split(":")
    preset, rpm, duration = parts[0], float(parts[1]), float(parts[2])
    contact = not (len(parts) > 3 and parts[3] == "off")
    base, changes = RETIRED_PRESETS.get(preset, (preset, {}))
    p, n = apply_preset(base)
    n = n.replace(**changes)
    if not contact:
        n = n.replace(contact=False, near_field_radius=0.0)
    sim = Simulator(p, n)
    sim.set_motor_speed(rpm * RPM_TO_RAD_S)
    steps = int(round(duration / n.dt))
    g_rr, g_h, inside, first_inside = math.inf, math.inf, 0, None
    error = None
    cpu0, wall0 = time.process_time(), time.perf_counter()
    try:
        for k in range(steps):
            sim.step()
            if (k + 1) % check_every == 0 or k + 1 == steps:
                a, b = sim.min_gaps()
                g_rr, g_h = min(g_rr, a), min(g_h, b)
                if p.has_head:
                    r = np.linalg.norm(sim.nodes[2:] - sim.nodes[0], axis=1)
                    now = int((r < p.head_radius).sum())
                    if now and first_inside is None:
                        first_inside = sim.time
                    inside = max(inside, now)
    except SimulationError as exc:
        error = str(exc)
    cpu = time.process_time() - cpu0
    return {"run": spec, "preset": preset, "omega_rpm": rpm, "duration_s": duration, "contact": contact,
            "simulated_s": sim.time, "cpu_s": cpu, "wall_s": time.perf_counter() - wall0,
            "real_time_factor_cpu": sim.time / cpu if cpu > 0 else None,
            "min_rod_rod_gap_mm": g_rr * 1e3, "min_head_gap_mm": g_h * 1e3,
            "max_nodes_inside_head": inside, "first_inside_head_s": first_inside,
            "end_to_end_ratio": sim.end_to_end_ratio(), "error": error,
            "jacobian_factorisations": sim.stats.jacobian_factorisations, "halvings": sim.stats.halvings,
            "contact_margin_mm": n.contact_margin * p.rod_radius * 1e3, "check_every_steps": check_every}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", default=DEFAULT_RUNS, help="PRESET:RPM:SECONDS[:off] (default: %(default)s)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--check-every", type=int, default=10, help="steps between gap checks (default 10)")
    ap.add_argument("--out", default="docs/contact_check.json")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error(f"--workers {args.workers} must be >= 1")
    out = Path(args.out)
    jl = out.with_suffix(".jsonl")
    done = {}
    if jl.exists():
        for line in jl.read_text().splitlines():
            row = json.loads(line)
            done[row["run"]] = row
    todo = [r for r in args.runs if r not in done]
    stamp = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "machine": platform.platform(),
             "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                      text=True).stdout.strip()}
    with ProcessPoolExecutor(args.workers) as pool:
        futs = {pool.submit(run_one, r, args.check_every): r for r in todo}
        for f in as_completed(futs):
            row = {**f.result(), **stamp, "load_avg": os.getloadavg()}  # the load as the run ends
            with jl.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
            done[row["run"]] = row
            print(f"done {row['run']}", flush=True)
    rows = [done[r] for r in args.runs if r in done]
    out.write_text(json.dumps(rows, indent=1))
    print(f"{'run':24s} {'t sim':>6s} {'RTF cpu':>8s} {'rr gap mm':>9s} {'head gap':>9s} {'inside':>6s} {'L/L':>6s}  error")
    for r in rows:
        print(f"{r['run']:24s} {r['simulated_s']:6.1f} {r['real_time_factor_cpu']:8.2f} {r['min_rod_rod_gap_mm']:9.3f} "
              f"{r['min_head_gap_mm']:9.3f} {r['max_nodes_inside_head']:6d} {r['end_to_end_ratio']:6.3f}  "
              f"{(r['error'] or '')[:70]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
