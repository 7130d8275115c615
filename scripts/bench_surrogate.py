"""Speed and error of ``FlagellumTurn-surrogate-v0`` (issue 48, item 3): decisions per CPU second through
``gymnasium.make`` and the leave-one-out error of its turn-map interpolation, optionally against ``faithful`` turns.

Speed: one env from ``gym.make`` (its wrappers included), one process, ``time.process_time``; each repeat runs
``--decisions`` decisions over as many episodes as they take (resets included, random paths of the env's defaults),
after one untimed episode (numba's compiled kernels loaded); the table gives the median over ``--repeats`` repeats and
their range. Policies: ``zero`` (the planner's turn as planned) and ``random`` (``action_space.sample()``, seeded),
nominal and randomised swimmers (``randomize=True``). The machine's load average is printed before and after: the
CPU clock counts this process only, but a loaded machine still slows it (shared caches, frequency).

Error: ``agents.surrogate_error.leave_one_out_theta`` (theta predicted at each burst length of the map from the
others, degrees). ``--faithful K``: also K turns of the default preset at burst lengths and phases off the map's grid
(``agents.turn_measurement.measure_turn``, ~3 CPU s each), against the surrogate's theta there; each finished turn is
appended to ``--faithful-cache`` (JSONL) and not run again (resumable).

Usage::

    python scripts/bench_surrogate.py [--decisions 20000] [--repeats 5] [--faithful 6]
                                      [--json docs/bench_surrogate.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import agents  # noqa: F401  (registers the ids)
from agents.assets import default_turn_map
from agents.surrogate_calibration import SurrogateCalibration, calibration_file
from agents.surrogate_error import leave_one_out_theta, summarise_leave_one_out
from agents.surrogate_swimmer import SurrogateSwimmer, TurnMapTable
from agents.turn_map import TurnMap
from physics.presets import DEFAULT_PRESET

ID = "FlagellumTurn-surrogate-v0"
#: Held-out faithful turns: (t_c s, phase deg) off the map's grid, on the rising branch where the planner flies.
HELD_OUT = [(2.25, 45.0), (2.875, 135.0), (3.1875, 225.0), (3.3125, 315.0), (3.4375, 45.0), (3.5625, 135.0),
            (3.6875, 225.0), (3.8125, 315.0)]


def load_average() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def time_decisions(kwargs: dict, policy: str, n: int, seed: int) -> tuple[float, float, int]:
    """(CPU s, wall s, episodes) of ``n`` decisions of one env from ``gym.make``."""
    env = gym.make(ID, **kwargs)
    env.action_space.seed(seed)
    zero = np.zeros(2, np.float32)
    env.reset(seed=seed)
    done = False
    while not done:  # untimed: kernels loaded, caches warm
        _, _, term, trunc, _ = env.step(zero)
        done = term or trunc
    episodes, k = 0, 0
    c0, w0 = time.process_time(), time.perf_counter()
    env.reset()
    while k < n:
        a = zero if policy == "zero" else env.action_space.sample()
        _, _, term, trunc, _ = env.step(a)
        k += 1
        if term or trunc:
            episodes += 1
            env.reset()
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    env.close()
    return cpu, wall, episodes


def speed_rows(n: int, repeats: int) -> list[dict]:
    rows = []
    for label, kwargs in (("nominal", {}), ("randomised", {"env_kwargs": {"randomize": True}})):
        for policy in ("zero", "random"):
            runs = [time_decisions(kwargs, policy, n, seed=1000 + r) for r in range(repeats)]
            rates = [n / c for c, _, _ in runs]
            wall = [n / w for _, w, _ in runs]
            rows.append({"swimmer": label, "policy": policy, "decisions": n, "repeats": repeats,
                         "median_per_cpu_s": statistics.median(rates), "min_per_cpu_s": min(rates),
                         "max_per_cpu_s": max(rates), "median_per_wall_s": statistics.median(wall),
                         "us_per_decision": 1e6 / statistics.median(rates),
                         "decisions_per_episode": n / max(1, statistics.median(e for _, _, e in runs))})
    return rows


def faithful_turns(k: int, cache: Path) -> list[dict]:
    """Up to ``k`` held-out turns of the default preset (cached), each with the surrogate's theta there."""
    from agents.turn_measurement import measure_turn
    from agents.turn_calibration import SETTLE_TURNS
    from flagellum_env.steady_start import get_steady_start
    from physics.params import RPM_TO_RAD_S

    tmap = TurnMap.load(default_turn_map(DEFAULT_PRESET))
    done = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            rec = json.loads(line)
            done[(rec["t_c"], rec["phase_deg"])] = rec
    for t_c, phase in HELD_OUT[:k]:
        if (t_c, phase) in done:
            continue
        start = get_steady_start(tmap.params, tmap.numerics, tmap.omega_l_rpm * RPM_TO_RAD_S,
                                 SETTLE_TURNS * 60.0 / tmap.omega_l_rpm)
        c0 = time.process_time()
        res = measure_turn(start.new_simulator(), tmap.omega_l_rpm, tmap.omega_h_rpm, t_c, phase,
                           phase_node=tmap.phase_node)
        rec = {"t_c": t_c, "phase_deg": phase, "theta_deg": res.theta_deg, "psi_deg": res.psi_deg,
               "cpu_s": round(time.process_time() - c0, 2)}
        cache.parent.mkdir(parents=True, exist_ok=True)
        with cache.open("a") as f:
            f.write(json.dumps(rec) + "\n")
        done[(t_c, phase)] = rec
        print(f"  faithful turn t_c={t_c} s, phase {phase} deg: theta {res.theta_deg:.1f} deg ({rec['cpu_s']} CPU s)")
    sw = SurrogateSwimmer(tmap, SurrogateCalibration.load(calibration_file(DEFAULT_PRESET)), TurnMapTable(tmap))
    out = []
    for t_c, phase in HELD_OUT[:k]:
        rec = dict(done[(t_c, phase)])
        turn = sw.turn(np.array([1.0, 0.0, 0.0]), t_c, math.radians(phase))
        rec["surrogate_theta_deg"] = math.degrees(turn.theta_rad)
        rec["error_deg"] = rec["surrogate_theta_deg"] - rec["theta_deg"]
        out.append(rec)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--decisions", type=int, default=20000, help="decisions per repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--faithful", type=int, default=0, help=f"held-out faithful turns (0-{len(HELD_OUT)})")
    ap.add_argument("--faithful-cache", type=Path, default=Path("results/bench/surrogate_faithful.jsonl"))
    ap.add_argument("--json", type=Path, default=Path("docs/bench_surrogate.json"))
    args = ap.parse_args(argv)
    if args.decisions < 1 or args.repeats < 1 or not 0 <= args.faithful <= len(HELD_OUT):
        ap.error(f"--decisions and --repeats must be >= 1 and --faithful in [0, {len(HELD_OUT)}]")
    load0 = load_average()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average {load0}")
    rows = speed_rows(args.decisions, args.repeats)
    load1 = load_average()
    print(f"\n{ID} through gym.make, one process, CPU time (time.process_time), median of {args.repeats} x "
          f"{args.decisions} decisions (resets included)\n")
    print("| swimmer | policy | decisions per CPU s (median) | range | per wall s | us per decision | "
          "decisions per episode |")
    print("|---|---|---:|---|---:|---:|---:|")
    for r in rows:
        print(f"| {r['swimmer']} | {r['policy']} | {r['median_per_cpu_s']:,.0f} | {r['min_per_cpu_s']:,.0f}-"
              f"{r['max_per_cpu_s']:,.0f} | {r['median_per_wall_s']:,.0f} | {r['us_per_decision']:.0f} | "
              f"{r['decisions_per_episode']:.1f} |")
    print(f"\nload average before {load0}, after {load1}")
    tmap = TurnMap.load(default_turn_map(DEFAULT_PRESET))
    loo = leave_one_out_theta(tmap, SurrogateCalibration.load(calibration_file(DEFAULT_PRESET)))
    summary = summarise_leave_one_out(loo)
    print("\nLeave-one-out theta error of the map interpolation (predicted - measured, deg; 4 phases each)\n")
    print("| t_c (s) | branch | mean abs (deg) | max abs (deg) | errors per phase (deg) |")
    print("|---:|---|---:|---:|---|")
    for r in loo:
        kind = ("extrapolated" if r["extrapolated"] else "rising" if r["on_rising_branch"] else "peak" if r["peak"]
                else "beyond peak")
        print(f"| {r['t_c']:g} | {kind} | {r['mean_abs_deg']:.2f} | {r['max_abs_deg']:.2f} | "
              f"{', '.join(f'{e:+.1f}' for e in r['errors_deg'])} |")
    for key, s in summary.items():
        print(f"{key}: RMS {s['rms_deg']:.2f} deg, max |error| {s['max_abs_deg']:.2f} deg over {s['n']} turns")
    held = faithful_turns(args.faithful, args.faithful_cache) if args.faithful else []
    if held:
        print("\nHeld-out faithful turns (off the map's grid) against the surrogate\n")
        print("| t_c (s) | phase (deg) | faithful theta (deg) | surrogate theta (deg) | error (deg) | faithful CPU s |")
        print("|---:|---:|---:|---:|---:|---:|")
        for h in held:
            print(f"| {h['t_c']:g} | {h['phase_deg']:g} | {h['theta_deg']:.1f} | {h['surrogate_theta_deg']:.1f} | "
                  f"{h['error_deg']:+.1f} | {h['cpu_s']} |")
    out = {"id": ID, "machine": {"cores": os.cpu_count(), "load_before": load0, "load_after": load1,
                       "python": platform.python_version()},
           "speed": rows, "leave_one_out": {"rows": loo, "summary": summary}, "faithful_held_out": held}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
