"""How well a burst ended by L'/L (the ratio clock) turns a swimmer off the model as the map says, on the rod.

For each of ``--count`` swimmers (seeds ``--seed0`` + k; E, mu and b randomised by ``--randomize`` F, the helix by
0.4 F, as ``flagellum evaluate --randomize F``), ``FlagellumBurst-v0`` at the default preset flies one burst per
length in ``--t-c`` at beta = 0 from the env's start, ended by time and by the ratio clock
(``BurstLimits.burst_end``). Per burst: the turn seen at the next decision, the map's burst length that turns as
much (on the map's rising branch: the map time the swimmer turned as), its direction about the old heading less
beta against the map's psi, the burst's flight time, and ln F, the swimmer's burst time factor
(``SurrogateSwimmer.time_factor``). Fits t_map - t_c = k (t_c - t_on) ln F by least squares for each burst end
over the bursts that stayed on the map's rising branch (direction within 90 deg of the map's: past the peak a turn
flips, and its size read back on the rising branch says nothing about its map time);
``agents.surrogate_swimmer.RATIO_CLOCK_COEFFICIENT`` is the ratio clock's k.

Usage::

    python scripts/measure_ratio_clock.py [--seed0 31000] [--count 24] [--t-c 2.8 3.1 3.4 3.6] [--randomize 0.1]
        [--out docs/ratio_clock.json]

Prints a table per burst end and length (turn error against the map's turn: mean and rms, deg; the map time's
error, s; direction error rms, deg; bursts flipped past the peak; the surrogate twin's turn and direction error
against the rod, rms, and the flips it predicts), the fitted k with its residual, and the CPU time; ``--out``
writes it all as JSON with every burst and the load average before and after.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import agents  # noqa: F401  (registers the ids)
from agents.online_turn_map import RatioClock
from agents.turn_geometry import wrap_angle
from flagellum_env.paths import path_from_waypoints

#: One waypoint 1 m ahead with a 1 m off-path band: no episode ends within one burst.
PATH = path_from_waypoints([[1.0, 0.0, 0.0]], name="far_ahead", reach_radius_m=0.015)
BURST_ENDS = ("time", "ratio")
#: a turn whose direction lies farther than this from the map's (deg) flipped: the burst went past the map's peak
FLIPPED_DEG = 90.0


def fly_bursts(seed: int, t_cs: list[float], randomize: float, burst_end: str) -> list[dict]:
    """One burst per length in ``t_cs`` (s) by the swimmer of ``seed``, each from the env's start, ended by
    ``burst_end``: turn, direction, flight time, the swimmer's factors, and the turn and direction the surrogate twin
    (``SurrogateSwimmer.turn``, the same swimmer) predicts for it."""
    f = randomize
    env_kwargs = {"randomize": {"youngs_modulus": f, "viscosity": f, "head_radius": f, "geometry": 0.4 * f,
                                "obs_noise_std": 0.0}, "off_path_m": 1.0, "max_sim_time_s": 5000.0}
    env = gym.make("FlagellumBurst-v0", paths=[PATH], env_kwargs=env_kwargs,
                   limits={"burst_end": burst_end}).unwrapped
    twin = gym.make("FlagellumBurst-surrogate-v0", paths=[PATH], env_kwargs=env_kwargs).unwrapped
    twin.reset(seed=seed)  # the same seed draws the same swimmer in both twins
    t_c_max = env.limits.t_c_max_s
    out = []
    for t_c in t_cs:
        env.reset(seed=seed)
        if env.episode_params != twin.episode_params:
            raise RuntimeError(f"seed {seed}: the twins drew different swimmers")
        c0 = time.process_time()
        env.step(np.array([t_c / t_c_max, 1.0, 0.0, -1.0]))
        entry = env.history.entries[0]
        burst = env.last_burst
        predicted = twin.swimmer.turn(np.array([1.0, 0.0, 0.0]), t_c, 0.0, burst_end)
        out.append({"seed": seed, "burst_end": burst_end, "t_c_s": t_c, "turn_deg": math.degrees(entry[1] * math.pi),
                    "direction_deg": math.degrees(math.atan2(entry[3], entry[2])), "burst_s": burst["burst_s"],
                    "stopped_by": burst["stopped_by"], "ln_F": math.log(twin.swimmer.time_factor),
                    "surrogate_turn_deg": math.degrees(predicted.theta_rad),
                    "surrogate_direction_deg": math.degrees(predicted.psi_rad), "cpu_s": time.process_time() - c0})
    env.close()
    return out


def summarise(rows: list[dict], turn_map, clock: RatioClock) -> dict:
    """Per burst end: per length the errors against the map, and the fit of k."""
    t_all, th_all, _ = turn_map.theta_curve()
    peak = float(turn_map.rising_branch()[0][-1])
    keep = t_all <= peak + 1e-9
    t_branch, th_branch = t_all[keep], th_all[keep]
    out: dict = {}
    for end in BURST_ENDS:
        mine = [r for r in rows if r["burst_end"] == end]
        for r in mine:
            r["map_turn_deg"] = float(np.interp(r["t_c_s"], t_all, th_all))
            r["map_time_s"] = float(np.interp(r["turn_deg"], th_branch, t_branch))  # the branch rises: invertible
            r["direction_error_deg"] = math.degrees(wrap_angle(math.radians(r["direction_deg"]
                                                                            - turn_map.psi_for(r["t_c_s"]))))
        per_length = {}
        for t_c in sorted({r["t_c_s"] for r in mine}):
            sel = [r for r in mine if r["t_c_s"] == t_c]
            err = np.array([r["turn_deg"] - r["map_turn_deg"] for r in sel])
            dt = np.array([r["map_time_s"] - t_c for r in sel])
            de = np.array([r["direction_error_deg"] for r in sel])
            map_psi = math.radians(turn_map.psi_for(t_c))
            s_err = np.array([r["surrogate_turn_deg"] - r["turn_deg"] for r in sel])
            s_dir = np.array([math.degrees(wrap_angle(math.radians(r["surrogate_direction_deg"] - r["direction_deg"])))
                              for r in sel])
            rod_flip = np.abs(de) > FLIPPED_DEG
            s_flip = np.array([abs(math.degrees(wrap_angle(math.radians(r["surrogate_direction_deg"]) - map_psi)))
                               > FLIPPED_DEG for r in sel])
            per_length[f"{t_c:g}"] = {"n": len(sel), "map_turn_deg": sel[0]["map_turn_deg"],
                                      "turn_error_mean_deg": float(err.mean()),
                                      "turn_error_rms_deg": float(np.sqrt((err ** 2).mean())),
                                      "map_time_error_rms_s": float(np.sqrt((dt ** 2).mean())),
                                      "direction_error_rms_deg": float(np.sqrt((de ** 2).mean())),
                                      "flipped": int(rod_flip.sum()),
                                      "surrogate_turn_error_rms_deg": float(np.sqrt((s_err ** 2).mean())),
                                      "surrogate_direction_error_rms_deg": float(np.sqrt((s_dir ** 2).mean())),
                                      "surrogate_flipped": int(s_flip.sum()),
                                      "surrogate_flipped_as_rod": int((s_flip & rod_flip).sum())}
        rising = [r for r in mine if abs(r["direction_error_deg"]) <= FLIPPED_DEG]
        x = np.array([(r["t_c_s"] - clock.start_s) * r["ln_F"] for r in rising])
        y = np.array([r["map_time_s"] - r["t_c_s"] for r in rising])
        k = float(x @ y / (x @ x))
        out[end] = {"per_length": per_length, "k": k, "residual_rms_s": float(np.sqrt(((y - k * x) ** 2).mean())),
                    "fitted": len(rising), "flipped": len(mine) - len(rising)}
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed0", type=int, default=31000)
    parser.add_argument("--count", type=int, default=24)
    parser.add_argument("--t-c", type=float, nargs="+", default=[2.8, 3.1, 3.4, 3.6])
    parser.add_argument("--randomize", type=float, default=0.1)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.count < 1 or not 0.0 < args.randomize <= 0.15:
        parser.error(f"--count {args.count} must be >= 1 and --randomize {args.randomize} in (0, 0.15]")
    if any(not 0.0 < t <= 3.7 for t in args.t_c):
        parser.error(f"--t-c {args.t_c}: each must be in (0, 3.7] s (the burst design's t_c_max)")
    load0 = os.getloadavg()
    c0 = time.process_time()
    rows = []
    for k in range(args.count):
        for end in BURST_ENDS:
            rows += fly_bursts(args.seed0 + k, args.t_c, args.randomize, end)
        print(f"swimmer {k + 1}/{args.count} done", flush=True)
    turn_map = gym.make("FlagellumBurst-v0").unwrapped.turn_map
    clock = RatioClock(turn_map)
    summary = summarise(rows, turn_map, clock)
    print(f"\nclock starts at t_on = {clock.start_s:.3f} s; swimmers {args.seed0}..{args.seed0 + args.count - 1} at "
          f"+-{args.randomize:g}")
    print("| burst end | t_c (s) | map turn (deg) | turn error mean / rms (deg) | map time error rms (s) "
          "| direction error rms (deg) | flipped | surrogate: turn / direction error rms (deg) | surrogate flipped "
          "(as the rod) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for end in BURST_ENDS:
        for t_c, s in summary[end]["per_length"].items():
            print(f"| {end} | {t_c} | {s['map_turn_deg']:.1f} | {s['turn_error_mean_deg']:+.1f} / "
                  f"{s['turn_error_rms_deg']:.1f} | {s['map_time_error_rms_s']:.3f} | "
                  f"{s['direction_error_rms_deg']:.1f} | {s['flipped']} | {s['surrogate_turn_error_rms_deg']:.1f} / "
                  f"{s['surrogate_direction_error_rms_deg']:.1f} | {s['surrogate_flipped']} "
                  f"({s['surrogate_flipped_as_rod']}) |")
    for end in BURST_ENDS:
        s = summary[end]
        print(f"{end}: t_map - t_c = k (t_c - t_on) ln F with k = {s['k']:.3f} (residual {s['residual_rms_s']:.3f} s "
              f"rms; {s['fitted']} bursts on the rising branch, {s['flipped']} flipped past the peak left out)")
    cpu = time.process_time() - c0
    print(f"CPU {cpu:.0f} s; load {load0[0]:.2f} -> {os.getloadavg()[0]:.2f}")
    if args.out is not None:
        doc = {"seed0": args.seed0, "count": args.count, "randomize": args.randomize, "t_c_s": args.t_c,
               "clock_start_s": clock.start_s, "summary": summary, "bursts": rows, "cpu_s": cpu,
               "load_before": load0, "load_after": os.getloadavg()}
        args.out.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
