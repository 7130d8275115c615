"""A from-scratch agent (``flagellum train`` with ``task.design: burst``) on fixed paths, in a ``FlagellumBurst-*`` env.

The agent's deterministic action (stable-baselines3 PPO or SAC, as its ``meta.json`` says, with the ``BurstLimits`` it
was trained with; observations normalised by its ``vecnormalize.pkl``) flies each path once in ``--env``
(``FlagellumBurst-v0``: the rod at ``--preset``; or ``FlagellumBurst-surrogate-v0``), with the seeds of ``flagellum evaluate``: every path at ``--seed0`` for the
nominal swimmer, the k-th path (in file-name order) at ``--seed0 + k`` with ``--randomize F`` (E, mu and b by F,
the helix by 0.4 F, as ``flagellum evaluate --randomize F``), so the swimmers are those the planners met there.
Per path: success, waypoints, the mean cross-track error, simulated time and bursts; prints a table, writes JSON.
One process per path task (``--workers``).

Usage::

    python scripts/evaluate_burst_agent.py --agent DIR --paths DIR --seed0 11000 [--randomize 0.1]
        [--env FlagellumBurst-v0] [--workers 2] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ENVS = ("FlagellumBurst-v0", "FlagellumBurst-surrogate-v0")


def fly(task: dict) -> dict:
    """One episode of the agent in ``task["env"]`` on ``task["path"]`` (a path file) with ``task["seed"]``."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    import gymnasium as gym
    import torch
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import agents  # noqa: F401  (registers the ids)
    from agents.evaluation import resolve_paths
    from agents.ppo_training import algorithm_class

    torch.set_num_threads(1)
    path = resolve_paths([task["path"]])[0]
    env_kwargs = {"reward": {"cross_track_per_cm_s": 0.05}}
    if task["randomize"]:
        f = task["randomize"]
        env_kwargs["randomize"] = {"youngs_modulus": f, "viscosity": f, "head_radius": f, "geometry": 0.4 * f,
                                   "obs_noise_std": 0.0}
    agent = Path(task["agent"])
    agent_meta = json.loads((agent / "meta.json").read_text(encoding="utf-8"))
    # the agent's own action design (its BurstLimits: t_c_max, cruises, how a burst ends), as the pilot flies it
    make_kwargs = {"env_kwargs": env_kwargs, "paths": [path],
                   "limits": agent_meta.get("make_kwargs", {}).get("limits")}
    if task["env"] == "FlagellumBurst-v0":
        make_kwargs["preset"] = task["preset"]
    venv = VecNormalize.load(str(agent / "vecnormalize.pkl"),
                             DummyVecEnv([lambda: gym.make(task["env"], **make_kwargs)]))
    venv.training, venv.norm_reward = False, False
    run = agent_meta.get("run", {})
    model = algorithm_class(run.get("algorithm", "ppo")).load(str(agent / "model.zip"), env=venv, device="cpu")
    t0, c0 = time.perf_counter(), time.process_time()
    venv.seed(task["seed"])
    obs = venv.reset()
    done, decisions = [False], 0
    while not done[0]:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, done, infos = venv.step(action)
        decisions += 1
    info = infos[0]
    venv.close()
    return {"path": path.name, "seed": task["seed"], "success": bool(info["is_success"]),
            "waypoints_reached": int(info["waypoints_reached"]), "n_waypoints": int(path.n_waypoints),
            "mean_cross_track_m": float(info["mean_cross_track_m"]), "time_s": float(info["time_s"]),
            "bursts": int(info["turns"]), "decisions": decisions, "error": info.get("error"),
            "out_of_range": bool(info.get("out_of_range", False)),
            "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agent", type=Path, required=True, help="the agent's folder (model.zip, vecnormalize.pkl)")
    parser.add_argument("--paths", type=Path, required=True, help="a folder of path files (scripts/make_eval_paths.py)")
    parser.add_argument("--env", choices=ENVS, default=ENVS[0])
    parser.add_argument("--preset", default="faithful", help="FlagellumBurst-v0's preset (default faithful)")
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--randomize", type=float, default=0.0, help="a fraction in [0, 0.15] (0: nominal)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    if not 0.0 <= args.randomize <= 0.15:
        parser.error(f"--randomize {args.randomize!r} is not allowed; allowed: a fraction in [0, 0.15]")
    for f in ("model.zip", "vecnormalize.pkl", "meta.json"):
        if not (args.agent / f).is_file():
            parser.error(f"--agent {str(args.agent)!r} lacks {f}; allowed: a folder written by flagellum train")
    files = sorted(args.paths.glob("*.json"))
    if not files:
        parser.error(f"--paths {str(args.paths)!r} holds no path files (*.json)")
    tasks = [{"agent": str(args.agent), "path": str(p), "env": args.env, "preset": args.preset,
              "randomize": args.randomize, "seed": args.seed0 + (k if args.randomize else 0)}
             for k, p in enumerate(files)]
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        rows = list(pool.map(fly, tasks))
    print(f"{args.env} ({args.preset if args.env == ENVS[0] else 'surrogate'}), randomize {args.randomize:g}, "
          f"agent {args.agent}; 1-min load {os.getloadavg()[0]:.2f}")
    print("| path | seed | success | waypoints | cross-track (cm) | time (s) | bursts | CPU s |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['path']} | {r['seed']} | {'yes' if r['success'] else 'no'} | {r['waypoints_reached']}/"
              f"{r['n_waypoints']} | {100 * r['mean_cross_track_m']:.2f} | {r['time_s']:.0f} | {r['bursts']} | "
              f"{r['cpu_s']:.0f} |")
    ok = sum(r["success"] for r in rows)
    summary = {"episodes": len(rows), "successes": ok,
               "mean_cross_track_m": float(np.mean([r["mean_cross_track_m"] for r in rows])),
               "mean_cross_track_successes_m": (float(np.mean([r["mean_cross_track_m"] for r in rows if r["success"]]))
                                                if ok else None)}
    print(f"success {ok}/{len(rows)}; mean cross-track {100 * summary['mean_cross_track_m']:.2f} cm")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()}, "summary": summary,
                                         "rows": rows}, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
