"""Benchmark the physics core on the paper's swimmer: wall time per step, real-time factor, and
where the time goes (elastic forces, hydrodynamics, linear solves, factorisations).

Prints a table and writes JSON. Medians over repeats; all rows measured in the same run.

    python scripts/bench_physics.py [--repeats 3] [--steps 400] [--json docs/bench_physics.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from dataclasses import asdict, dataclass

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core per simulation, as in sweeps
os.environ.setdefault("OMP_NUM_THREADS", "1")

from physics import Simulator, advance, configure  # noqa: E402
from physics.params import RPM_TO_RAD_S  # noqa: E402


@dataclass(frozen=True)
class Case:
    name: str
    omega_rpm: float
    dt: float
    warmup_s: float  # simulated time before measuring (steady swimming / buckled state)
    head_rotation: str = "torque_free"


CASES = (
    Case("paper 10 rpm, h = 1 ms", 10.0, 1e-3, 2.0),
    Case("paper 10 rpm, h = 5 ms", 10.0, 5e-3, 2.0),
    Case("paper 60 rpm, h = 1 ms", 60.0, 1e-3, 2.0),
    Case("paper 60 rpm, h = 5 ms", 60.0, 5e-3, 2.0),
    Case("paper 60 rpm buckled (fixed head), h = 5 ms", 60.0, 5e-3, 40.0, "fixed"),
)


def measure(case: Case, steps: int, repeats: int) -> dict:
    sim = Simulator(*configure(None, {"head_rotation": case.head_rotation, "dt": case.dt}))
    sim.set_motor_speed(case.omega_rpm * RPM_TO_RAD_S)
    advance(sim, case.warmup_s)
    per_step, parts = [], []
    for _ in range(repeats):
        s0 = asdict(sim.stats)
        t0 = time.perf_counter()
        advance(sim, steps=steps)
        wall = time.perf_counter() - t0
        s1 = asdict(sim.stats)
        d = {k: s1[k] - s0[k] for k in s1}
        per_step.append(wall / steps)
        parts.append({k: v / steps for k, v in d.items()})
    med = statistics.median(per_step)
    i = per_step.index(med) if med in per_step else 0
    p = parts[i]
    accounted = sum(p[k] for k in p if k.startswith("time_"))
    return {
        "case": case.name, "omega_rpm": case.omega_rpm, "dt_s": case.dt, "head_rotation": case.head_rotation,
        "warmup_s": case.warmup_s, "steps_per_repeat": steps, "repeats": repeats,
        "wall_per_step_ms": med * 1e3, "real_time_factor": case.dt / med,
        "newton_iterations_per_step": p["newton_iterations"],
        "resistance_refreshes_per_step": p["resistance_refreshes"],
        "jacobian_factorisations_per_step": p["jacobian_factorisations"],
        "split_ms_per_step": {
            "resistance refresh (LSBT + Cholesky)": p["time_resistance_refresh"] * 1e3,
            "Jacobian refresh (Hessian + dense R + LU)": p["time_jacobian_refresh"] * 1e3,
            "the rest (iterations, rotations, bookkeeping)": (med - accounted) * 1e3,
        },
        "end_to_end_ratio": sim.end_to_end_ratio(),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=400, help="steps per repeat (default 400)")
    ap.add_argument("--repeats", type=int, default=3, help="repeats; the median is reported (default 3)")
    ap.add_argument("--json", default="docs/bench_physics.json", help="where to write the JSON")
    ap.add_argument("--quick", action="store_true", help="skip the buckled case (needs 40 s of warm-up)")
    args = ap.parse_args(argv)
    cases = [c for c in CASES if not (args.quick and c.warmup_s > 10)]
    rows = []
    for c in cases:
        print(f"measuring {c.name} ...", flush=True)
        rows.append(measure(c, args.steps, args.repeats))
    head = f"{'case':48s} {'ms/step':>8s} {'RTF':>6s} {'it/st':>6s} {'hyd/st':>7s} {'jac/st':>7s}"
    print("\n" + head)
    for r in rows:
        print(f"{r['case']:48s} {r['wall_per_step_ms']:8.3f} {r['real_time_factor']:6.2f} "
              f"{r['newton_iterations_per_step']:6.2f} {r['resistance_refreshes_per_step']:7.3f} "
              f"{r['jacobian_factorisations_per_step']:7.3f}")
    print("\nsplit of the step cost (ms per step):")
    for r in rows:
        print("  " + r["case"])
        for k, v in r["split_ms_per_step"].items():
            print(f"    {k:45s} {v:8.3f}")
    out = {"machine": {"platform": platform.platform(), "processor": platform.processor(),
                       "cpu_count": os.cpu_count(), "python": platform.python_version()},
           "date": time.strftime("%Y-%m-%d %H:%M:%S"), "rows": rows}
    os.makedirs(os.path.dirname(args.json) or ".", exist_ok=True)
    with open(args.json, "w") as fh:
        json.dump(out, fh, indent=2)
    print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
