"""CPU cost of the RFT swimmer's step: the Python banded Newton iteration against the compiled one.

The swimmer: ``faithful``'s numerics (adaptive BDF3, step_tol 1e-4, Newton tolerance 1e-5, no Anderson mixing) with
``hydro_model="rft"`` (local resistive-force theory: the exact banded Newton step of ``step_solvers
.BandedNewtonSolver``), at N nodes. No preset uses RFT yet; this is the configuration the compiled iteration
(``chord_iteration.chord_loop`` with the banded increment) takes.

Protocol, per node count and per repeat, for each path (``Simulator.compiled_chord`` False: the Python iteration
``Simulator._chord_python``; True: the compiled one), in alternating order: a new simulator, 6 s at 10 rpm from
rest (settling, not timed), then ``--steady`` s at 10 rpm (timed: steady), then ``--burst`` s at 150 rpm (timed:
burst; the flagellum buckles after ~4.5 s at N = 40). CPU seconds by ``time.process_time``; the table shows the
medians over the repeats, the real-time factor (simulated / CPU seconds) and the ratio Python / compiled. Both
paths must end on the same bits (their configurations' SHA-256 are compared and printed). The machine's load (1-min
average, ``os.getloadavg``) is recorded before and after.

    python scripts/bench_rft_step.py                         # N = 40, 60, 80, 122; 3 repeats
    python scripts/bench_rft_step.py --nodes 40 --repeats 5 --json out/bench/rft_step.json

Prints a table and writes JSON (default out/bench/rft_step.json).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import statistics
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

from physics import Simulator, advance, configure
from physics.params import RPM_TO_RAD_S

SETTLE_S = 6.0


def swimmer(n_nodes: int, compiled: bool) -> Simulator:
    """An RFT swimmer on ``faithful``'s numerics at ``n_nodes`` nodes, on the compiled or the Python iteration."""
    params, numerics = configure("faithful", {"hydro_model": "rft", "n_nodes": n_nodes})
    sim = Simulator(params, numerics)
    sim.compiled_chord = compiled
    return sim


def one_run(n_nodes: int, compiled: bool, steady_s: float, burst_s: float) -> dict:
    """Settle, then the timed steady and burst phases: CPU s, accepted steps and residuals of each phase, and the
    hash of the final configuration."""
    sim = swimmer(n_nodes, compiled)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, SETTLE_S)
    out = {}
    for phase, rpm, seconds in (("steady", 10.0, steady_s), ("burst", 150.0, burst_s)):
        sim.set_motor_speed(rpm * RPM_TO_RAD_S)
        steps0, it0 = sim.stats.substeps, sim.stats.newton_iterations
        c0 = time.process_time()
        advance(sim, seconds)
        out[phase] = {"cpu_s": time.process_time() - c0, "steps": sim.stats.substeps - steps0,
                      "residuals": sim.stats.newton_iterations - it0}
    out["lratio_end"] = sim.end_to_end_ratio()
    out["hash"] = hashlib.sha256(sim.q.tobytes()).hexdigest()[:16]
    return out


def bench(nodes: list[int], repeats: int, steady_s: float, burst_s: float) -> list[dict]:
    rows = []
    for n in nodes:
        for compiled in (False, True):  # warm-up: compile (or load the cache) outside the timing
            one_run(n, compiled, 0.2, 0.2)
        runs: dict[bool, list[dict]] = {False: [], True: []}
        for rep in range(repeats):
            for compiled in ((False, True) if rep % 2 == 0 else (True, False)):
                runs[compiled].append(one_run(n, compiled, steady_s, burst_s))
        hashes = {c: {r["hash"] for r in runs[c]} for c in runs}
        row = {"n_nodes": n, "same_bits": hashes[False] == hashes[True] and len(hashes[False]) == 1,
               "hash": sorted(hashes[True])[0], "lratio_end": runs[True][0]["lratio_end"]}
        for phase, seconds in (("steady", steady_s), ("burst", burst_s)):
            med = {c: statistics.median(r[phase]["cpu_s"] for r in runs[c]) for c in runs}
            row[phase] = {"seconds": seconds, "python_cpu_s": med[False], "compiled_cpu_s": med[True],
                          "python_cpu_s_all": [r[phase]["cpu_s"] for r in runs[False]],
                          "compiled_cpu_s_all": [r[phase]["cpu_s"] for r in runs[True]],
                          "steps": runs[True][0][phase]["steps"], "residuals": runs[True][0][phase]["residuals"],
                          "rtf_python": seconds / med[False], "rtf_compiled": seconds / med[True],
                          "ratio": med[False] / med[True]}
        rows.append(row)
        print_row(row)
    return rows


def print_header() -> None:
    print(f"{'N':>4} {'phase':>7} {'sim s':>6} {'steps':>6} {'resid.':>7} {'Python CPU s':>13} "
          f"{'compiled CPU s':>15} {'RTF Python':>11} {'RTF compiled':>13} {'ratio':>6}  bits", flush=True)


def print_row(row: dict) -> None:
    for phase in ("steady", "burst"):
        d = row[phase]
        print(f"{row['n_nodes']:>4} {phase:>7} {d['seconds']:>6.1f} {d['steps']:>6} {d['residuals']:>7} "
              f"{d['python_cpu_s']:>13.3f} {d['compiled_cpu_s']:>15.3f} {d['rtf_python']:>11.1f} "
              f"{d['rtf_compiled']:>13.1f} {d['ratio']:>6.2f}  "
              f"{'same ' + row['hash'] if row['same_bits'] else 'DIFFERENT'}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nodes", type=int, nargs="+", default=[40, 60, 80, 122])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steady", type=float, default=10.0, help="timed seconds at 10 rpm")
    ap.add_argument("--burst", type=float, default=7.5, help="timed seconds at 150 rpm")
    ap.add_argument("--json", default="out/bench/rft_step.json")
    a = ap.parse_args()
    if a.repeats < 1 or a.steady <= 0 or a.burst <= 0 or any(n < 4 for n in a.nodes):
        ap.error(f"--repeats {a.repeats}, --steady {a.steady}, --burst {a.burst}, --nodes {a.nodes} are not allowed; "
                 "allowed: repeats >= 1, positive seconds, node counts >= 4")
    load_before = os.getloadavg()[0]
    print_header()
    with threadpool_limits(limits=1):
        rows = bench(a.nodes, a.repeats, a.steady, a.burst)
    load_after = os.getloadavg()[0]
    print(f"load (1-min average) {load_before:.2f} before, {load_after:.2f} after; medians of {a.repeats} repeats")
    out = {"protocol": {"preset": "faithful", "overrides": {"hydro_model": "rft"}, "settle_s_at_10rpm": SETTLE_S,
                        "steady_s_at_10rpm": a.steady, "burst_s_at_150rpm": a.burst, "repeats": a.repeats,
                        "timer": "time.process_time", "statistic": "median"},
           "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "load_before": load_before,
                       "load_after": load_after},
           "measured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "rows": rows}
    path = Path(a.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
