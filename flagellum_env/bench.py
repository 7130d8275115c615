"""Wall-clock speed of the environment: env steps per second under simple fixed policies.

Policies (continuous action): ``low`` holds the lowest motor speed (straight swimming),
``random`` draws a uniform action every step, ``high`` holds the highest speed (the flagellum
buckles after ~10 s at 150 rpm with the ``fast`` preset, and a buckled flagellum costs much
more per simulated second). Episodes that end are reset; reset time is reported apart.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from flagellum_env.steer_env import FlagellumSteerEnv

POLICIES = ("low", "random", "high")


def _action(policy: str, rng: np.random.Generator) -> np.ndarray:
    if policy == "low":
        return np.array([-1.0], np.float32)
    if policy == "high":
        return np.array([1.0], np.float32)
    return rng.uniform(-1.0, 1.0, size=1).astype(np.float32)


def bench_policy(policy: str, n_steps: int, seed: int = 0, env_kwargs: Mapping[str, Any] | None = None,
                 on_step: Callable[[], None] | None = None) -> dict[str, Any]:
    """Run ``n_steps`` env steps under ``policy``; wall-time statistics (s) of steps and resets."""
    if policy not in POLICIES:
        raise ValueError(f"policy={policy!r} is not allowed; choose one of {list(POLICIES)}")
    if n_steps < 1:
        raise ValueError(f"n_steps={n_steps!r} must be >= 1")
    kwargs = dict(env_kwargs or {})
    kwargs.setdefault("action_type", "continuous")
    env = FlagellumSteerEnv(**kwargs)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    env.reset(seed=seed)
    first_reset = time.perf_counter() - t0
    step_times, reset_times, buckling, episodes, failures = [], [], 0, 0, 0
    for _ in range(n_steps):
        t0 = time.perf_counter()
        _, _, terminated, truncated, info = env.step(_action(policy, rng))
        step_times.append(time.perf_counter() - t0)
        failures += int("error" in info)
        if on_step is not None:
            on_step()
        if terminated or truncated:
            buckling += info["buckling_events"]
            episodes += 1
            t0 = time.perf_counter()
            env.reset()
            reset_times.append(time.perf_counter() - t0)
    buckling += env.buckling.events
    env.close()
    st = np.array(step_times)
    median = float(np.median(st))
    return {
        "policy": policy, "preset": env.config.preset, "control_dt_s": env.config.control_dt,
        "n_steps": n_steps, "median_step_s": median, "steps_per_s": 1.0 / median,
        "mean_steps_per_s": float(n_steps / st.sum()), "p90_step_s": float(np.percentile(st, 90)),
        "sim_s_per_wall_s": env.config.control_dt / median, "first_reset_s": first_reset,
        "median_reset_s": float(np.median(reset_times)) if reset_times else None,
        "episodes_ended": episodes, "buckling_events": buckling, "simulation_errors": failures,
    }


def bench_env(steps: Mapping[str, int], seed: int = 0, env_kwargs: Mapping[str, Any] | None = None,
              on_step: Callable[[], None] | None = None) -> list[dict[str, Any]]:
    """``bench_policy`` for each ``{policy: n_steps}``, in order."""
    return [bench_policy(p, n, seed=seed, env_kwargs=env_kwargs, on_step=on_step) for p, n in steps.items()]


def format_table(rows: list[dict[str, Any]]) -> str:
    """A plain-text table of ``bench_env`` rows."""
    head = f"{'policy':<8} {'preset':<8} {'dt (s)':>6} {'steps':>6} {'median step (s)':>16} " \
           f"{'steps/s':>8} {'mean steps/s':>13} {'sim s / wall s':>15} {'buckling':>9}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['policy']:<8} {r['preset']:<8} {r['control_dt_s']:>6g} {r['n_steps']:>6d} "
                     f"{r['median_step_s']:>16.4f} {r['steps_per_s']:>8.2f} {r['mean_steps_per_s']:>13.2f} "
                     f"{r['sim_s_per_wall_s']:>15.2f} {r['buckling_events']:>9d}")
    return "\n".join(lines)
