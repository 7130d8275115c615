"""Validation against the paper (rows R1-R9, R11 of paper_targets.md) for both readings of the
head, with contact on: the physically consistent one (torque-free head, eqn 13, reciprocal head
forms; ``head_rotation=torque_free``) and the paper's (head not spinning, flagellum base at omega
in the lab frame, eqns 10-11 as printed; ``head_rotation=paper``).

    python scripts/validate_readings.py [--workers 2] [--out results/validation] [--report-only]

Every run starts from rest at a constant motor speed for 100 s (t_bar = 1.02) on the paper's grid
(N = 122, edges 2 delta). Time step: ``--dt`` (default 20 ms: the ``paper`` preset at h = 20 ms with Newton
tolerance 1e-5, which was the ``balanced`` preset until 2026-12-02; its deviations from h = 1 ms are measured
in docs/fidelity.md). omega_b is bisected on
L'/L(100 s) < 0.98 for each head size, to a 2-rpm bracket for b = 1.2 cm and a 5-rpm bracket for
the others. R9 follows the paper's protocol (steady 10 rpm, a burst of t_c at 60 rpm, back to
10 rpm) under the paper's reading. Runs are appended to ``<out>/runs.jsonl`` as they finish
(resumable; a run is never repeated); the report (docs/validation.json, docs/validation.md,
docs/figures/fig4_*.png) is rebuilt from them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

READINGS = ("torque_free", "paper")
HEADS_M = (0.0, 0.004, 0.008, 0.012)
LOW_RPM = (10.0, 30.0)  # below omega_b for every head and reading: R3-R6, R8
BUCKLED_RATIO = 0.98
DURATION_S = 100.0
R9_TC_S = (10.0, 20.0, 30.0, 40.0, 54.0)
R9_SETTLE_S = 60.0


def _key(kind: str, reading: str, b: float, value: float) -> str:
    return f"{kind}|{reading}|{b:.4f}|{value:.4f}"


def run_point(reading: str, b: float, rpm: float, dt: float) -> dict:
    """100 s from rest at constant rpm: L'/L, ||s||, torque, distance per turn, gaps, Re, shape."""
    import numpy as np

    from physics.errors import SimulationError
    from physics.params import RPM_TO_RAD_S
    from physics.presets import apply_preset

    from physics.simulator import Simulator

    p, n = apply_preset("paper")  # at --dt (below) with the Newton tolerance of the retired `balanced` preset
    n = n.replace(newton_tol=1e-5)
    p = p.replace(head_radius=b, head_rotation=reading)
    n = n.replace(dt=dt)
    sim = Simulator(p, n)
    omega = rpm * RPM_TO_RAD_S
    sim.set_motor_speed(omega)
    steps = int(round(DURATION_S / dt))
    period = 60.0 / rpm
    turns_avg = 5
    i_avg = steps - int(round(turns_avg * period / dt))
    torque, re_max, g_rr, g_h = [], 0.0, math.inf, math.inf
    x_avg0 = None
    error = None
    cpu0 = time.process_time()
    try:
        for k in range(steps):
            sim.step()
            re_max = max(re_max, sim.reynolds_number())
            if k >= steps // 2:
                torque.append(sim.motor_torque)
            if k + 1 == i_avg:
                x_avg0 = sim.head_position
            if (k + 1) % 25 == 0:
                a, c = sim.min_gaps()
                g_rr, g_h = min(g_rr, a), min(g_h, c)
    except SimulationError as exc:
        error = str(exc)
    cpu = time.process_time() - cpu0
    x = sim.nodes
    inside = int((np.linalg.norm(x[2:] - x[0], axis=1) < b).sum()) if b > 0 else 0
    per_turn = (float(np.linalg.norm(sim.head_position - x_avg0)) / turns_avg
                if x_avg0 is not None and error is None else None)
    return {"kind": "point", "reading": reading, "head_radius": b, "omega_rpm": rpm, "dt": dt,
            "omega_bar": p.omega_bar(omega), "end_to_end_ratio": sim.end_to_end_ratio(),
            "displacement_m": sim.displacement(), "mean_motor_torque_Nm": float(np.mean(torque)) if torque else None,
            "distance_per_turn_m": per_turn, "max_reynolds": re_max, "min_rod_rod_gap_mm": g_rr * 1e3,
            "min_head_gap_mm": g_h * 1e3, "nodes_inside_head_at_end": inside, "error": error,
            "simulated_s": sim.time, "cpu_s": cpu, "final_nodes": x.tolist()}


def run_turn(reading: str, t_c: float, dt: float) -> dict:
    """R9, the paper's protocol: steady at 10 rpm, t_c at 60 rpm, back to 10 rpm; theta, phi."""
    from flagellum_env.turn_measurement import measure_turn
    from physics.errors import SimulationError
    from physics.params import RPM_TO_RAD_S
    from physics.presets import apply_preset
    from physics.simulator import Simulator

    p, n = apply_preset("paper")  # at --dt with the Newton tolerance of the retired `balanced` preset
    n = n.replace(newton_tol=1e-5)
    p = p.replace(head_radius=0.012, head_rotation=reading)
    sim = Simulator(p, n.replace(dt=dt))
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    cpu0 = time.process_time()
    try:
        sim.advance(R9_SETTLE_S)
        r = measure_turn(sim, 10.0, 60.0, t_c)
        out = {"theta_deg": r.theta_deg, "phi_deg": r.phi_deg, "straight": r.straight, "error": None}
    except SimulationError as exc:
        out = {"theta_deg": None, "phi_deg": None, "straight": False, "error": str(exc)}
    return {"kind": "turn", "reading": reading, "head_radius": 0.012, "t_c_s": t_c,
            "t_bar_c": p.t_bar(t_c), "dt": dt, "cpu_s": time.process_time() - cpu0, **out}


