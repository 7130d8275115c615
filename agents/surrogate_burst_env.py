"""``FlagellumBurst-surrogate-v0``: the burst action design (``agents.burst_design``) on the turn-level surrogate.

No planner: each action is a burst command (length, phase, cruise after it) that the kinematic swimmer of
``agents.surrogate_swimmer`` flies through ``agents.surrogate_episode.SurrogateEpisode`` (hover to the phase,
burst, relax, cruise; legs, rewards, waypoints and the time budget as in ``FlagellumTurn-surrogate-v0``). Its
physics twin, with the rod, is ``FlagellumBurst-v0``; the two share spaces, rewards and ``info`` keys so that an
agent trained here flies there.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from agents.burst_design import (N_BURST_ACTIONS, N_BURST_FEATURES, SURROGATE_BURST_ENV_ARGUMENTS, BurstHistory,
                                 BurstLimits, burst_limits, burst_observation, decode_burst_action, parse_map_noise,
                                 turn_seen)
from agents.controller_spec import CONTROLLER_ENV_DEFAULTS
from agents.registration import BURST_SURROGATE_ENV_ID
from agents.surrogate_episode import SurrogateEpisode, surrogate_info
from agents.surrogate_swimmer import SurrogateSwimmer, TurnMapTable
from agents.surrogate_turn_env import surrogate_setup
from agents.turn_decision_env import DEFAULT_RANDOM_PATH, TurnEpisodes, fixed_paths, refuse_unknown_arguments
from agents.turn_planner import PlannerConfig, wobble_period_steps
from flagellum_env.config import DEFAULT_REACH_RADIUS_M, draw_randomization
from flagellum_env.tracking import PathTracker
from physics.presets import DEFAULT_PRESET

class SurrogateBurstEnv(TurnEpisodes, gym.Env):
    """
    ## Description

    Follow waypoints by bursts, with no planner (``agents.burst_design``'s docstring is the manual of the action
    and the observation), on the turn-level surrogate swimmer: ~10^4 decisions per CPU second.

    ## Spaces

    Observation ``Box(-10, 10, (N_BURST_FEATURES,), float32)``, 43 values (``burst_observation``; the layout in
    ``agents.burst_design``'s docstring: the targets and segment in the heading's frame, the time left and the last
    four bursts' length, turn seen and the turn's direction relative to the commanded beta); action
    ``Box(-1, 1, (4,), float32)``: burst length, the burst phase's direction (2), cruise time
    (``decode_burst_action``). An action that is not four finite numbers raises ``ValueError``; entries outside
    [-1, 1] are clipped.

    ## Rewards, episode end, ``info``

    ``FlagellumSteer-v0``'s reward terms over the legs flown (weights from ``env_kwargs["reward"]``, default
    ``{"cross_track_per_cm_s": 0.05}``). An episode ends at the last waypoint (``info["is_success"]``), off the
    path, or at the time budget (truncated). ``info``: ``FlagellumTurn-v0``'s keys (``turns`` counts the bursts
    flown) plus ``out_of_range`` (and ``out_of_range_reason``: a burst read beyond the map's burst lengths).

    ## Arguments

    ``preset`` (only "faithful", the map replayed), ``turn_map``, ``env_kwargs`` (``FlagellumSteer-v0`` arguments
    as ``FlagellumTurn-surrogate-v0`` takes them; ``randomize`` up to 15 %), ``paths`` (fixed paths in turn) or
    ``random_path`` (``RandomPathConfig`` fields; default 3 waypoints, 12-20 cm segments, planar and 3-D),
    ``limits`` (``BurstLimits`` or a dict of its fields), ``render_mode`` (None only), ``map_noise`` (this env
    only; ``FlagellumBurst-v0`` refuses it): None (the default) flies the map as measured; a dict
    ``{"direction_deg": D, "turn_scale": S}`` (0 <= D <= 180, 0 <= S < 1) randomises the map itself per episode:
    at each reset, after everything else it draws (so a seed's path and swimmer are those drawn without it), a
    direction bias b ~ U(-D, D) deg and a turn-size factor s ~ U(1 - S, 1 + S) from the env's ``np_random``, and
    every burst of the episode turns towards psi + b (the displacement's lateral part rotated by b about the
    heading) by s x theta (clipped to [0, pi]; the displacement otherwise the map's); the draws are the attributes
    ``map_bias_rad`` and ``map_turn_scale`` (0 and 1 when off), not ``info`` keys. Outside the calibrated range:
    ``ValueError`` naming the value and what is allowed.

    ## Version History

    - v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}
    env_id: ClassVar[str] = BURST_SURROGATE_ENV_ID

    def __init__(self, preset: str | None = None, turn_map: str | os.PathLike | None = None,
                 env_kwargs: Mapping[str, Any] | None = None, paths: Sequence[Any] | None = None,
                 random_path: Mapping[str, Any] | None = None, limits: BurstLimits | Mapping[str, Any] | None = None,
                 render_mode: str | None = None, map_noise: Mapping[str, Any] | None = None, **unknown: Any) -> None:
        refuse_unknown_arguments(self.env_id, unknown, SURROGATE_BURST_ENV_ARGUMENTS)
        self.map_noise = parse_map_noise(map_noise)
        self.map_bias_rad, self.map_turn_scale = 0.0, 1.0
        self.render_mode = None
        self.preset, self.config, self.turn_map, self.calibration = surrogate_setup(
            self.env_id, DEFAULT_PRESET if preset is None else preset, turn_map, env_kwargs, render_mode,
            CONTROLLER_ENV_DEFAULTS["rule"])
        self.table = TurnMapTable(self.turn_map)
        self.limits = burst_limits(limits)
        self.paths = fixed_paths(paths)
        self.set_random_path(DEFAULT_RANDOM_PATH if random_path is None else random_path)
        self.observation_space = spaces.Box(-10.0, 10.0, (N_BURST_FEATURES,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (N_BURST_ACTIONS,), np.float32)
        dt = self.config.control_dt
        self.period_steps = wobble_period_steps(self.turn_map.period_s, dt)
        self.relax_wait_s = (2 * self.period_steps * dt, PlannerConfig().max_relax_factor * self.turn_map.relax_s)
        self._episode = 0
        self._swimmer_rng: np.random.Generator | None = None
        self._warned = False
        self._done = True

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        path = self._episode_path(seed, options)
        if seed is not None or self._swimmer_rng is None:
            # the physics env's own generator, seeded alike: the same seed draws the same swimmer there and here
            self._swimmer_rng, _ = seeding.np_random(seed)
        cfg = self.config
        params, _ = draw_randomization(self.turn_map.params, cfg.randomize, self._swimmer_rng)
        self.swimmer = SurrogateSwimmer(self.turn_map, self.calibration, self.table, params)
        if self.map_noise is not None:
            # drawn after the path (np_random) and the swimmer (its own generator): a seed's episode is the same
            # but for the map
            d_deg, spread = self.map_noise
            self.map_bias_rad = math.radians(float(self.np_random.uniform(-d_deg, d_deg)))
            self.map_turn_scale = float(self.np_random.uniform(1.0 - spread, 1.0 + spread))
            self.swimmer.direction_bias_rad, self.swimmer.turn_scale = self.map_bias_rad, self.map_turn_scale
        self.episode_params, self.path = params, path
        self.tracker = PathTracker(path, cfg.reach_radius_m or path.reach_radius_m or DEFAULT_REACH_RADIUS_M)
        max_time = (cfg.max_sim_time_s if cfg.max_sim_time_s is not None
                    else cfg.time_factor * path.length_m / self.calibration.cruise_speed_m_s)
        self.time_limit_s = max(1, math.ceil(max_time / cfg.control_dt - 1e-9)) * cfg.control_dt
        self.episode = SurrogateEpisode(self.swimmer, self.tracker, cfg, self.time_limit_s)
        self.bursts, self.history = 0, BurstHistory()
        # a heading is measured after one period at omega_l, as the physics twin measures it
        end = self.episode.cruise((self.period_steps + 1) * cfg.control_dt)
        self._pending = (self.episode.reward(), end)
        self._decision_heading = self.episode.heading.copy()
        self._done = False
        return self._observation(), self._info()

    def step(self, action: Any):
        if self._done:
            raise RuntimeError("call reset() before step()")
        command = decode_burst_action(action, self.limits, self.config.control_dt)
        reward, end = self._pending
        self._pending = (0.0, None)
        run = self.episode
        if end is None and command.t_c_s > 0.0:
            end = run.hover_to_phase(command.beta_rad)
            if end is None:
                self.bursts += 1
                end = run.burst(command.t_c_s, command.beta_rad, *self.relax_wait_s, command.burst_end)
                if run.out_of_range is not None and not self._warned:
                    self._warned = True
                    gym.logger.warn(f"{self.env_id}: {run.out_of_range}; reported in info['out_of_range']")
        if end is None:
            end = run.cruise(command.cruise_s)
        reward += run.reward()
        if command.t_c_s > 0.0:
            self.history.record(command.t_c_s / self.limits.t_c_max_s,
                                *turn_seen(self._decision_heading, run.heading), command.beta_rad)
        self._decision_heading = run.heading.copy()
        terminated, truncated = end if end is not None else (False, False)
        self._done = terminated or truncated
        return self._observation(), float(reward), bool(terminated), bool(truncated), self._info()

    def _observation(self) -> np.ndarray:
        run = self.episode
        return burst_observation(run.head, run.heading, self.tracker.targets(2), self.tracker.segment(),
                                 max(0.0, 1.0 - run.time_s / self.time_limit_s), self.history)

    def _info(self) -> dict[str, Any]:
        return surrogate_info(self.path.name, self.tracker, self.episode, self.bursts)
