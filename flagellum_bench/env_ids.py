"""Cost of every registered id: env steps per CPU second (and per wall second) under two simple policies.

``gymnasium.make(env_id)`` with the id's own defaults, one env in this process. For each id and policy: one
untimed ``reset(seed)`` and step (caches the steady start, compiles the kernels), then timed steps, CPU time by
``time.process_time`` (this process: the env runs in it) and wall time by ``time.perf_counter``.

- ``FlagellumSteer-*``: a random path (the default), ``n_steps`` steps; an episode that ends is reset (the reset
  is timed with the steps). Policies: ``fixed`` holds the lowest motor speed (action -1: 10 rpm, straight
  swimming) and ``random`` draws a uniform action each step from the action space (seeded).
- ``FlagellumTurn-*``: one step = one planned turn (the turn-level env); ``n_episodes`` episodes on the one-turn
  path of docs/env.md, each timed from ``reset`` (which flies the swimmer to the first planned turn) to the end,
  so a decision's cost includes its share of the cruise. Policies: ``fixed`` the action 0 (the planner's turn
  as planned) and ``random``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

#: The path of docs/env.md's FlagellumTurn block: 2 cm ahead, then 8 cm to the left.
ONE_TURN_WAYPOINTS = [[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]]
POLICIES = ("fixed", "random")


def _action(env, policy: str) -> np.ndarray:
    space = env.action_space
    if policy == "random":
        return space.sample()
    return np.full(space.shape, -1.0 if space.shape == (1,) else 0.0, np.float32)


def bench_steer(env_id: str, policy: str, n_steps: int, seed: int = 0,
                on_step: Callable[[], None] | None = None) -> dict[str, Any]:
    """``n_steps`` steps of a ``FlagellumSteer-*`` id under ``policy``; steps per CPU and wall second."""
    import gymnasium as gym

    import flagellum_env  # noqa: F401  (registers the ids)

    env = gym.make(env_id)
    env.action_space.seed(seed)
    env.reset(seed=seed)
    env.step(_action(env, policy))  # untimed: steady start cached, kernels compiled
    env.reset(seed=seed)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    episodes = buckling = errors = 0
    for _ in range(n_steps):
        _, _, terminated, truncated, info = env.step(_action(env, policy))
        errors += int("error" in info)
        if on_step is not None:
            on_step()
        if terminated or truncated:
            episodes += 1
            buckling += int(info["buckling_events"])
            env.reset()
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    buckling += int(env.unwrapped.buckling.events)
    preset, dt = env.unwrapped.config.preset, env.unwrapped.config.control_dt
    env.close()
    return {"env_id": env_id, "preset": preset, "policy": policy, "control_dt_s": dt, "steps": n_steps,
            "cpu_s": round(cpu, 2), "wall_s": round(wall, 2), "steps_per_cpu_s": round(n_steps / cpu, 3),
            "steps_per_wall_s": round(n_steps / wall, 3), "sim_s_per_cpu_s": round(n_steps * dt / cpu, 2),
            "episodes_ended": episodes, "buckling_events": buckling, "simulation_errors": errors}


def bench_turn(env_id: str, policy: str, n_episodes: int, seed: int = 0,
               on_step: Callable[[], None] | None = None) -> dict[str, Any]:
    """``n_episodes`` episodes of a ``FlagellumTurn-*`` id on the one-turn path; decisions per CPU and wall
    second, resets included."""
    import gymnasium as gym

    import agents  # noqa: F401  (registers the FlagellumTurn ids)
    from flagellum_env.paths import path_from_waypoints

    path = path_from_waypoints(ONE_TURN_WAYPOINTS, name="one_turn", reach_radius_m=0.015)
    env = gym.make(env_id, paths=[path])
    env.action_space.seed(seed)
    env.reset(seed=seed)  # untimed: steady start cached, kernels compiled
    cpu = wall = sim = 0.0
    steps = 0
    for k in range(n_episodes):
        cpu0, wall0 = time.process_time(), time.perf_counter()
        env.reset(seed=seed + k)
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(_action(env, policy))
            steps += 1
            done = terminated or truncated
            if on_step is not None:
                on_step()
        cpu += time.process_time() - cpu0
        wall += time.perf_counter() - wall0
        sim += float(info["time_s"])
    preset = env.unwrapped.preset if hasattr(env.unwrapped, "preset") else None
    env.close()
    return {"env_id": env_id, "preset": preset, "policy": policy, "control_dt_s": None, "steps": steps,
            "episodes": n_episodes, "cpu_s": round(cpu, 2), "wall_s": round(wall, 2),
            "steps_per_cpu_s": round(steps / cpu, 4), "steps_per_wall_s": round(steps / wall, 4),
            "sim_s_per_cpu_s": round(sim / cpu, 2)}


def machine() -> dict[str, Any]:
    """Where and when: UTC date, load averages, cores, Python and NumPy versions."""
    import platform

    return {"date_utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "loadavg": [round(x, 2) for x in os.getloadavg()], "cpu_count": os.cpu_count(),
            "python": platform.python_version(), "numpy": np.__version__, "platform": platform.platform()}


def format_table(rows: list[dict[str, Any]]) -> str:
    """A Markdown table of the rows of ``bench_steer`` / ``bench_turn``."""
    lines = ["| id | preset | policy | steps | CPU s | steps per CPU s | steps per wall s | simulated s per CPU s |",
             "|----|--------|--------|------:|------:|----------------:|-----------------:|----------------------:|"]
    for r in rows:
        lines.append(f"| `{r['env_id']}` | `{r['preset']}` | {r['policy']} | {r['steps']} | {r['cpu_s']:.1f} | "
                     f"{r['steps_per_cpu_s']:.3g} | {r['steps_per_wall_s']:.3g} | {r['sim_s_per_cpu_s']:.3g} |")
    return "\n".join(lines)
