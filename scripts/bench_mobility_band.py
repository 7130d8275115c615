"""Cost of the buckling burst against the Newton-Krylov preconditioner's mobility band.

``physics.solvers.newton_krylov.MOBILITY_BAND_NODES``: the preconditioner keeps the LSBT mobility's entries between
nodes at most this many apart. Protocol: ``faithful`` swims 26 s at 10 rpm (settled; not timed), then, from a copy of
that state for each band, 7.5 s at 150 rpm (the burst of ``scripts/bench_phases.py``). Per band: CPU seconds
(``time.process_time``, median of the repeats after an untimed warm-up), real-time factor, steps, GMRES iterations
per Newton-Krylov step, residuals per step, and the largest node-position difference of the end state from the
first band's (m).

    python scripts/bench_mobility_band.py --bands 3 2 5 8 --json out/bench/mobility_band.json

Prints a table and writes JSON. Ratios are from one run; the machine's load (1-min average) is recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import platform
import statistics
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import physics.solvers.newton_krylov as newton_krylov
from physics import Simulator, advance, configure
from physics.model.geometry import nodes_of
from physics.params import RPM_TO_RAD_S


def burst(blob: bytes, band: int) -> tuple[float, Simulator, dict[str, float]]:
    """(CPU s, the simulator after the burst, per-step counts) from the pickled settled state ``blob``."""
    newton_krylov.MOBILITY_BAND_NODES = band
    sim = pickle.loads(blob)
    sim.set_motor_speed(150.0 * RPM_TO_RAD_S)
    s0 = {k: getattr(sim.stats, k) for k in ("substeps", "krylov_steps", "krylov_iterations", "newton_iterations")}
    c0 = time.process_time()
    advance(sim, 7.5)
    cpu = time.process_time() - c0
    d = {k: getattr(sim.stats, k) - v for k, v in s0.items()}
    return cpu, sim, {"steps": d["substeps"], "gmres_per_krylov_step": d["krylov_iterations"] / max(d["krylov_steps"], 1),
                      "residuals_per_step": d["newton_iterations"] / max(d["substeps"], 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bands", type=int, nargs="+", default=[3, 2, 5, 8], help="band widths in nodes (>= 1)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    bad = [b for b in a.bands if b < 1]
    if bad or a.repeats < 1:
        ap.error(f"--bands {bad or a.bands} / --repeats {a.repeats}: bands must be >= 1 node, repeats >= 1")
    default = newton_krylov.MOBILITY_BAND_NODES
    rows = []
    with threadpool_limits(1):
        sim = Simulator(*configure("faithful", {}))
        sim.set_motor_speed(10.0 * RPM_TO_RAD_S)
        advance(sim, 26.0)
        blob = pickle.dumps(sim)
        burst(blob, a.bands[0])  # warm-up: whatever a copied state compiles
        ref = None
        for band in a.bands:
            runs = [burst(blob, band) for _ in range(a.repeats)]
            cpu = statistics.median(r[0] for r in runs)
            end = runs[-1][1]
            ref = end.q if ref is None else ref
            row = {"band_nodes": band, "cpu_s": cpu, "rtf_cpu": 7.5 / cpu, **runs[-1][2],
                   "max_node_difference_m": float(np.linalg.norm(end.nodes - nodes_of(ref), axis=1).max()),
                   "lratio_end": end.end_to_end_ratio()}
            rows.append(row)
    newton_krylov.MOBILITY_BAND_NODES = default
    print(f"{'band':>4s} {'cpu s':>7s} {'RTF':>6s} {'steps':>6s} {'GMRES/step':>10s} {'residuals/step':>14s} "
          f"{'max dx m':>9s} {'L/L':>6s}")
    for r in rows:
        print(f"{r['band_nodes']:4d} {r['cpu_s']:7.3f} {r['rtf_cpu']:6.2f} {r['steps']:6d} "
              f"{r['gmres_per_krylov_step']:10.2f} {r['residuals_per_step']:14.2f} {r['max_node_difference_m']:9.1e} "
              f"{r['lratio_end']:6.4f}")
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"rows": rows, "default_band_nodes": default, "repeats": a.repeats,
                                      "measured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                                      "load_1min": os.getloadavg()[0],
                                      "machine": platform.processor() or platform.machine()}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
