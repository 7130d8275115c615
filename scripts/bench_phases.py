"""Cost of the swimmer by phase: start, steady cruise, buckling burst, relaxation after it.

Protocol (one simulator, one core): 6 s at 10 rpm from rest (start), 20 s more at 10 rpm (steady:
the helix has settled), 7.5 s at 150 rpm (burst: the flagellum buckles), 20 s at 10 rpm
(relaxation). For each phase: CPU seconds (``time.process_time``), real-time factor on CPU time,
accepted steps, mean step, Newton/GMRES iterations and factorisations per step. The node positions
and twists at the end of the burst and of the relaxation are saved (``--states``) so that
configurations can be compared with a reference run (``--reference``: max node distance in r0,
max twist difference in rad, L'/L).

    python scripts/bench_phases.py --preset faithful --json out/bench/phases_faithful.json
    python scripts/bench_phases.py --preset faithful --set step_tol=1e-6 --states out/bench/ref.npz
    python scripts/bench_phases.py --preset faithful --reference out/bench/ref.npz

Prints a table and writes JSON. Ratios are from one run; the machine's load (1-min average) is recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from physics import Simulator, advance, configure
from physics.params import RPM_TO_RAD_S

PHASES = (("start", 10.0, 6.0), ("steady", 10.0, 20.0), ("burst", 150.0, 7.5), ("relax", 10.0, 20.0))


def run(preset: str, overrides: dict[str, str]) -> tuple[list[dict], dict[str, np.ndarray]]:
    params, numerics = configure(preset, overrides)
    sim = Simulator(params, numerics)
    rows, states = [], {}
    for name, rpm, duration in PHASES:
        sim.set_motor_speed(rpm * RPM_TO_RAD_S)
        s0 = asdict(sim.stats)
        c0, w0 = time.process_time(), time.perf_counter()
        advance(sim, duration)
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        d = {k: v - s0[k] for k, v in asdict(sim.stats).items()}
        n = max(d["substeps"], 1)
        rows.append({"phase": name, "rpm": rpm, "duration_s": duration, "cpu_s": cpu, "wall_s": wall,
                     "rtf_cpu": duration / cpu, "substeps": d["substeps"], "mean_h_ms": 1e3 * duration / n,
                     "ms_per_step_cpu": 1e3 * cpu / n,
                     **{k: d[k] / n for k in d if k not in ("steps", "substeps") and not k.startswith("time_")},
                     "lratio_end": sim.end_to_end_ratio()})
        states[name] = sim.q.copy()
    return rows, states


def compare(states: dict[str, np.ndarray], ref: dict[str, np.ndarray], r0: float) -> dict[str, dict]:
    out = {}
    for name in ("burst", "relax"):
        a, b = states[name], ref[name]
        dx = np.linalg.norm(a[:-3].reshape(-1, 4)[:, :3] - b[:-3].reshape(-1, 4)[:, :3], axis=1)
        dx = np.concatenate([dx, [np.linalg.norm(a[-3:] - b[-3:])]])
        dtw = np.abs(a[3::4][1:] - b[3::4][1:])  # free twists (theta^0 is the motor)
        out[name] = {"max_node_error_r0": float(dx.max() / r0), "max_twist_error_rad": float(dtw.max())}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="faithful")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--states", type=Path, default=None, help="save the end-of-phase states (npz)")
    ap.add_argument("--reference", type=Path, default=None, help="compare with states saved by --states")
    a = ap.parse_args(argv)
    overrides = dict(s.split("=", 1) for s in a.set)
    with threadpool_limits(1):
        rows, states = run(a.preset, overrides)
    print(f"{'phase':8s} {'rpm':>5s} {'cpu s':>8s} {'RTF cpu':>8s} {'steps':>6s} {'h ms':>7s} {'ms/step':>8s} "
          f"{'iters':>6s} {'refresh':>7s} {'LU':>6s} {'L/L':>6s}")
    for r in rows:
        print(f"{r['phase']:8s} {r['rpm']:5.0f} {r['cpu_s']:8.2f} {r['rtf_cpu']:8.2f} {r['substeps']:6d} "
              f"{r['mean_h_ms']:7.2f} {r['ms_per_step_cpu']:8.3f} {r['newton_iterations']:6.2f} "
              f"{r['resistance_refreshes']:7.3f} {r['jacobian_factorisations']:6.3f} {r['lratio_end']:6.4f}")
    report = {"preset": a.preset, "overrides": overrides, "phases": rows,
              "measured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
              "load_1min": os.getloadavg()[0], "machine": platform.processor() or platform.machine()}
    if a.reference:
        ref = dict(np.load(a.reference))
        report["errors"] = compare(states, ref, configure(a.preset, overrides)[0].rod_radius)
        for name, e in report["errors"].items():
            print(f"error at end of {name}: nodes {e['max_node_error_r0']:.3e} r0, twist {e['max_twist_error_rad']:.3e} rad")
    if a.states:
        a.states.parent.mkdir(parents=True, exist_ok=True)
        np.savez(a.states, **states)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
