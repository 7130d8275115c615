"""Env steps per second of RLlib PPO (``flagellum train --engine ray``) with 1 and with 2 env runners (issue 49,
item 4), and the same env stepped alone in this process (no Ray): the per-step rate r and Ray's overhead.

For each number of env runners N (``--runners``): one RLlib PPO (``agents.rllib_training.algorithm_config``, the
config of ``--config`` with ``num_env_runners`` = N and ``train_batch_size`` = ``--batch-per-runner`` x N: every
runner samples the same number of steps per iteration at every N) on a local Ray (or ``--address``); ``--warmup``
untimed iterations (actors start, Numba's kernels load), then ``--iterations`` timed ones. Per iteration: env steps
sampled / wall time of ``Algorithm.train()`` (sampling and the learner's update: what a training run gets), the
driver's CPU time (``time.process_time``, the learner included) and the env runners' (their process CPU time,
reported after each sample). The table gives medians over the timed iterations and their range.

Alone: one env from ``gymnasium.make`` in this process, zero actions, ``--alone-steps`` steps after one untimed
step: r = steps / wall s (and CPU s per step). Ray's overhead at N: N r / (steps/s at N) - 1; the env runners' CPU
s per step against the env's alone is the same comparison in CPU time (which a busy machine does not distort).

The 1-minute load average is recorded before and after each part: the figures mean something only on an idle
machine (a busy one takes cores from the env runners).

Usage::

    python scripts/bench_ray.py [--config agents/configs/rllib_ppo_surrogate.yml] [--env-id FlagellumTurn-v0]
                                [--runners 1 2] [--batch-per-runner 8] [--warmup 1] [--iterations 5]
                                [--json docs/bench_ray.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np


def load_1min() -> float:
    return round(os.getloadavg()[0], 2)


def alone(env_id: str, env_kwargs: dict[str, Any], steps: int, seed: int) -> dict[str, Any]:
    """Steps of one env in this process (zero actions): wall and CPU seconds."""
    import gymnasium as gym

    import agents  # noqa: F401  (registers the ids)

    env = gym.make(env_id, **env_kwargs)
    zero = np.zeros(env.action_space.shape, np.float32)
    env.reset(seed=seed)
    env.step(zero)  # untimed: kernels loaded
    c0, w0 = time.process_time(), time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(zero)
        if term or trunc:
            env.reset()
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    env.close()
    return {"steps": steps, "wall_s": wall, "cpu_s": cpu, "steps_per_s": steps / wall, "cpu_s_per_step": cpu / steps}


def with_ray(config, runners: int, warmup: int, iterations: int) -> dict[str, Any]:
    """Timed iterations of RLlib PPO with ``runners`` env runners (module docstring)."""
    import ray

    from agents.rllib_training import algorithm_config, start_ray

    config = dataclasses.replace(config, num_env_runners=runners)
    start_ray(config.address, config)
    rows = []
    try:
        algo = algorithm_config(config).build_algo()
        for k in range(warmup + iterations):
            c0, w0 = time.process_time(), time.perf_counter()
            result = algo.train()
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            er = result["env_runners"]
            steps = int(er.get("num_env_steps_sampled", 0))
            row = {"warmup": k < warmup, "env_steps": steps, "wall_s": wall, "driver_cpu_s": cpu,
                   "runner_cpu_s": float(er.get("flagellum_cpu_s", 0.0)), "steps_per_s": steps / wall}
            rows.append(row)
            print(f"  {runners} runner(s), iteration {k + 1}{' (warm-up)' if row['warmup'] else ''}: {steps} steps "
                  f"in {wall:.1f} s, {row['steps_per_s']:.3g} steps/s", flush=True)
        algo.stop()
    finally:
        ray.shutdown()
    timed = [r for r in rows if not r["warmup"]]
    med = {k: statistics.median(r[k] for r in timed) for k in ("steps_per_s", "wall_s", "driver_cpu_s",
                                                                 "runner_cpu_s", "env_steps")}
    return {"runners": runners, "iterations": rows, "median": med,
            "range_steps_per_s": [min(r["steps_per_s"] for r in timed), max(r["steps_per_s"] for r in timed)]}


def main() -> None:
    from agents.assets import package_file
    from agents.rllib_config import RayTrainConfig

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=package_file("configs", "rllib_ppo_surrogate.yml"))
    ap.add_argument("--env-id", default="FlagellumTurn-v0",
                    help="the env (replaces the config's; default FlagellumTurn-v0: faithful, ~2-5 CPU s per step)")
    ap.add_argument("--env-kwargs", default="{}", help="its gymnasium.make arguments, JSON (replace the config's)")
    ap.add_argument("--runners", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--batch-per-runner", type=int, default=8, help="env steps per runner and iteration")
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--iterations", type=int, default=5)
    ap.add_argument("--alone-steps", type=int, default=8, help="0: skip the measurement without Ray")
    ap.add_argument("--address", default=None, help="a Ray cluster (default: a local Ray per part)")
    ap.add_argument("--json", type=Path, default=Path("out/bench_ray.json"))
    args = ap.parse_args()

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    base = RayTrainConfig.from_yaml(args.config)
    env_kwargs = json.loads(args.env_kwargs)
    load = {"start": load_1min()}
    report: dict[str, Any] = {"env_id": args.env_id, "env_kwargs": env_kwargs, "config": str(args.config),
                              "batch_per_runner": args.batch_per_runner, "warmup": args.warmup,
                              "iterations": args.iterations, "cpu_count": os.cpu_count(),
                              "machine": platform.processor() or platform.machine(), "parts": []}
    if args.alone_steps:
        print(f"{args.env_id} alone, {args.alone_steps} steps (load {load['start']})", flush=True)
        report["alone"] = alone(args.env_id, env_kwargs, args.alone_steps, base.seed)
        load["after_alone"] = load_1min()
    for n in args.runners:
        batch = args.batch_per_runner * n
        config = dataclasses.replace(base, env_id=args.env_id, env_kwargs=env_kwargs, train_batch_size=batch,
                                     minibatch_size=min(base.minibatch_size, batch), num_epochs=1,
                                     address=args.address)
        before = load_1min()
        print(f"{n} env runner(s), {batch} steps per iteration (load {before})", flush=True)
        part = with_ray(config, n, args.warmup, args.iterations)
        part.update(load_before=before, load_after=load_1min())
        report["parts"].append(part)
    report["load_1min"] = {**load, "end": load_1min()}
    r = report.get("alone", {}).get("steps_per_s")
    print(f"\n{args.env_id}: env steps/s (median of {args.iterations} iterations after {args.warmup} warm-up; "
          f"{args.batch_per_runner} steps per runner and iteration)")
    print("| env runners | steps/s | range | wall s / iteration | driver CPU s | runners' CPU s | CPU s / step | "
          "overhead | load 1 min before / after |")
    print("|---|---|---|---|---|---|---|---|---|")
    if r:
        a = report["alone"]
        print(f"| 0 (alone, no Ray) | {r:.3g} | | {a['wall_s'] / a['steps'] * args.batch_per_runner:.3g} | "
              f"{a['cpu_s'] / a['steps'] * args.batch_per_runner:.3g} | | {a['cpu_s_per_step']:.3g} | | "
              f"{load['start']} / {load['after_alone']} |")
    for part in report["parts"]:
        m, n = part["median"], part["runners"]
        overhead = n * r / m["steps_per_s"] - 1 if r else None
        part["overhead"] = overhead
        part["runner_cpu_s_per_step"] = m["runner_cpu_s"] / m["env_steps"]
        print(f"| {n} | {m['steps_per_s']:.3g} | {part['range_steps_per_s'][0]:.3g}-{part['range_steps_per_s'][1]:.3g}"
              f" | {m['wall_s']:.3g} | {m['driver_cpu_s']:.3g} | {m['runner_cpu_s']:.3g} | "
              f"{part['runner_cpu_s_per_step']:.3g} | "
              f"{'' if overhead is None else f'{overhead:.2f}'} | {part['load_before']} / {part['load_after']} |")
    if len(report["parts"]) >= 2:
        s = {p["runners"]: p["median"]["steps_per_s"] for p in report["parts"]}
        lo, hi = min(s), max(s)
        report["speedup"] = {"runners": [lo, hi], "ratio": s[hi] / s[lo]}
        print(f"\nspeed-up {hi} vs {lo} runner(s): {s[hi] / s[lo]:.2f}x")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
