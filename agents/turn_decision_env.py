"""Training environment of the residual PPO agent: one step = one turn the planner plans.

``TurnDecisionEnv`` runs ``FlagellumSteer-v0`` under a ``ResidualPlanner`` (0.1 s control steps,
the rule planner's). Whenever the planner plans a turn it stops and hands the turn's features
to the agent (the observation); the agent's action corrects the turn (``ResidualLimits``); the
env then runs on until the next planned turn or the end of the episode. The reward of a step is
the sum of ``FlagellumSteer-v0``'s rewards over the control steps it covered (progress, cross-track
error, energy, waypoints, penalties; weights from ``env_kwargs["reward"]``) less ``action_cost``
times |a|^2, so with ``action_cost = 0`` the return of an episode is the base env's return.

An episode is one path: from ``paths`` in turn (validation), else drawn from this env's seeded
generator with ``random_path`` (training paths; ``planar`` may be a list to alternate planar
and 3-D paths). If a path ends without any planned turn (rare: reached by swimming straight),
the next ``step`` ends the episode with that path's return, whatever the action.

Final ``info`` (the step that ends the episode): ``is_success``, ``waypoints_reached``,
``mean_cross_track_m`` (over the control steps), ``time_s``, ``energy_J``, ``buckling_events``
and ``turns`` (decisions taken).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.path_following import CONTROLLER_ENV_DEFAULTS
from agents.residual_planner import N_FEATURES, ResidualLimits, ResidualPlanner
from agents.assets import default_turn_map
from agents.turn_map import TurnMap
from flagellum_env.config import _resolve_path
from flagellum_env.paths import RandomPathConfig, WaypointPath
from flagellum_env.paths import random_path as draw_random_path
from flagellum_env.steer_env import FlagellumSteerEnv
from physics.presets import DEFAULT_PRESET
from physics.validation import require_finite


class TurnDecisionEnv(gym.Env):
    """Gymnasium env over the residual planner's turn decisions (module docstring).

    preset: physics preset of the swimmer; turn_map: a map file (default: the preset's committed
    map); env_kwargs: further ``FlagellumSteer-v0`` arguments (e.g. ``randomize``, ``reward``);
    paths: fixed paths, used in turn; random_path: ``RandomPathConfig`` fields for drawn paths
    (``planar`` may be a list, cycled per episode); limits: ``ResidualLimits`` or its fields;
    action_cost: c >= 0, the reward of a decision is lowered by c |a|^2 (the price of leaving the
    planner's turn: a residual policy should move it only where that pays).

    Observation: ``Box(-10, 10, (N_FEATURES,), float32)`` (``residual_planner.turn_features``).
    Action: ``Box(-1, 1, (2,), float32)``: correction of the turning angle and of the burst phase.
    """

    metadata: dict[str, Any] = {"render_modes": []}
    #: Keyword arguments of the constructor (``gym.make("FlagellumTurn-v0", ...)``).
    ARGUMENTS = ("preset", "turn_map", "env_kwargs", "paths", "random_path", "limits", "action_cost", "render_mode")

    def __init__(self, preset: str = DEFAULT_PRESET, turn_map: str | None = None, env_kwargs: Mapping[str, Any] | None = None,
                 paths: Sequence[WaypointPath] | None = None, random_path: Mapping[str, Any] | None = None,
                 limits: ResidualLimits | Mapping[str, Any] | None = None, action_cost: float = 0.0,
                 render_mode: str | None = None, **unknown: Any) -> None:
        # the same validation as FlagellumSteer-v0: a ValueError naming the argument, at construction
        if unknown:
            raise ValueError(f"unknown argument(s) {sorted(unknown)} for FlagellumTurn-v0; known arguments: "
                             f"{list(self.ARGUMENTS)}")
        if render_mode is not None:
            raise ValueError(f"render_mode={render_mode!r} is not allowed; FlagellumTurn-v0 does not render "
                             "(render FlagellumSteer-v0)")
        if env_kwargs is not None and not isinstance(env_kwargs, Mapping):
            raise ValueError(f"env_kwargs={env_kwargs!r} must be a dict of FlagellumSteer-v0 arguments or None")
        kwargs = {**CONTROLLER_ENV_DEFAULTS["rule"], "preset": preset, **dict(env_kwargs or {})}
        if "path" in kwargs:
            raise ValueError("env_kwargs must not hold 'path'; give paths= or random_path=")
        self.base = FlagellumSteerEnv(path="random", **kwargs)
        self.paths = _fixed_paths(paths)
        if limits is not None and not isinstance(limits, (ResidualLimits, Mapping)):
            raise ValueError(f"limits={limits!r} must be a ResidualLimits, a dict of its fields or None")
        if isinstance(limits, Mapping):
            try:
                limits = ResidualLimits(**limits)
            except TypeError as exc:
                raise ValueError(f"limits: {exc}") from None
        self.action_cost = require_finite("action_cost", action_cost, 0.0)
        if random_path is not None and not isinstance(random_path, Mapping):
            raise ValueError(f"random_path={random_path!r} must be a dict of RandomPathConfig fields or None")
        self.set_random_path(random_path or {})
        tmap = TurnMap.load(turn_map or default_turn_map(preset))
        self.planner = ResidualPlanner.for_env(self.base, tmap, limits=limits)
        self.observation_space = spaces.Box(-10.0, 10.0, (N_FEATURES,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._episode = 0
        self._obs: np.ndarray | None = None
        self._done = True

    def set_random_path(self, random_path: Mapping[str, Any]) -> None:
        """Draw the next episodes' paths with these ``RandomPathConfig`` fields (curriculum)."""
        rp = dict(random_path)
        planar = rp.pop("planar", True)
        cycle = list(planar) if isinstance(planar, (list, tuple)) else [planar]
        if not cycle:
            raise ValueError("random_path.planar=[] must be True, False or a non-empty list of them")
        known = [f.name for f in dataclasses.fields(RandomPathConfig)]
        unknown = sorted(set(rp) - set(known))
        if unknown:
            raise ValueError(f"random_path: unknown key(s) {unknown}; allowed keys: {known}")
        self._path_configs = [RandomPathConfig(**{**rp, "planar": p}) for p in cycle]

    def _next_path(self) -> WaypointPath:
        k = self._episode
        self._episode += 1
        if self.paths:
            return self.paths[k % len(self.paths)]
        return draw_random_path(self.np_random, self._path_configs[k % len(self._path_configs)])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"path"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: ['path']")
        fixed = _resolve_path(options["path"]) if "path" in options else None  # "random" -> None
        if seed is not None:
            self._episode = 0
        path = fixed or self._next_path()
        self._obs, _ = self.base.reset(seed=seed, options={"path": path})
        self.planner.reset()
        self._start, self._done = True, False
        self._cross, self._turns = [], 0
        self._pending_reward = 0.0
        reward, terminated, truncated, info = self._advance()
        if terminated or truncated:
            # ended before any decision: the next step closes the episode with this return
            self._pending_reward, self._pending_end = reward, (terminated, truncated, info)
        else:
            self._pending_reward, self._pending_end = reward, None
        return self._features(), {"path": path.name}

    def step(self, action: Any):
        if self._done:
            raise RuntimeError("call reset() before step()")
        reward = self._pending_reward
        self._pending_reward = 0.0
        if self._pending_end is not None:
            terminated, truncated, info = self._pending_end
        else:
            raw = np.asarray(action)
            if raw.dtype.kind not in "iuf" or raw.size != 2 or not np.all(np.isfinite(raw.astype(np.float64))):
                raise ValueError(f"action={action!r} must be two finite numbers in [-1, 1]")
            a = np.clip(raw.astype(np.float64).reshape(-1), -1.0, 1.0)
            self.planner.decide(a)
            self._turns += 1
            r, terminated, truncated, info = self._advance()
            reward += r - self.action_cost * float(a @ a)
        self._done = terminated or truncated
        out_info: dict[str, Any] = {}
        if self._done:
            out_info = {"is_success": bool(info["is_success"]), "waypoints_reached": int(info["waypoint_index"]),
                        "mean_cross_track_m": float(np.mean(self._cross)) if self._cross else 0.0,
                        "time_s": float(info["sim_time_s"]), "energy_J": float(info["energy_used_j"]),
                        "buckling_events": int(info["buckling_events"]), "turns": self._turns}
            if info.get("error"):
                out_info["error"] = info["error"]
        return self._features(), float(reward), bool(terminated), bool(truncated), out_info

    def _advance(self) -> tuple[float, bool, bool, dict[str, Any]]:
        """Run control steps until the planner waits for a decision or the episode ends."""
        total = 0.0
        while True:
            act, _ = self.planner.predict(self._obs, episode_start=np.array([self._start]))
            self._start = False
            self._obs, r, terminated, truncated, info = self.base.step(act)
            total += r
            self._cross.append(info["cross_track_error_m"])
            if terminated or truncated:
                return total, terminated, truncated, info
            if self.planner.awaiting is not None:
                return total, False, False, info

    def _features(self) -> np.ndarray:
        if self.planner.awaiting is not None:
            return self.planner.awaiting.copy()
        return np.zeros(N_FEATURES, np.float32)

    def close(self) -> None:
        self.base.close()


def _fixed_paths(paths: Any) -> list[WaypointPath] | None:
    """``paths`` as a non-empty list of validated paths (each in any form ``FlagellumSteer-v0``'s ``path`` takes,
    except "random"), or None for random paths; ValueError naming the bad one."""
    if paths is None:
        return None
    if isinstance(paths, (str, bytes, Mapping)) or not isinstance(paths, (Sequence, np.ndarray)):
        raise ValueError(f"paths={paths!r} must be a list of paths (WaypointPath, 'square', a path file or a list "
                         "of [x, y, z] waypoints) or None for random paths")
    if len(paths) == 0:
        raise ValueError("paths=[] is empty; allowed: a non-empty list of paths, or None for random paths")
    out = []
    for i, p in enumerate(paths):
        try:
            resolved = _resolve_path(p)
        except ValueError as exc:
            raise ValueError(f"paths[{i}]: {exc}") from None
        if resolved is None:
            raise ValueError(f"paths[{i}]='random' is not allowed; give random_path= for random paths")
        out.append(resolved)
    return out
