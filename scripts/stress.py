"""Stability at the extremes: run the corners of the parameter space and classify every run.

    python scripts/stress.py [--workers N] [--duration 2.0] [--out out/stress]

Each run starts from rest at constant motor speed for ``--duration`` simulated seconds (or
``--max-steps`` steps, whichever is shorter) and must end in one of two ways: a finite, bounded
state ("ok": no NaN, every edge within [0.5, 2] x its rest length) or a ``SimulationError``
with a clear message ("error"). Anything else ("crash": another exception, or a NaN/unbounded
state without an error) is a bug. Step-halving on Newton failure is on (``max_substeps``).
Results are appended to out/stress/results.jsonl as they finish (resumable) and summarised in
docs/stability.md.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

BASE = {"n_nodes": 60, "dt": 5e-3}
CORNERS: list[tuple[str, dict]] = [
    ("reference 10 rpm", {}),
    ("omega 150 rpm", {"omega_rpm": 150}),
    ("omega 300 rpm", {"omega_rpm": 300}),
    ("h 0.1 ms", {"dt": 1e-4}),
    ("h 20 ms", {"dt": 0.02}),
    ("h 50 ms", {"dt": 0.05}),
    ("h 50 ms, 300 rpm", {"dt": 0.05, "omega_rpm": 300}),
    ("N 8 (minimum)", {"n_nodes": 8}),
    ("N 15", {"n_nodes": 15}),
    ("N 400", {"n_nodes": 400}),
    ("b 0 (no head)", {"head_radius": 0.0}),
    ("b 3 cm", {"head_radius": 0.03}),
    ("b 3 cm, 300 rpm", {"head_radius": 0.03, "omega_rpm": 300}),
    ("E / 100", {"youngs_modulus": 1e5, "shear_modulus": 1e5 / 3}),
    ("E x 100", {"youngs_modulus": 1e9, "shear_modulus": 1e9 / 3}),
    ("mu / 100", {"viscosity": 0.027}),
    ("mu x 100", {"viscosity": 270.0}),
    ("E / 100, 300 rpm", {"youngs_modulus": 1e5, "shear_modulus": 1e5 / 3, "omega_rpm": 300}),
    ("mu / 100, h 50 ms", {"viscosity": 0.027, "dt": 0.05}),
    ("RFT, h 50 ms, 300 rpm", {"hydro_model": "rft", "dt": 0.05, "omega_rpm": 300}),
    ("RFT, N 400, h 0.1 ms", {"hydro_model": "rft", "n_nodes": 400, "dt": 1e-4}),
    ("torque-free head, 300 rpm", {"head_rotation": "torque_free", "omega_rpm": 300}),
]


def run_corner(name: str, changes: dict, duration: float, max_steps: int) -> dict:
    import math

    import numpy as np

    from physics.errors import SimulationError
    from physics.model.geometry import nodes_of
    from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams, apply_overrides
    from physics.simulator import Simulator

    ch = {**BASE, **changes}
    rpm = float(ch.pop("omega_rpm", 10.0))
    rec = {"corner": name, "changes": changes, "omega_rpm": rpm}
    t0 = time.perf_counter()
    try:
        p, n = apply_overrides(SwimmerParams(), NumericsConfig(), {k: str(v) for k, v in ch.items()})
        sim = Simulator(p, n)
        sim.set_motor_speed(rpm * RPM_TO_RAD_S)
        steps = min(int(round(duration / n.dt)), max_steps)
        for _ in range(steps):
            sim.step()
        lengths = np.linalg.norm(np.diff(nodes_of(sim.q), axis=0), axis=1) / sim.rest.l_bar
        finite = bool(np.all(np.isfinite(sim.q)))
        bounded = finite and 0.5 <= lengths.min() and lengths.max() <= 2.0
        rec.update(outcome="ok" if bounded else "crash", sim_time_s=sim.time, steps=steps,
                   halvings=sim.stats.halvings, edge_ratio=[float(lengths.min()), float(lengths.max())],
                   end_to_end=sim.end_to_end_ratio(), newton_per_step=sim.stats.newton_iterations / max(steps, 1),
                   min_gaps_mm=[1e3 * g for g in sim.min_gaps()],
                   message=None if bounded else "state not finite/bounded without an error")
    except SimulationError as exc:
        rec.update(outcome="error", message=str(exc), quantity=exc.quantity)
    except Exception as exc:  # a bug: report it
        rec.update(outcome="crash", message=f"{type(exc).__name__}: {exc}")
    rec["wall_s"] = time.perf_counter() - t0
    _ = math  # noqa
    return rec


def _init() -> None:
    os.environ["OPENBLAS_NUM_THREADS"] = "1"


def write_md(recs: list[dict], path: Path, command: str) -> None:
    from physics.params import SwimmerParams

    head_rotation = BASE.get("head_rotation", SwimmerParams().head_rotation)
    lines = ["# Stability at the extremes", "",
             f"Produced by `{command.strip()}`. Base: N = {BASE['n_nodes']}, "
             f"h = {BASE['dt'] * 1e3:g} ms, b = 1.2 cm, LSBT + Higdon head, `head_rotation={head_rotation}`, "
             "contact on, 10 rpm, from rest; "
             "each run a few simulated seconds. Outcomes: ok (finite, every edge within 0.5-2x its rest length), "
             "error (a SimulationError with its message), crash (anything else: a bug).", "",
             "Smallest gaps at the end of the run (mm): rod-rod = centre-line distance of non-adjacent edges - 2 r0, "
             "head = edge to head centre - b - r0 (negative = overlap; the contact margin is 0.25 r0).", "",
             "| corner | outcome | sim time (s) | halvings | Newton it/step | L'/L | gaps rod-rod / head (mm) | wall (s) | message |",
             "|---|---|---|---|---|---|---|---|---|"]
    order = {name: i for i, (name, _) in enumerate(CORNERS)}
    for r in sorted(recs, key=lambda r: order.get(r["corner"], 99)):
        lines.append(f"| {r['corner']} | {r['outcome']} | {r.get('sim_time_s', 0):.3g} | {r.get('halvings', '—')} | "
                     f"{r.get('newton_per_step', float('nan')):.2f} | {r.get('end_to_end', float('nan')):.3f} | "
                     + (" / ".join(f"{g:.2f}" for g in r["min_gaps_mm"]) if r.get("min_gaps_mm") else "—")
                     + f" | {r['wall_s']:.1f} | {(r.get('message') or '').replace('|', '/')[:160]} |")
    path.parent.mkdir(parents=True, exist_ok=True)
    # the page's "Every tier" section (scripts/stress_tiers.py) is kept as it is
    text = path.read_text() if path.exists() else ""
    marker = "<!-- every-tier -->"
    tiers = "\n" + text[text.index(marker):] if marker in text else ""
    path.write_text("\n".join(lines) + "\n" + tiers)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--duration", type=float, default=2.0, help="simulated seconds per corner (default 2)")
    ap.add_argument("--max-steps", type=int, default=2000, help="cap on steps per corner (default 2000)")
    ap.add_argument("--out", default="out/stress")
    ap.add_argument("--md", default="docs/stability.md")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res = out / "results.jsonl"
    done = {}
    if res.exists():
        for line in res.read_text().splitlines():
            try:
                r = json.loads(line)
                done[r["corner"]] = r
            except json.JSONDecodeError:
                pass
    todo = [(n, c) for n, c in CORNERS if n not in done]
    from tqdm import tqdm

    with ProcessPoolExecutor(max_workers=args.workers, initializer=_init) as pool, open(res, "a") as fh:
        futs = [pool.submit(run_corner, n, c, args.duration, args.max_steps) for n, c in todo]
        for f in tqdm(as_completed(futs), total=len(futs), desc="stress", unit="run"):
            r = f.result()
            fh.write(json.dumps(r) + "\n")
            fh.flush()
            done[r["corner"]] = r
            print(f"{r['corner']:28s} {r['outcome']:6s} {(r.get('message') or '')[:90]}", flush=True)
    write_md([done[n] for n, _ in CORNERS if n in done], Path(args.md), "python scripts/stress.py " + " ".join(argv or []))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