class Plan:
    """Which runs are needed next, given the runs done (low speeds, then bisection of omega_b)."""

    def __init__(self, done: dict[str, dict], dt: float) -> None:
        self.done = done
        self.dt = dt

    def _point(self, reading, b, rpm):
        return self.done.get(_key("point", reading, b, rpm))

    def bracket(self, reading: str, b: float) -> tuple[float | None, float | None]:
        if b == 0.0:
            reading = "torque_free"  # no head: both readings are the same swimmer (one bisection serves both)
        pts = [r for r in self.done.values() if r["kind"] == "point" and r["reading"] == reading
               and abs(r["head_radius"] - b) < 1e-9]
        below = [r["omega_rpm"] for r in pts if r["error"] is None and r["end_to_end_ratio"] >= BUCKLED_RATIO]
        above = [r["omega_rpm"] for r in pts if r["error"] is not None or r["end_to_end_ratio"] < BUCKLED_RATIO]
        hi = min(above, default=None)
        lo = max([w for w in below if hi is None or w < hi], default=None)
        return lo, hi

    def pending(self) -> list[tuple]:
        """Runs that can start now (their inputs are known), most needed first: the low speeds, then
        the b = 1.2 cm bisection and R9 under the paper's reading, then the other heads' bisection."""
        low, main, other = [], [], []
        for reading in READINGS:
            for b in HEADS_M:
                for rpm in LOW_RPM:
                    if self._point(reading, b, rpm) is None:
                        low.append(("point", reading, b, rpm))
                if b == 0.0 and reading != "torque_free":
                    continue  # the headless swimmer's bisection runs once (see ``bracket``)
                lo, hi = self.bracket(reading, b)
                if lo is None:
                    continue  # the low speeds are still running
                width = 2.0 if abs(b - 0.012) < 1e-9 else 5.0
                if hi is None:
                    nxt = {30.0: 90.0, 90.0: 150.0}.get(lo)
                    if nxt is None and lo < 90.0:
                        nxt = 90.0
                    if nxt is None:
                        continue  # no buckling up to 150 rpm (past the paper's speed axis): reported as such
                elif hi - lo > width:
                    nxt = round(0.5 * (lo + hi), 2)
                else:
                    continue
                (main if abs(b - 0.012) < 1e-9 else other).append(("point", reading, b, nxt))
        # R9 (the paper's protocol), b = 1.2 cm: the paper's reading first
        turns = []
        for reading in ("paper", "torque_free"):
            for t_c in R9_TC_S:
                if _key("turn", reading, 0.012, t_c) not in self.done:
                    turns.append(("turn", reading, 0.012, t_c))
        return low + main + turns[:len(R9_TC_S)] + other + turns[len(R9_TC_S):]


def _submit(pool, task, dt):
    kind, reading, b, v = task
    if kind == "point":
        return pool.submit(run_point, reading, b, v, dt)
    return pool.submit(run_turn, reading, v, dt)


def run_all(out: Path, workers: int, dt: float) -> dict[str, dict]:
    out.mkdir(parents=True, exist_ok=True)
    jl = out / "runs.jsonl"
    done = load(out)
    stamp = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "machine": platform.platform(),
             "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                      text=True).stdout.strip()}
    plan = Plan(done, dt)
    running: dict = {}
    with ProcessPoolExecutor(workers) as pool:
        while True:
            busy = set(running.values())
            for task in plan.pending():
                if len(running) >= workers:
                    break
                if task in busy:
                    continue
                running[_submit(pool, task, dt)] = task
                busy.add(task)
            if not running:
                break
            fin, _ = wait(list(running), return_when=FIRST_COMPLETED)
            for f in fin:
                task = running.pop(f)
                row = {**f.result(), **stamp, "load_avg": os.getloadavg()}
                v = row["omega_rpm"] if row["kind"] == "point" else row["t_c_s"]
                key = _key(row["kind"], row["reading"], row["head_radius"], v)
                with jl.open("a") as fh:
                    fh.write(json.dumps(row) + "\n")
                done[key] = row
                print(f"{time.strftime('%H:%M:%S')} done {task} cpu {row['cpu_s']:.0f} s"
                      + (f" L'/L {row['end_to_end_ratio']:.3f}" if row["kind"] == "point" else
                         f" theta {row['theta_deg']}"), flush=True)
    return done


def load(out: Path) -> dict[str, dict]:
    done = {}
    jl = out / "runs.jsonl"
    if jl.exists():
        for line in jl.read_text().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut by a kill
            v = row["omega_rpm"] if row["kind"] == "point" else row["t_c_s"]
            done[_key(row["kind"], row["reading"], row["head_radius"], v)] = row
    return done


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--dt", type=float, default=0.02, help="time step, s (default 0.02: the paper's grid at 20 ms, the retired balanced preset)")
    ap.add_argument("--out", default="results/validation")
    ap.add_argument("--docs", default="docs")
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error(f"--workers {args.workers} must be >= 1")
    out = Path(args.out)
    done = load(out) if args.report_only else run_all(out, args.workers, args.dt)
    from validation_report import write_report

    write_report(done, Path(args.docs), Plan(done, args.dt))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
