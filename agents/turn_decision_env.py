"""Training environment of the residual PPO agent: one step = one turn the planner plans.

``TurnDecisionEnv`` (``FlagellumTurn-v0``; a ``-fast`` variant, both registered by
``import agents``) runs ``FlagellumSteer-v0`` under a ``ResidualPlanner`` (0.1 s control steps,
the rule planner's; ``planner="adaptive"``: an ``AdaptiveResidualPlanner``, the adaptive planner's). Whenever
the planner plans a turn it stops and hands the turn's features to the
agent (the observation); the agent's action corrects the turn (``ResidualLimits``); the env then
runs on until the next planned turn or the end of the episode. The reward of a step is the sum of
``FlagellumSteer-v0``'s rewards over the control steps it covered (progress, cross-track error,
energy, waypoints, penalties; weights from ``env_kwargs["reward"]``) less ``action_cost`` times
|a|^2, so with ``action_cost = 0`` the return of an episode is the base env's return.

An episode is one path: from ``paths`` in turn (validation), else drawn from this env's seeded
generator with ``random_path`` (training paths; ``planar`` may be a list to alternate planar
and 3-D paths). If a path ends without any planned turn (rare: reached by swimming straight),
the next ``step`` ends the episode with that path's return, whatever the action.

``info`` (``reset`` and every step): ``path`` (its name), ``is_success``, ``waypoints_reached``,
``mean_cross_track_m`` (over the control steps so far), ``time_s``, ``energy_J``,
``buckling_events`` and ``turns`` (decisions taken), so far in the episode; ``error`` after a
simulation error.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.assets import default_turn_map, missing_turn_map_message
from agents.controller_spec import CONTROLLER_ENV_DEFAULTS
from agents.residual_planner import ResidualLimits, base_planner
from agents.turn_map import TurnMap
from flagellum_env.config import resolve_path
from flagellum_env.paths import RandomPathConfig, WaypointPath
from flagellum_env.paths import random_path as draw_random_path
from agents.registration import TURN_ENV_ID, TURN_FAST_ENV_ID
from flagellum_env.steer_env import FlagellumSteerEnv
from physics.presets import DEFAULT_PRESET, check_preset
from physics.validation import require_finite

#: The first agent's env settings (its task and last curriculum stage; its config retired with the preset it was
#: trained on, in git history) are the defaults of every ``FlagellumTurn`` id. The shipped agent
#: (agents/pretrained/ppo_residual_adaptive) stores its own env in its ``meta.json`` (``env_id``, ``make_kwargs``). The correction limits are ``ResidualLimits()``'s defaults.
DEFAULT_ACTION_COST = 5.0
DEFAULT_ENV_KWARGS: dict[str, Any] = {"reward": {"cross_track_per_cm_s": 0.05}}
DEFAULT_RANDOM_PATH: dict[str, Any] = {"n_waypoints": 3, "segment_length_m": [0.12, 0.2], "min_turn_deg": 30.0,
                                       "max_turn_deg": 150.0, "planar": [True, False]}
RESET_OPTIONS = ("path",)
#: The keyword arguments of every ``FlagellumTurn`` env (this one and ``agents.surrogate_turn_env``).
TURN_ENV_ARGUMENTS = ("preset", "turn_map", "env_kwargs", "paths", "random_path", "limits", "action_cost",
                      "render_mode", "planner")


def load_turn_map(turn_map: str | os.PathLike | None, preset: str) -> TurnMap:
    """The turn map file ``turn_map`` (None: the preset's shipped map); ValueError (one line) naming a missing file."""
    tmap_file = Path(turn_map) if turn_map is not None else default_turn_map(preset)
    if not tmap_file.is_file():
        raise ValueError(f"turn_map={str(tmap_file)!r}: " + missing_turn_map_message(tmap_file, preset,
                                                                                       given=turn_map is not None))
    return TurnMap.load(tmap_file)


def turn_env_kwargs(env_kwargs: Mapping[str, Any] | None) -> dict[str, Any]:
    """A turn-level env's ``env_kwargs`` (None: ``DEFAULT_ENV_KWARGS``) as a dict; ValueError (one line) unless it is
    a dict of ``FlagellumSteer-v0`` arguments without ``path`` or ``render_mode`` (the env's own arguments)."""
    env_kwargs = DEFAULT_ENV_KWARGS if env_kwargs is None else env_kwargs
    if not isinstance(env_kwargs, Mapping):
        raise ValueError(f"env_kwargs={env_kwargs!r} must be a dict of FlagellumSteer-v0 arguments or None")
    for name, why in (("path", "give paths= or random_path="), ("render_mode", "give render_mode=")):
        if name in env_kwargs:
            raise ValueError(f"env_kwargs must not hold {name!r}; {why}")
    return dict(env_kwargs)


def refuse_unknown_arguments(env_id: str, unknown: Mapping[str, Any],
                             known: Sequence[str] = TURN_ENV_ARGUMENTS) -> None:
    """ValueError (one line) naming keyword arguments an env does not take, and those it does (``known``; default
    a ``FlagellumTurn`` env's)."""
    if unknown:
        raise ValueError(f"unknown argument(s) {sorted(unknown)} for {env_id}; known arguments: " + ", ".join(known))


INFO_KEYS = ("path", "is_success", "waypoints_reached", "mean_cross_track_m", "time_s", "energy_J",
             "buckling_events", "turns")


def parse_turn_action(action: Any) -> np.ndarray:
    """A decision's action as (2,) float64 (not clipped); ValueError unless it is two finite numbers."""
    if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind == "f":  # the usual one, cheaper
        a = action.astype(np.float64)
        if math.isfinite(a[0]) and math.isfinite(a[1]):
            return a
    try:
        raw = np.asarray(action)
        a = np.empty(0) if np.iscomplexobj(raw) else np.asarray(raw, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        a = np.empty(0)
    if a.size != 2 or not np.all(np.isfinite(a)):
        raise ValueError(f"action={action!r} must be two finite numbers in [-1, 1] (burst length, phase)")
    return a


class TurnEpisodes:
    """The paths of a turn-level env's episodes (``FlagellumTurn-v0`` and ``FlagellumTurn-surrogate-v0``): the
    fixed ``paths`` in turn, else drawn from the env's ``np_random`` with the ``random_path`` settings."""

    paths: list[WaypointPath] | None
    _episode: int
    np_random: np.random.Generator

    def set_random_path(self, random_path: Mapping[str, Any]) -> None:
        """Draw the next episodes' paths with these ``RandomPathConfig`` fields (curriculum); ``planar``
        may be a list, cycled per episode. ``ValueError`` naming a bad field or value."""
        self._path_configs = _random_path_configs(random_path)

    def _next_path(self) -> WaypointPath:
        k = self._episode
        self._episode += 1
        if self.paths:
            return self.paths[k % len(self.paths)]
        return draw_random_path(self.np_random, self._path_configs[k % len(self._path_configs)])

    def _episode_path(self, seed: int | None, options: dict[str, Any] | None) -> WaypointPath:
        """This episode's path (``reset``'s ``options["path"]`` or ``_next_path``); ValueError for an unknown
        reset option or a bad path. A seed restarts the fixed paths' cycle."""
        options = dict(options or {})
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: {list(RESET_OPTIONS)}")
        if seed is not None:
            self._episode = 0
        if options.get("path") is not None:
            return _fixed_path(options["path"], "options['path']")
        return self._next_path()


class TurnDecisionEnv(TurnEpisodes, gym.Env):
    """
    ## Description

    The residual agent's task (module docstring): the rule planner (or, with ``planner="adaptive"``, the
    adaptive planner) steers ``FlagellumSteer-v0`` through waypoints and, at each turn it plans, asks for a
    correction of that turn.

    ## Spaces

    Observation: ``Box(-10, 10, (n,), float32)``, the planned turn's features
    (``agents.residual_planner.turn_features``, n = ``N_FEATURES``; with ``planner="adaptive"`` followed by the
    online map's state, ``map_features``, n = ``N_ADAPTIVE_FEATURES``). Action: ``Box(-1, 1, (2,), float32)``: the correction
    of the burst length (a_0 x ``max_dtc_fraction``) and of the burst phase (a_1 x ``max_dphase_deg``).
    An action that is not two finite numbers raises ``ValueError``; entries outside [-1, 1] are clipped.

    ## Episode End

    The base env's: the last waypoint reached (``info["is_success"]``), off the path, a simulation
    error (``info["error"]``), or its time budget (truncation). No ``max_episode_steps`` at
    registration: an episode is a few to some tens of decisions.

    ## Arguments

    | Argument    | Default                          | Meaning                                               |
    |-------------|----------------------------------|-------------------------------------------------------|
    | preset      | "faithful" (the id's)            | physics preset: "faithful", "fast", "reference" or "paper" |
    | turn_map    | None                             | a turn-map file (None: the preset's, ``agents.assets.default_turn_map``) |
    | env_kwargs  | {"reward": {"cross_track_per_cm_s": 0.05}} | further ``FlagellumSteer-v0`` arguments (not ``path``); a dict given replaces the default |
    | paths       | None                             | fixed paths used in turn (any form of ``FlagellumSteer-v0``'s ``path`` but "random") |
    | random_path | 3 waypoints, 12-20 cm, turns 30-150 deg, planar and 3-D alternating | ``RandomPathConfig`` fields of the drawn paths; ``planar`` may be a list |
    | limits      | 0.05, 15 deg (``ResidualLimits()``) | ``ResidualLimits`` or a dict of its fields          |
    | action_cost | 5.0                              | c >= 0: a decision's reward is lowered by c |a|^2     |
    | planner     | "rule"                           | the planner corrected: "rule" (``ResidualPlanner``) or "adaptive" (``AdaptiveResidualPlanner``), either optionally with "@line=W" (``PlannerConfig.line_weight``) |
    | render_mode | None                             | None or "rgb_array" (the base env's frame after the step) |

    The defaults are the settings of the first agent (its config retired with the preset it was trained on; in
    git history). Every agent's ``meta.json`` stores its
    env as ``env_id`` and ``make_kwargs``: the shipped agent (agents/pretrained/ppo_residual_adaptive, trained at
    ``faithful`` on the adaptive planner with randomised swimmers) is ``gym.make(meta["env_id"],
    **meta["make_kwargs"])``, and ``PPO.load`` plus ``VecNormalize.load`` of its files on that env reproduce it. Invalid values raise ``ValueError`` naming the argument and the
    value, at construction. ``reset(options={"path": ...})`` replaces the path for one episode.

    ## Variants

    ``FlagellumTurn-fast-v0`` (``TurnDecisionFastEnv``): preset "fast", with its own turn map. A decision
    costs a few CPU seconds at each preset (docs/env.md, Speed); ``FlagellumTurn-surrogate-v0`` replays the
    turn map with no rod. ``FlagellumTurn-coarse-v0`` was retired with its preset (``gym.make`` of it raises a
    one-line ValueError naming the replacement).

    ## Version History

    - v0: initial version; ``render_mode``, ``info`` on every step, validation at construction, the
      first agent's settings as defaults and the ``-fast`` / ``-coarse`` variants added; the ``-coarse``
      variant retired with its preset (``FlagellumTurn-v0`` itself unchanged).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 2}
    env_id: ClassVar[str] = TURN_ENV_ID
    default_preset: ClassVar[str] = DEFAULT_PRESET

    def __init__(self, preset: str | None = None, turn_map: str | os.PathLike | None = None,
                 env_kwargs: Mapping[str, Any] | None = None, paths: Sequence[Any] | None = None,
                 random_path: Mapping[str, Any] | None = None, limits: ResidualLimits | Mapping[str, Any] | None = None,
                 action_cost: float = DEFAULT_ACTION_COST, render_mode: str | None = None, planner: str = "rule",
                 **unknown: Any) -> None:
        refuse_unknown_arguments(self.env_id, unknown)
        kind, planner_cls, planner_config = base_planner(planner)  # ValueError for a planner not allowed
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not allowed; choose one of "
                             f"{[None] + self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.preset = self.default_preset if preset is None else preset
        self.base, tmap = steer_base_env(self.preset, turn_map, env_kwargs, render_mode, CONTROLLER_ENV_DEFAULTS[kind])
        self.planner = planner_cls.for_env(self.base, tmap, planner_config, limits=residual_limits(limits))
        self.action_cost = require_finite("action_cost", action_cost, 0.0)
        self.paths = fixed_paths(paths)
        self.set_random_path(DEFAULT_RANDOM_PATH if random_path is None else random_path)
        self.observation_space = spaces.Box(-10.0, 10.0, (self.planner.n_features,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._episode = 0
        self._obs: np.ndarray | None = None
        self._done = True
        self._path_name = ""
        self._last: dict[str, Any] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        path = self._episode_path(seed, options)
        self._path_name = path.name
        self._obs, _ = self.base.reset(seed=seed, options={"path": path})
        self.planner.reset()
        self.planner.reach_radius_m = self.base.tracker.reach_radius_m  # this path's (random_path may draw it)
        self._start, self._done = True, False
        self._cross, self._turns = [], 0
        self._pending_reward = 0.0
        reward, terminated, truncated, info = self._advance()
        if terminated or truncated:
            # ended before any decision: the next step closes the episode with this return
            self._pending_reward, self._pending_end = reward, (terminated, truncated, info)
        else:
            self._pending_reward, self._pending_end = reward, None
        return self._features(), self._info(info)

    def step(self, action: Any):
        if self._done:
            raise RuntimeError("call reset() before step()")
        a = parse_turn_action(action)
        reward = self._pending_reward
        self._pending_reward = 0.0
        if self._pending_end is not None:
            terminated, truncated, info = self._pending_end
        else:
            a = np.clip(a, -1.0, 1.0)
            self.planner.decide(a)
            self._turns += 1
            r, terminated, truncated, info = self._advance()
            reward += r - self.action_cost * float(a @ a)
        self._done = terminated or truncated
        return self._features(), float(reward), bool(terminated), bool(truncated), self._info(info)

    def render(self):
        """The base env's frame (``render_mode="rgb_array"``): the path, the trail and the swimmer now."""
        if self.render_mode is None:
            gym.logger.warn("render() was called without a render_mode; pass render_mode='rgb_array'")
            return None
        return self.base.render()

    def _info(self, base_info: dict[str, Any]) -> dict[str, Any]:
        """The episode so far (module docstring), from the base env's last ``info``."""
        return decision_info(self._path_name, base_info, self._cross, self._turns)

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
        return np.zeros(self.planner.n_features, np.float32)

    def close(self) -> None:
        self.base.close()


class TurnDecisionFastEnv(TurnDecisionEnv):
    """``FlagellumTurn-fast-v0``: ``FlagellumTurn-v0`` (``TurnDecisionEnv``, whose docstring is the manual) at
    the ``fast`` preset (``FlagellumSteerFastEnv``: the paper's grid, a looser error tolerance) with its turn
    map. Every other argument and default is ``FlagellumTurn-v0``'s."""

    env_id: ClassVar[str] = TURN_FAST_ENV_ID
    default_preset: ClassVar[str] = "fast"


# --- shared with agents.burst_decision_env -------------------------------------------------------
def steer_base_env(preset: str, turn_map: str | os.PathLike | None, env_kwargs: Mapping[str, Any] | None,
                   render_mode: str | None, defaults: Mapping[str, Any]) -> tuple[FlagellumSteerEnv, TurnMap]:
    """(``FlagellumSteer-v0`` on random paths, the turn map) of a turn-level env: ``env_kwargs`` (None:
    ``DEFAULT_ENV_KWARGS``) merged over ``defaults`` (a controller kind's ``CONTROLLER_ENV_DEFAULTS``) and
    ``preset``; ``turn_map`` None: the preset's. ValueError (one line) naming a bad preset, argument or map."""
    check_preset(preset)
    kwargs = {**defaults, "preset": preset, **turn_env_kwargs(env_kwargs)}
    try:
        base = FlagellumSteerEnv(path="random", render_mode=render_mode, **kwargs)
    except ValueError as exc:
        raise ValueError(f"env_kwargs: {exc}") from None
    return base, load_turn_map(turn_map, preset)


def decision_info(path_name: str, base_info: Mapping[str, Any], cross_track_m: Sequence[float],
                  turns: int) -> dict[str, Any]:
    """A turn-level env's ``info`` (``INFO_KEYS``, and ``error`` after a simulation error) from the base env's
    last ``info``, the cross-track errors of the control steps so far (m) and the turns flown."""
    out = {"path": path_name, "is_success": bool(base_info["is_success"]),
           "waypoints_reached": int(base_info["waypoint_index"]),
           "mean_cross_track_m": float(np.mean(cross_track_m)) if cross_track_m else 0.0,
           "time_s": float(base_info["sim_time_s"]), "energy_J": float(base_info["energy_used_j"]),
           "buckling_events": int(base_info["buckling_events"]), "turns": turns}
    if base_info.get("error"):
        out["error"] = base_info["error"]
    return out


# --- validation ------------------------------------------------------------------------------
def residual_limits(value: Any) -> ResidualLimits | None:
    if value is None or isinstance(value, ResidualLimits):
        return value
    if isinstance(value, Mapping):
        known = [f.name for f in fields(ResidualLimits)]
        unknown = sorted(set(value) - set(known))
        if unknown:
            raise ValueError(f"limits: unknown key(s) {unknown}; allowed keys: {known}")
        return ResidualLimits(**value)
    raise ValueError(f"limits={value!r} must be a ResidualLimits, a dict of its fields or None")


def _fixed_path(spec: Any, name: str) -> WaypointPath:
    try:
        path = resolve_path(spec)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None
    if path is None:
        raise ValueError(f"{name}={spec!r}: a fixed path is needed here (a name of a path file, 'square', a "
                         "list of [x, y, z] waypoints or a WaypointPath); random paths come from random_path=")
    return path


def fixed_paths(paths: Any) -> list[WaypointPath] | None:
    if paths is None:
        return None
    if isinstance(paths, (str, bytes, os.PathLike, WaypointPath, Mapping)) or not isinstance(paths, Sequence):
        raise ValueError(f"paths={paths!r} must be a list of paths (each as FlagellumSteer-v0's path argument) "
                         "or None")
    if not paths:
        raise ValueError("paths=[] holds no path; give None to draw random paths")
    return [_fixed_path(p, f"paths[{k}]") for k, p in enumerate(paths)]


def _random_path_configs(random_path: Any) -> list[RandomPathConfig]:
    if not isinstance(random_path, Mapping):
        raise ValueError(f"random_path={random_path!r} must be a dict of RandomPathConfig fields")
    known = [f.name for f in fields(RandomPathConfig)]
    unknown = sorted(set(random_path) - set(known))
    if unknown:
        raise ValueError(f"random_path: unknown key(s) {unknown}; allowed keys: {known}")
    rp = dict(random_path)
    planar = rp.pop("planar", True)
    cycle = list(planar) if isinstance(planar, (list, tuple)) else [planar]
    if not cycle:
        raise ValueError("random_path.planar=[] must be True, False or a non-empty list of them")
    return [RandomPathConfig(**{**rp, "planar": p}) for p in cycle]
