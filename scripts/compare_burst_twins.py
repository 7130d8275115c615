"""``FlagellumBurst-v0`` (the rod) against its twin ``FlagellumBurst-surrogate-v0`` (the map replayed), decision by
decision: both reset with the same seed on the same path (the nominal swimmer), then fly the same seeded random
actions; per decision, each env's turn (the angle between its headings at the decision and after it), the azimuth of
that turn about the old heading less the burst phase beta (the map's psi), the head's displacement, the simulated
time, and the CPU time. The path is one far waypoint with a wide off-path band and a long time budget, so that no
episode ends before the last decision.

Usage::

    python scripts/compare_burst_twins.py [--decisions 12] [--seed 0] [--preset faithful] [--out twins.json]

Prints a table and the summary (rms of the per-decision turn difference, over all decisions, over bursts, over bursts
on the map's rising branch and beyond it; the same of the turns' azimuth less beta; CPU s per decision in each env);
``--out`` writes all of it as JSON, with the load average before and after.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import agents  # noqa: F401  (registers the ids)
from agents.burst_design import N_BURST_ACTIONS, decode_burst_action
from agents.turn_geometry import angle_between, azimuth, wrap_angle
from flagellum_env.paths import path_from_waypoints

#: One waypoint 1 m ahead (never reached in a dozen decisions at ~0.7 mm/s), a 1 m off-path band, 5000 s of budget.
PATH = path_from_waypoints([[1.0, 0.0, 0.0]], name="far_ahead", reach_radius_m=0.015)
ENV_KWARGS = {"reward": {"cross_track_per_cm_s": 0.05}, "off_path_m": 1.0, "max_sim_time_s": 5000.0}


def _state(env: Any, twin: bool) -> tuple[np.ndarray, np.ndarray, float]:
    """(head m, heading, time s) of either env, from its public state."""
    if twin:
        return env.head.copy(), env.heading.copy(), env.time_s
    run = env.episode
    return run.head.copy(), run.heading.copy(), run.time_s


def rising_branch_end_s(preset: str) -> float:
    """The longest burst on the rod's turn map's rising branch (s): beyond it, the chaotic post-buckling branch."""
    env = gym.make("FlagellumBurst-v0", preset=preset).unwrapped
    return float(env.turn_map.rising_branch()[0][-1])


def fly(env_id: str, preset: str, seed: int, actions: np.ndarray) -> list[dict[str, Any]]:
    """Per decision of ``actions`` in ``env_id``: turn (deg), azimuth less beta (deg), displacement (m), sim and CPU
    time (s), the reward and, in the rod, the hover's record (``BurstDecisionEnv.last_burst``)."""
    twin = env_id == "FlagellumBurst-v0"
    kwargs = {"preset": preset} if twin else {}
    env = gym.make(env_id, paths=[PATH], env_kwargs=ENV_KWARGS, **kwargs).unwrapped
    c0 = time.process_time()
    env.reset(seed=seed)
    rows = [{"reset_cpu_s": time.process_time() - c0}]
    for a in actions:
        head0, d0, t0 = _state(env, twin)
        c0 = time.process_time()
        _, reward, term, trunc, info = env.step(a)
        cpu = time.process_time() - c0
        head1, d1, t1 = _state(env, twin)
        command = decode_burst_action(a, env.limits, env.control_dt if twin else env.config.control_dt)
        row = {"t_c_s": command.t_c_s, "beta_deg": math.degrees(command.beta_rad), "cruise_s": command.cruise_s,
               "turn_deg": math.degrees(angle_between(d0, d1)),
               "psi_deg": math.degrees(wrap_angle(azimuth(d1, d0) - command.beta_rad)),
               "heading": d1.tolist(), "displacement_m": float(np.linalg.norm(head1 - head0)), "sim_s": t1 - t0,
               "cpu_s": cpu, "reward": reward, "ended": bool(term or trunc)}
        if twin and command.t_c_s > 0.0:
            row["hover"] = env.last_burst
        if not twin:
            row["out_of_range"] = info["out_of_range"]
        rows.append(row)
        if term or trunc:
            break
    env.close()
    return rows


def _rms(x: list[float]) -> float:
    return float(math.sqrt(np.mean(np.square(x)))) if x else math.nan


def _psi_diff(rod: dict[str, Any], sur: dict[str, Any]) -> float:
    """The difference of the turns' azimuths less beta, deg in (-180, 180]."""
    return math.degrees(wrap_angle(math.radians(rod["psi_deg"] - sur["psi_deg"])))


