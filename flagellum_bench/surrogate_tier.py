"""The turn-level surrogate as a row of ``flagellum bench --quick``: the cheapest tier, measured in the same run as
the physics presets.

``FlagellumTurn-surrogate-v0`` has no rod, so it has no steady or burst real-time factor; it is measured where the
physics presets can be compared with it:

* ``surrogate_episode``: the rule planner's episode on the quick protocol's path (``EPISODE_PATH``), flown in the
  surrogate with the planner's own turns (action 0), as the physics presets fly it on ``FlagellumSteer-v0``:
  success, cross-track error, simulated time and its CPU cost (simulated s per CPU s); and the env's speed,
  decisions per CPU s through ``gym.make`` on random paths (``SPEED_DECISIONS``, zero action, resets included,
  after an untimed episode on a random path: its compiled kernels are loaded before the clock starts);
* ``surrogate_map``: the leave-one-out error of its turn map's interpolation (``agents.surrogate_error``): every
  burst length dropped in turn and predicted from the others, θ in degrees; relative errors as the presets' (floor
  10°), over the rising branch the planners fly.

Its error against ``reference`` at the burst lengths of the physics rows is not measured: the map's samples are
the default preset's own turns, so at those it would repeat ``faithful``'s error; what the surrogate adds is its
error between samples, which the leave-one-out bounds (docs/surrogate.md: held-out turns against ``faithful``).
"""

from __future__ import annotations

import time
from typing import Any

#: the turn-level surrogate's env id (``agents.registration``)
SURROGATE_ID = "FlagellumTurn-surrogate-v0"
#: decisions timed for the env's speed (zero action, random paths from seed 1000 on; ~1 CPU s)
SPEED_DECISIONS = 20000
#: the surrogate row's metrics (``run_surrogate_metric``)
SURROGATE_METRICS = ("surrogate_episode", "surrogate_map")


def run_surrogate_metric(metric: str, path_file: str, angle_floor_deg: float) -> dict[str, Any]:
    """One metric of the surrogate row: ``surrogate_episode`` on the path file ``path_file`` (JSON) or
    ``surrogate_map`` (relative errors with the angle floor ``angle_floor_deg``, deg). Returns its values."""
    if metric == "surrogate_episode":
        return _episode(path_file)
    if metric == "surrogate_map":
        return _map_error(angle_floor_deg)
    raise ValueError(f"unknown surrogate metric {metric!r}; known: {SURROGATE_METRICS}")


def _episode(path_file: str) -> dict[str, Any]:
    import gymnasium as gym
    import numpy as np

    import agents  # noqa: F401  (registers the ids)

    env = gym.make(SURROGATE_ID)
    zero = np.zeros(env.action_space.shape, np.float32)

    def fly(seed: int, options: dict | None) -> tuple[dict, int]:
        env.reset(seed=seed, options=options)
        steps, done, info = 0, False, {}
        while not done:
            _, _, terminated, truncated, info = env.step(zero)
            steps += 1
            done = terminated or truncated
        return info, steps

    fly(0, {"path": path_file})  # untimed: the compiled kernels are loaded
    c0 = time.process_time()
    info, decisions = fly(0, {"path": path_file})
    cpu = time.process_time() - c0
    out = {"episode_success": bool(info["is_success"]), "episode_mean_cross_track_m": float(info["mean_cross_track_m"]),
           "episode_time_s": float(info["time_s"]), "episode_cpu_s": cpu, "episode_decisions": decisions,
           "rtf_cpu": float(info["time_s"]) / max(cpu, 1e-9)}
    fly(999, None)  # untimed: the random path's kernels are loaded too
    k, seed = 0, 1000
    c0 = time.process_time()
    while k < SPEED_DECISIONS:
        env.reset(seed=seed)
        seed += 1
        done = False
        while not done and k < SPEED_DECISIONS:
            _, _, terminated, truncated, _ = env.step(zero)
            k += 1
            done = terminated or truncated
    out["decisions_per_cpu_s"] = SPEED_DECISIONS / max(time.process_time() - c0, 1e-9)
    env.close()
    return out


def _map_error(angle_floor_deg: float) -> dict[str, Any]:
    from agents.assets import default_turn_map
    from agents.surrogate_calibration import SurrogateCalibration, calibration_file
    from agents.surrogate_error import leave_one_out_theta, summarise_leave_one_out
    from agents.turn_map import TurnMap
    from physics.presets import DEFAULT_PRESET

    tmap = TurnMap.load(default_turn_map(DEFAULT_PRESET))
    rows = leave_one_out_theta(tmap, SurrogateCalibration.load(calibration_file(DEFAULT_PRESET)))
    summary = summarise_leave_one_out(rows)
    measured = {(p.t_c, p.phase_deg): p.theta_deg for p in tmap.points}
    phases = sorted({p.phase_deg for p in tmap.points})
    relative = [abs(e) / max(abs(measured[(r["t_c"], ph)]), angle_floor_deg)
                for r in rows if r["on_rising_branch"] and not r["extrapolated"]
                for ph, e in zip(phases, r["errors_deg"])]
    return {"map_loo_rising_rms_deg": summary["rising_branch"]["rms_deg"],
            "map_loo_rising_max_deg": summary["rising_branch"]["max_abs_deg"],
            "map_loo_peak_rms_deg": summary["peak"]["rms_deg"],
            "map_loo_beyond_rms_deg": summary["beyond_peak"]["rms_deg"],
            "map_loo_rising_relative_max": max(relative)}
