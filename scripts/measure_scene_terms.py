"""What each force term costs and changes, scene by scene (issue 48, item 5): the default preset with a term left out
or simplified, against the full model, in the scenes the package flies.

    python scripts/measure_scene_terms.py [--out docs/scene_terms.json] [--t-c 3.5 8.0] [--workers 2]

Variants (``physics.presets.configure`` overrides of the default preset): ``full``; ``no contact``
(``contact=false``: the rod may pass through itself and the head); ``Stokes head`` (``head_model=stokes``: the head a
sphere with Stokes drag, no flow coupling with the flagellum). Scenes, each from the same settled cruise (26 s at
10 rpm): cruise (12 s at 10 rpm: swim per motor turn); a burst of t_c at 150 rpm from the turn map's protocol
(``agents.turn_measurement.measure_turn``, phase 0: θ, φ, L'/L at its end, burst and relaxation CPU s), once for each
``--t-c`` (3.5 s: the planners' longest bursts; 8 s: deep post-buckling, where a random policy lives). The same
bursts are flown again in 0.1 s steps to record the smallest rod-rod and head gaps (centre-line distance minus the
contact distance; negative: the bodies overlap), which says where contact can act at all.

Writes the JSON and prints a table; each variant and scene runs in its own process (``--workers``).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

VARIANTS = {"full": {}, "no contact": {"contact": "false"}, "Stokes head": {"head_model": "stokes"}}
SETTLE_S, CRUISE_S = 26.0, 12.0


def settled(overrides: dict):
    from physics.params import RPM_TO_RAD_S
    from physics.presets import DEFAULT_PRESET, configure
    from physics.simulator import Simulator

    p, n = configure(DEFAULT_PRESET, overrides)
    sim = Simulator(p, n)
    sim.set_motor_speed(10.0 * RPM_TO_RAD_S)
    for _ in range(round(SETTLE_S / n.dt)):
        sim.step()
    return sim, n.dt


def cruise(variant: str) -> dict:
    import numpy as np

    sim, dt = settled(VARIANTS[variant])
    x0, c0 = sim.head_position.copy(), time.process_time()
    for _ in range(round(CRUISE_S / dt)):
        sim.step()
    cpu = time.process_time() - c0
    turns = 10.0 / 60.0 * CRUISE_S
    return {"variant": variant, "scene": "cruise 10 rpm", "swim_per_turn_m": float(np.linalg.norm(sim.head_position - x0)
                                                                                  / turns),
            "cpu_s": cpu, "cpu_per_sim_s": cpu / CRUISE_S}


def burst(variant: str, t_c: float) -> dict:
    from agents.turn_measurement import measure_turn
    from physics.params import RPM_TO_RAD_S

    sim, _ = settled(VARIANTS[variant])
    turn = measure_turn(sim, 10.0, 150.0, t_c, 0.0)
    sim, dt = settled(VARIANTS[variant])
    sim.set_motor_speed(150.0 * RPM_TO_RAD_S)
    rod, head = [], []
    for _ in range(round(t_c / dt)):
        sim.step()
        g = sim.min_gaps()
        rod.append(g[0])
        head.append(g[1])
    return {"variant": variant, "scene": f"burst t_c {t_c:g} s", "t_c": t_c, "theta_deg": turn.theta_deg,
            "phi_deg": turn.phi_deg, "lratio_end": turn.burst_end_ratio, "burst_cpu_s": turn.burst_cpu_s,
            "relax_cpu_s": turn.relax_cpu_s, "cpu_per_sim_s": turn.burst_cpu_s / t_c,
            "min_rod_gap_m": min(rod), "min_head_gap_m": min(head),
            "first_rod_contact_s": next((dt * (k + 1) for k, g in enumerate(rod) if g < 0.0), None)}


def run(task: tuple) -> dict:
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    return cruise(task[0]) if task[1] is None else burst(task[0], task[1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/scene_terms.json"))
    ap.add_argument("--t-c", type=float, nargs="+", default=[3.5, 8.0], help="burst lengths, s")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    for t in args.t_c:
        if not 0.0 < t <= 20.0:
            ap.error(f"--t-c {t} must be in (0, 20] s")
    tasks = [(v, None) for v in VARIANTS] + [(v, t) for t in args.t_c for v in VARIANTS]
    load0 = os.getloadavg()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        rows = list(pool.map(run, tasks))
    full = {r["scene"]: r for r in rows if r["variant"] == "full"}
    print(f"{'scene':16s} {'variant':12s} {'CPU/sim s':>9s} {'x full':>7s}  result")
    for r in rows:
        f = full[r["scene"]]
        res = (f"swim/turn {1e3 * r['swim_per_turn_m']:.4f} mm" if "swim_per_turn_m" in r else
               f"theta {r['theta_deg']:6.1f} phi {r['phi_deg']:6.1f} L'/L {r['lratio_end']:.3f} "
               f"gaps rod {1e3 * r['min_rod_gap_m']:6.2f} head {1e3 * r['min_head_gap_m']:6.2f} mm")
        print(f"{r['scene']:16s} {r['variant']:12s} {r['cpu_per_sim_s']:9.3f} {r['cpu_per_sim_s'] / f['cpu_per_sim_s']:7.2f}"
              f"  {res}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"rows": rows, "variants": VARIANTS, "load_before": list(load0),
                                    "load_after": list(os.getloadavg())}, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
