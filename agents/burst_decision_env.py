"""``FlagellumBurst-v0``: the burst action design (``agents.burst_design``) on the rod, ``FlagellumSteer-v0``.

The physics twin of ``FlagellumBurst-surrogate-v0`` (``agents.surrogate_burst_env``): the same action decoding,
observation, reward terms, episode ends and ``info`` keys, but each burst command is flown by the rod at 0.1 s
control steps, measured and timed as the rule planner (``agents.turn_planner``) measures and times its turns
(``agents.burst_flight``, which the ``ppo-scratch`` controller flies too).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.burst_design import (BURST_ENV_ARGUMENTS, N_BURST_ACTIONS, N_BURST_FEATURES, BurstHistory, BurstLimits,
                                 burst_limits, burst_observation, decode_burst_action, turn_seen)
from agents.burst_flight import BurstFlight
from agents.controller_spec import CONTROLLER_ENV_DEFAULTS
from agents.registration import BURST_ENV_ID
from agents.turn_decision_env import (DEFAULT_RANDOM_PATH, TurnEpisodes, decision_info, fixed_paths,
                                      refuse_unknown_arguments, steer_base_env)
from agents.turn_planner import RulePlanner
from physics.presets import DEFAULT_PRESET


class BurstDecisionEnv(TurnEpisodes, gym.Env):
    """
    ## Description

    Follow waypoints by bursts, with no planner (``agents.burst_design``'s docstring is the manual of the action
    and the observation), on the rod: the twin of ``FlagellumBurst-surrogate-v0`` (same spaces, rewards, episode
    ends and ``info`` keys), a decision costing 0.05-4 CPU s at ``faithful`` (mean 1.2-1.4 s over random actions,
    scripts/compare_burst_twins.py) instead of ~0.1 ms. One step drives ``FlagellumSteer-v0``
    (``FlagellumSteerEnv``, continuous motor speed) through control steps of ``control_dt`` (0.1 s):

    1. hover at omega_l until the phase node's azimuth about the heading reaches the command's beta, as the rule
       planner hovers (``agents.turn_planner.hover_check``: a hover whose phase swings instead of turning measures
       the heading again, up to ``RulePlanner.HOVER_RESTARTS`` times; after ``RulePlanner.HOVER_LIMIT_PERIODS``
       map periods it bursts at the phase it has); then burst at omega_h for t_c; then relax at omega_l until
       ``relax_over`` (>= 2 wobble periods and the heading steady, at most ``max_relax_factor`` x the map's
       relaxation time). Skipped when t_c = 0;
    2. cruise at omega_l for the command's cruise time, ending at the first control step that reaches a waypoint.

    The heading is the head's displacement over the last wobble period (``period_heading``; the map's
    ``period_s``), the head the base env's ``info["head_position_m"]``, both in the episode's start frame (m);
    the phase node is read from the observation (``ObservationLayout.read``).

    ## Spaces

    Observation ``Box(-10, 10, (N_BURST_FEATURES,), float32)``, 43 values (``burst_observation``: the next two waypoints and
    the current segment in the heading's frame, in units of 0.1 m; the time left; the last four bursts' t_c / t_c_max,
    the turn seen over each one's decision / pi and that turn's direction relative to the command's beta as
    (cos, sin), weighted by min(1, turn / 10 deg); ``agents.burst_design``'s layout). Action
    ``Box(-1, 1, (4,), float32)``: burst length, the burst phase's direction (2), cruise time
    (``decode_burst_action``: t_c <= ``t_c_max_s`` s,
    beta = atan2(a_2, a_1) rad, cruise ``cruise_min_s`` to ``cruise_max_s`` s, whole control steps). An action that
    is not four finite numbers raises ``ValueError``; entries outside [-1, 1] are clipped.

    ## Rewards

    The sum of ``FlagellumSteer-v0``'s rewards over the control steps a decision covered (progress, cross-track
    error, energy, waypoints, penalties; weights from ``env_kwargs["reward"]``, default
    ``{"cross_track_per_cm_s": 0.05}``). ``reset`` cruises one wobble period and a control step at omega_l to
    measure a heading (never stopping at a waypoint); that cruise's reward is paid with the first step.

    ## Episode End

    The base env's: the last waypoint reached (``info["is_success"]``), off the path, a simulation error
    (``info["error"]``) or its time budget (truncated). An episode that ended during ``reset``'s cruise ends at the
    first step, whatever the action.

    ## Info

    ``path``, ``is_success``, ``waypoints_reached``, ``mean_cross_track_m`` (over the control steps so far, m),
    ``time_s`` (s), ``energy_J`` (J), ``buckling_events``, ``turns`` (bursts flown) and ``out_of_range``, always
    False (the surrogate's flag for a burst read beyond its map; the rod has no such range); ``error`` after a
    simulation error.

    ## Arguments

    ``preset`` (default "faithful"; any physics preset, its turn map by default), ``turn_map`` (a turn-map file:
    omega_l, omega_h, the phase node, the wobble period and the relaxation time), ``env_kwargs`` (further
    ``FlagellumSteer-v0`` arguments over ``control_dt`` 0.1 s and ``{"reward": {"cross_track_per_cm_s": 0.05}}``,
    as ``FlagellumTurn-v0`` takes them; a dict given replaces the reward default; ``randomize`` draws the swimmer
    from the base env's generator, so a seed draws the same swimmer as ``FlagellumBurst-surrogate-v0`` with that
    seed; later unseeded resets differ from the surrogate's when observation noise is on, as the noise draws from
    the same generator), ``paths`` (fixed paths in turn) or ``random_path`` (``RandomPathConfig`` fields; default
    3 waypoints, 12-20 cm segments, planar and 3-D), ``limits`` (``BurstLimits`` or a dict of its fields),
    ``render_mode`` (None or "rgb_array": the base env's frame). A bad value raises a one-line ``ValueError`` naming
    it and what is allowed; ``reset(options={"path": ...})`` replaces the path for one episode.

    ## Version History

    - v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 2}
    env_id: ClassVar[str] = BURST_ENV_ID

    def __init__(self, preset: str | None = None, turn_map: str | os.PathLike | None = None,
                 env_kwargs: Mapping[str, Any] | None = None, paths: Sequence[Any] | None = None,
                 random_path: Mapping[str, Any] | None = None, limits: BurstLimits | Mapping[str, Any] | None = None,
                 render_mode: str | None = None, **unknown: Any) -> None:
        refuse_unknown_arguments(self.env_id, unknown, BURST_ENV_ARGUMENTS)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not allowed; choose one of "
                             f"{[None] + self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.preset = DEFAULT_PRESET if preset is None else preset
        self.base, self.turn_map = steer_base_env(self.preset, turn_map, env_kwargs, render_mode,
                                                  CONTROLLER_ENV_DEFAULTS["rule"])
        # the rule planner as an instrument (never asked to plan): it checks the map against the env and holds
        # the speed -> action map; the flight measures and times as it does
        instrument = RulePlanner.for_env(self.base, self.turn_map)
        self.action_of, self.flight = instrument.action_of, BurstFlight.for_planner(instrument)
        self.control_dt = float(self.base.config.control_dt)
        self.limits = burst_limits(limits)
        self.paths = fixed_paths(paths)
        self.set_random_path(DEFAULT_RANDOM_PATH if random_path is None else random_path)
        self.observation_space = spaces.Box(-10.0, 10.0, (N_BURST_FEATURES,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (N_BURST_ACTIONS,), np.float32)
        self._episode = 0
        self._done = True

    # --- Gymnasium API -----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        path = self._episode_path(seed, options)
        self._path_name = path.name
        obs, info = self.base.reset(seed=seed, options={"path": path})  # the seed draws the swimmer there
        self.episode_params = self.base.episode_params
        self._base_info = info
        self.flight.start(info["head_position_m"], obs, self.base.tracker.index, info["sim_time_s"])
        self._cross: list[float] = []
        self._reward, self._end = 0.0, None
        self.history = BurstHistory()
        # a heading measured over one period
        self._drive(self.flight.cruise(self.flight.period_steps + 1, stop_at_waypoint=False))
        self._decision_heading = self.heading
        self._done = False
        return self._observation(), self._info()

    def step(self, action: Any):
        if self._done:
            raise RuntimeError("call reset() before step()")
        command = decode_burst_action(action, self.limits, self.control_dt)
        if self._end is None:
            self._drive(self.flight.fly(command))
        reward, self._reward = self._reward, 0.0
        heading = self.heading
        if command.t_c_s > 0.0:
            self.history.record(command.t_c_s / self.limits.t_c_max_s, *turn_seen(self._decision_heading, heading),
                                command.beta_rad)
        self._decision_heading = heading
        terminated, truncated = self._end if self._end is not None else (False, False)
        self._done = terminated or truncated
        return self._observation(), float(reward), terminated, truncated, self._info()

    def render(self):
        """The base env's frame (``render_mode="rgb_array"``): the path, the trail and the swimmer now."""
        if self.render_mode is None:
            gym.logger.warn("render() was called without a render_mode; pass render_mode='rgb_array'")
            return None
        return self.base.render()

    def close(self) -> None:
        self.base.close()

    # --- the state the observation is made of ------------------------------------------------------
    @property
    def head(self) -> np.ndarray:
        """The head's position now, (3,) m, start frame."""
        return self.flight.head

    @property
    def heading(self) -> np.ndarray:
        """The heading now, (3,) unit (``BurstFlight.heading``)."""
        return self.flight.heading

    @property
    def time_s(self) -> float:
        """Simulated time since the episode started, s."""
        return self.flight.time_s

    @property
    def bursts(self) -> int:
        """Bursts flown in this episode."""
        return self.flight.bursts

    @property
    def last_burst(self) -> dict[str, Any] | None:
        """What the last burst's hover did (``BurstFlight.last_burst``); None before any burst."""
        return self.flight.last_burst

    # --- flying a command -------------------------------------------------------------------------
    def _drive(self, speeds: Iterator[float]) -> None:
        """Step the base env at each motor speed (rpm) the flight yields, until it is done or the episode ends;
        the rewards are added up."""
        for rpm in speeds:
            obs, reward, terminated, truncated, info = self.base.step(self.action_of(rpm))
            self._base_info = info
            self._reward += reward
            self._cross.append(info["cross_track_error_m"])
            self.flight.observe(info["head_position_m"], obs, self.base.tracker.index, info["sim_time_s"])
            if terminated or truncated:
                self._end = (bool(terminated), bool(truncated))
                return

    # --- observation and info ---------------------------------------------------------------------
    def _observation(self) -> np.ndarray:
        time_limit_s = self.base.max_steps * self.control_dt
        tracker = self.base.tracker
        return burst_observation(self.head, self.heading, tracker.targets(2), tracker.segment(),
                                 max(0.0, 1.0 - self.time_s / time_limit_s), self.history)

    def _info(self) -> dict[str, Any]:
        return {**decision_info(self._path_name, self._base_info, self._cross, self.bursts), "out_of_range": False}