def _over(rod: dict[str, Any], sur: dict[str, Any], deg: float) -> bool:
    """Whether both turns exceed ``deg`` (the azimuth of a smaller one is mostly the heading's measurement noise)."""
    return min(rod["turn_deg"], sur["turn_deg"]) > deg


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--decisions", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0, help="the envs' reset seed and the actions' generator")
    ap.add_argument("--preset", default="faithful", help="the rod's preset (the surrogate replays faithful's map)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()
    actions = np.random.default_rng(args.seed).uniform(-1.0, 1.0, (args.decisions, N_BURST_ACTIONS)).astype(np.float32)
    rod = fly("FlagellumBurst-v0", args.preset, args.seed, actions)
    sur = fly("FlagellumBurst-surrogate-v0", args.preset, args.seed, actions)
    pairs = list(zip(rod[1:], sur[1:]))
    head = (f"{'#':>2} {'t_c s':>5} {'beta':>6} {'cruise':>6} | {'turn rod':>8} {'sur':>6} {'diff':>6} | "
            f"{'psi rod':>7} {'sur':>6} | {'disp mm rod':>11} {'sur':>6} | {'sim s rod':>9} {'sur':>6} | "
            f"{'gap deg':>7} | {'cpu s rod':>9} {'hover s':>7} {'relax s':>7}")
    print(head)
    print("-" * len(head))
    for k, (r, s) in enumerate(pairs):
        hv = r.get("hover") or {}
        psi = (f"{r['psi_deg']:7.1f} {s['psi_deg']:6.1f}" if r["t_c_s"] > 0 else f"{'':7} {'':6}")
        print(f"{k:2d} {r['t_c_s']:5.1f} {r['beta_deg']:6.0f} {r['cruise_s']:6.1f} | {r['turn_deg']:8.1f} "
              f"{s['turn_deg']:6.1f} {r['turn_deg'] - s['turn_deg']:6.1f} | {psi} | "
              f"{1e3 * r['displacement_m']:11.1f} {1e3 * s['displacement_m']:6.1f} | {r['sim_s']:9.1f} "
              f"{s['sim_s']:6.1f} | {math.degrees(angle_between(np.array(r['heading']), np.array(s['heading']))):7.1f}"
              f" | {r['cpu_s']:9.2f} {hv.get('hover_s', math.nan):7.1f} {hv.get('relax_s', math.nan):7.1f}")
    bursts = [(r, s) for r, s in pairs if r["t_c_s"] > 0]
    t_rise = rising_branch_end_s(args.preset)
    summary = {
        "decisions": len(pairs), "bursts": len(bursts),
        "rms_turn_diff_deg": _rms([r["turn_deg"] - s["turn_deg"] for r, s in pairs]),
        "rms_turn_diff_deg_bursts": _rms([r["turn_deg"] - s["turn_deg"] for r, s in bursts]),
        "rising_branch_end_s": t_rise,
        "rms_turn_diff_deg_bursts_on_rising_branch": _rms([r["turn_deg"] - s["turn_deg"] for r, s in bursts
                                                           if r["t_c_s"] <= t_rise]),
        "rms_turn_diff_deg_bursts_beyond_it": _rms([r["turn_deg"] - s["turn_deg"] for r, s in bursts
                                                    if r["t_c_s"] > t_rise]),
        "rms_turn_diff_deg_no_burst": _rms([r["turn_deg"] - s["turn_deg"] for r, s in pairs if r["t_c_s"] == 0]),
        "rms_psi_diff_deg_rising_branch_turns_over_10deg": _rms([_psi_diff(r, s) for r, s in bursts
                                                                 if r["t_c_s"] <= t_rise and _over(r, s, 10.0)]),
        "rms_psi_diff_deg_beyond_it_turns_over_10deg": _rms([_psi_diff(r, s) for r, s in bursts
                                                             if r["t_c_s"] > t_rise and _over(r, s, 10.0)]),
        "rms_displacement_diff_mm": _rms([1e3 * (r["displacement_m"] - s["displacement_m"]) for r, s in pairs]),
        "rms_sim_time_diff_s": _rms([r["sim_s"] - s["sim_s"] for r, s in pairs]),
        "rod_cpu_s_per_decision": float(np.mean([r["cpu_s"] for r, _ in pairs])),
        "rod_cpu_s_per_sim_s": float(sum(r["cpu_s"] for r, _ in pairs) / sum(r["sim_s"] for r, _ in pairs)),
        "rod_reset_cpu_s": rod[0]["reset_cpu_s"],
        "surrogate_cpu_s_per_decision": float(np.mean([s["cpu_s"] for _, s in pairs])),
        "hover_timeouts": sum(bool((r.get("hover") or {}).get("hover_timed_out")) for r, _ in bursts),
        "hover_restarts": sum(int((r.get("hover") or {}).get("hover_restarts", 0)) for r, _ in bursts),
        "surrogate_out_of_range": sum(bool(s["out_of_range"]) for _, s in pairs),
    }
    load1 = os.getloadavg()
    print()
    for k, v in summary.items():
        print(f"{k:48} {v:.4g}" if isinstance(v, float) else f"{k:48} {v}")
    print(f"{'load average (1, 5, 15 min)':48} before {load0}, after {load1}")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"seed": args.seed, "preset": args.preset, "path": PATH.waypoints.tolist(),
                                        "env_kwargs": ENV_KWARGS, "actions": actions.tolist(), "rod": rod,
                                        "surrogate": sur, "summary": summary, "load_before": load0,
                                        "load_after": load1}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
