"""Paired episodes of ``FlagellumTurn-v0`` (the default preset's rod) and ``FlagellumTurn-surrogate-v0``: the same seed
draws the same path (and, with ``--randomize``, the same swimmer) in both; both fly the planner's turns (action 0).

Per seed: success, waypoints, decisions, episode time and return in each, and the mean |difference| of each feature of
the observations at the decisions both reached (paired by index). Each finished physics episode is appended to
``--cache`` (JSONL) and not run again: a run can be stopped and resumed (the physics costs 1-20 CPU s per decision).

Usage::

    python scripts/compare_surrogate.py --seeds 0 1 2 [--randomize [--noise 0]]
                                        [--cache results/bench/surrogate_pairs.jsonl]
    python scripts/compare_surrogate.py --eval-paths        # the 20 shipped evaluation paths
    python scripts/compare_surrogate.py --paths DIR         # the path files in DIR (e.g. scripts/make_eval_paths.py's)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import agents  # noqa: F401  (registers the ids)
from agents.assets import eval_paths_dir

FEATURES = ("theta/max", "t_c/10", "miss/R", "straight miss/R", "distance/0.1m", "heading error/90",
            "corner/90", "next segment/0.1m", "L'/L", "time left", "turns/5", "had previous", "theta ratio",
            "azimuth error/90")


def episode(env_id: str, seed: int, randomize: bool | dict, path: str | None = None) -> dict:
    kwargs = {"env_kwargs": {"reward": {"cross_track_per_cm_s": 0.05}, "randomize": randomize}}
    env = gym.make(env_id, **kwargs)
    c0 = time.process_time()
    obs, info = env.reset(seed=seed, options={"path": path} if path else None)
    observations, ret, done = [obs.tolist()], 0.0, False
    while not done:
        obs, r, term, trunc, info = env.step(np.zeros(2, np.float32))
        ret += r
        done = term or trunc
        if not done:
            observations.append(obs.tolist())
    env.close()
    return {"env_id": env_id, "seed": seed, "randomize": randomize, "path": path, "return": ret,
            "is_success": info["is_success"], "waypoints_reached": info["waypoints_reached"], "turns": info["turns"],
            "time_s": info["time_s"], "mean_cross_track_m": info["mean_cross_track_m"],
            "observations": observations, "cpu_s": round(time.process_time() - c0, 2), "error": info.get("error"),
            "end": {k: info[k] for k in ("is_success",) if k in info}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--randomize", action="store_true")
    ap.add_argument("--noise", type=float, default=None,
                    help="with --randomize: obs_noise_std instead of the default 0.01 (0: the swimmer only)")
    ap.add_argument("--eval-paths", action="store_true",
                    help="fly the 20 shipped evaluation paths (agents/eval_paths, seed 0) instead of random ones")
    ap.add_argument("--paths", type=Path, default=None, metavar="DIR",
                    help="fly the path files (JSON) in DIR (seed 0) instead of random ones")
    ap.add_argument("--cache", type=Path, default=Path("results/bench/surrogate_pairs.jsonl"))
    args = ap.parse_args(argv)
    randomize = ({"obs_noise_std": args.noise} if args.noise is not None else True) if args.randomize else False
    key_r = json.dumps(randomize, sort_keys=True)
    done = {}
    if args.cache.is_file():
        for line in args.cache.read_text().splitlines():
            rec = json.loads(line)
            done[(rec["seed"], json.dumps(rec["randomize"], sort_keys=True), rec.get("path"))] = rec
    rows = []
    if args.paths is not None and not sorted(args.paths.glob("*.json")):
        ap.error(f"--paths {str(args.paths)!r}: no path files (*.json) there")
    folder = eval_paths_dir() if args.eval_paths else args.paths
    runs = ([(0, str(p)) for p in sorted(folder.glob("*.json"))] if folder is not None
            else [(seed, None) for seed in args.seeds])
    for seed, path in runs:
        if (seed, key_r, path) not in done:
            rec = episode("FlagellumTurn-v0", seed, randomize, path)
            args.cache.parent.mkdir(parents=True, exist_ok=True)
            with args.cache.open("a") as f:
                f.write(json.dumps(rec) + "\n")
            done[(seed, key_r, path)] = rec
        phys, sur = done[(seed, key_r, path)], episode("FlagellumTurn-surrogate-v0", seed, randomize, path)
        n = min(len(phys["observations"]), len(sur["observations"]))
        diff = np.abs(np.array(phys["observations"][:n]) - np.array(sur["observations"][:n])).mean(axis=0)
        rows.append((Path(path).stem if path else seed, phys, sur, diff))
    print("| seed or path | success (rod / surrogate) | waypoints | decisions | time (s) | return | rod CPU s |")
    print("|---|---|---|---|---|---|---:|")
    for seed, p, s, _ in rows:
        print(f"| {seed} | {p['is_success']} / {s['is_success']} | {p['waypoints_reached']} / {s['waypoints_reached']}"
              f" | {p['turns']} / {s['turns']} | {p['time_s']:.0f} / {s['time_s']:.0f} | {p['return']:.1f} / "
              f"{s['return']:.1f} | {p['cpu_s']} |")
    same = sum(p["waypoints_reached"] == s["waypoints_reached"] for _, p, s, _ in rows)
    print(f"\nsame waypoints reached: {same} of {len(rows)}; success rod {sum(p['is_success'] for _, p, _, _ in rows)}, "
          f"surrogate {sum(s['is_success'] for _, _, s, _ in rows)}")
    mean = np.mean([d for *_, d in rows], axis=0)
    print("\nmean |rod - surrogate| of each feature at paired decisions:")
    print(", ".join(f"{name} {v:.3f}" for name, v in zip(FEATURES, mean)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
