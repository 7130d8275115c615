"""One episode of the turn-level surrogate swimmer: the head's legs, the bookkeeping of the physics env, a burst.

Shared by the surrogate envs (``agents.surrogate_turn_env``, the planner's loop; ``agents.surrogate_burst_env``,
an agent's burst commands). The swimmer (``agents.surrogate_swimmer.SurrogateSwimmer``) says what a burst does;
this object moves the head along straight legs (``agents.surrogate_legs.fly_state``: cruise, hover, the chord of a
turn) and keeps what ``FlagellumSteer-v0`` keeps: the time, the motor energy, int e dt of the cross-track error,
the waypoints, leaving the path, the time budget, and the reward of the legs flown since it was last asked
(``flagellum_env.rewards.reward_terms``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from agents.surrogate_calibration import burst_energy_at
from agents.surrogate_legs import (ACC_CROSS, ACC_ENERGY, ACC_REACHED, CROSS, CRUISE_POWER, DT, ENERGY, GOES_ON,
                                   HEADING, LEG_SIZE, MU_RATIO, OFF_PATH, OFF_PATH_M, PERIOD, REACH, SPEED,
                                   STATE_SIZE, TAU_RATIO, TERMINATED, TIME, TIME_FACTOR, TIME_LIMIT, SegmentFrames,
                                   fly_state)
from agents.surrogate_swimmer import SurrogateSwimmer, turn_outcome
from flagellum_env.config import SteerConfig
from flagellum_env.rewards import reward_values
from flagellum_env.tracking import PathTracker, path_progress


class SurrogateEpisode:
    """The state of one surrogate episode. ``head`` (3,) m, ``heading`` (3,) unit, ``time_s``, ``energy_j`` (J),
    ``cross_integral`` (m s), ``buckling_events``; ``out_of_range`` names the first burst read beyond the map's
    burst lengths (None while every burst was within them). ``state`` holds them for the compiled legs
    (``agents.surrogate_legs.STATE_SIZE``), ``consts`` the legs' constants (``LEG_SIZE``), ``frames`` the path's
    (``SegmentFrames``)."""

    def __init__(self, swimmer: SurrogateSwimmer, tracker: PathTracker, config: SteerConfig,
                 time_limit_s: float) -> None:
        self.swimmer, self.tracker, self.config = swimmer, tracker, config
        self.frames = SegmentFrames(tracker)
        self.time_limit_s = time_limit_s
        self.state = np.zeros(STATE_SIZE)
        self.state[HEADING] = 1.0
        self.consts = np.empty(LEG_SIZE)
        self.consts[[REACH, TIME_LIMIT, OFF_PATH_M, SPEED, CRUISE_POWER, DT, PERIOD, TAU_RATIO, TIME_FACTOR,
                     MU_RATIO]] = (tracker.reach_radius_m, time_limit_s, config.off_path_m, swimmer.speed_m_s,
                                   swimmer.cruise_power_w, config.control_dt, swimmer.period_s, swimmer.tau_ratio,
                                   swimmer.time_factor, swimmer.mu_ratio)
        #: the calibration's burst lengths (s) and cumulative burst energies (J), (2, K) (``burst_energy_at``)
        self.burst_energies = swimmer.calibration.burst_table
        w = config.reward
        #: ``RewardConfig``'s weights in ``reward_values``' order
        self._weights = np.array([w.progress_per_cm, w.cross_track_per_cm_s, w.energy_per_mj, w.waypoint_bonus,
                                  w.off_path_penalty, w.error_penalty])
        self.buckling_events = 0
        self.out_of_range: str | None = None
        self._progress = 0.0

    @property
    def head(self) -> np.ndarray:
        """The head, (3,) m (a copy)."""
        return self.state[0:3].copy()

    @property
    def heading(self) -> np.ndarray:
        """The unit heading, (3,) (a copy)."""
        return self.state[HEADING:HEADING + 3].copy()

    @property
    def time_s(self) -> float:
        """The episode's time, s."""
        return float(self.state[TIME])

    @property
    def energy_j(self) -> float:
        """The motor energy so far, J."""
        return float(self.state[ENERGY])

    @property
    def cross_integral(self) -> float:
        """int e dt of the cross-track error so far, m s."""
        return float(self.state[CROSS])

    # --- legs ------------------------------------------------------------------------------------
    def collect(self, reached: int, how: int) -> tuple[bool, bool] | None:
        """Count the ``reached`` waypoints of the legs just flown (``fly_state``: they wait for ``reward``) and turn
        how they ended (``GOES_ON``, ``TERMINATED``, ``TRUNCATED``) into None or (terminated, truncated)."""
        if reached:
            self.tracker.mark_reached(reached)
        if how == GOES_ON:
            return None
        return (True, False) if how == TERMINATED else (False, True)

    def cruise(self, duration: float, stop_at_waypoint: bool = True) -> tuple[bool, bool] | None:
        """Swim straight at omega_l for ``duration`` s (stopping at a waypoint if asked); the episode's end or None."""
        return self.collect(*cruise_state(self.state, duration, stop_at_waypoint, self.tracker.index,
                                          self.frames.table, self.consts))

    def reward(self) -> float:
        """The reward of the legs flown since the last call (``reward_state``): ``reward_terms``
        (``flagellum_env.rewards``) of the progress made, int e dt (passed as e x tau with tau = 1 s), the motor
        energy, the waypoints reached and the off-path penalty."""
        tr = self.tracker
        reward, self._progress = reward_state(self.state, tr.index, tr.path.vertices, tr.path.segment_lengths,
                                              tr.cumulative_m, self._progress, self._weights)
        return reward

    # --- a burst ----------------------------------------------------------------------------------
    def hover_to_phase(self, beta: float) -> tuple[bool, bool] | None:
        """Cruise (whole control steps, at least one) until the phase node's azimuth about the heading, which turns
        once per map period from phase 0 at t = 0, reaches ``beta`` (rad); the episode's end or None."""
        return self.collect(*hover_state(self.state, beta, self.tracker.index, self.frames.table, self.consts))

    def burst(self, t_c: float, beta: float, min_wait_s: float, max_wait_s: float, burst_end: str = "time"
              ) -> tuple[bool, bool] | None:
        """A burst of ``t_c`` s (whole control steps; ended by ``burst_end``, ``SurrogateSwimmer.burst_times``, its
        flight time rounded to whole control steps) started at azimuth ``beta`` (rad), then the relaxation at
        omega_l, waiting the map's relaxation time for this swimmer clamped to [``min_wait_s``, ``max_wait_s``]
        (whole control steps): the head moves along the chord of the map's displacement (plus any cruise past the
        relaxation) and the heading jumps to the new one at the end (``burst_state``). Returns the episode's end or
        None."""
        sw = self.swimmer
        flight, t_map = sw.burst_times(t_c, burst_end)
        dt = self.config.control_dt
        flown = max(1, round(flight / dt)) * dt if burst_end != "time" else t_c
        tab = sw.table
        reached, how, end_ratio, in_range = burst_state(
            self.state, t_map, flown, beta, min_wait_s, max_wait_s, sw.burst_energy_j(t_c, burst_end),
            sw.direction_bias_rad, sw.turn_scale, self.tracker.index, self.frames.table, self.consts, tab.t_c,
            tab.phases, tab.channels)
        self._burst_seen(t_c, t_map, end_ratio, in_range)
        return self.collect(reached, how)

    def turn(self, t_c: float, beta: float, min_wait_s: float, max_wait_s: float) -> tuple[bool, bool] | None:
        """``hover_to_phase(beta)`` then, unless the episode ended, ``burst(t_c, beta, min_wait_s, max_wait_s)`` (a
        burst ended by time) in one compiled call (``turn_state``); the episode's end or None."""
        sw = self.swimmer
        tab = sw.table
        reached, how, end_ratio, in_range = turn_state(
            self.state, t_c, beta, min_wait_s, max_wait_s, sw.direction_bias_rad, sw.turn_scale, self.tracker.index,
            self.frames.table, self.consts, tab.t_c, tab.phases, tab.channels, self.burst_energies)
        if not math.isnan(end_ratio):
            self._burst_seen(t_c, sw.map_time(t_c), end_ratio, in_range)
        return self.collect(reached, how)

    def _burst_seen(self, t_c: float, t_map: float, end_ratio: float, in_range: bool) -> None:
        """Count a buckling (L'/L at the burst's end below the threshold) and name the first burst out of range."""
        if not in_range and self.out_of_range is None:
            t_max = self.swimmer.table.t_c[-1]
            self.out_of_range = (f"burst of {t_c:.3g} s reads the map at t_c = {float(t_map):.4g} s, beyond its "
                                 f"calibrated burst lengths [0, {t_max:g}] s (the longest used)")
        if end_ratio < self.config.buckling_threshold:
            self.buckling_events += 1


@njit(cache=True)
def reward_state(state: np.ndarray, index: int, vertices: np.ndarray, lengths: np.ndarray, cumulative: np.ndarray,
                 last_progress: float, weights: np.ndarray) -> tuple[float, float]:
    """``SurrogateEpisode.reward`` on ``state``: (the reward, the progress m now), the sum of ``reward_values`` (in
    ``TERMS``' order; ``weights`` (6,) ``RewardConfig``'s in its order) of the progress since ``last_progress`` m
    (``path_progress`` with the target ``index`` and the path's ``vertices``, ``lengths``, ``cumulative``), the
    int e dt, motor energy, waypoints and leaving the path since the last reward (then cleared)."""
    progress = path_progress(state[0:3], index, vertices, lengths, cumulative)
    p, c, e, w, pen = reward_values(weights[0], weights[1], weights[2], weights[3], weights[4], weights[5],
                                    progress - last_progress, state[ACC_CROSS], 1.0, state[ACC_ENERGY],
                                    int(state[ACC_REACHED]), state[OFF_PATH] != 0.0, False)
    state[ACC_ENERGY], state[ACC_CROSS], state[ACC_REACHED] = 0.0, 0.0, 0.0
    return (((p + c) + e) + w) + pen, progress


@njit(cache=True)
def cruise_state(state: np.ndarray, duration: float, stop_at_waypoint: bool, index: int, table: np.ndarray,
                 consts: np.ndarray) -> tuple[int, int]:
    """Swim straight along the heading of ``state`` at the cruise speed for ``duration`` s (``fly_state``'s
    arguments and answer)."""
    step = consts[SPEED] * duration
    return fly_state(state, state[0] + step * state[HEADING], state[1] + step * state[HEADING + 1],
                     state[2] + step * state[HEADING + 2], duration, consts[CRUISE_POWER], 0.0, False,
                     stop_at_waypoint, index, table, consts)


@njit(cache=True)
def hover_state(state: np.ndarray, beta: float, index: int, table: np.ndarray, consts: np.ndarray
                ) -> tuple[int, int]:
    """``SurrogateEpisode.hover_to_phase`` on ``state``: cruise whole control steps, at least one, until the phase
    (turning once per map period from 0 at t = 0) reaches ``beta`` (rad) (``fly_state``'s arguments and answer)."""
    dt = consts[DT]
    omega_phase = 2.0 * math.pi / consts[PERIOD]
    togo = (beta - omega_phase * state[TIME]) % (2.0 * math.pi)
    return cruise_state(state, max(1, math.ceil(togo / omega_phase / dt - 1e-9)) * dt, False, index, table, consts)


@njit(cache=True)
def burst_state(state: np.ndarray, t_map: float, flown: float, beta: float, min_wait_s: float, max_wait_s: float,
                burst_energy_j: float, direction_bias: float, turn_scale: float, index: int, table: np.ndarray,
                consts: np.ndarray, t: np.ndarray, ph: np.ndarray, channels: np.ndarray
                ) -> tuple[int, int, float, bool]:
    """``SurrogateEpisode.burst`` on ``state``: the map (``turn_outcome``'s ``t``, ``ph``, ``channels``,
    ``direction_bias``, ``turn_scale``) read at the map time ``t_map`` (s) and azimuth ``beta`` (rad), a burst
    flown for ``flown`` s of ``burst_energy_j`` (J) and the wait clamped to [``min_wait_s``, ``max_wait_s``] (whole
    control steps) at the cruise power. Returns (the waypoints reached, how the leg ended, L'/L at the burst's end,
    within the map's burst lengths)."""
    dt = consts[DT]
    h0, h1, h2, x0, x1, x2, _, _, relax, ratio, in_range = turn_outcome(
        t, ph, channels, t_map, beta, state[HEADING:HEADING + 3], direction_bias, turn_scale)
    relax_s = relax * consts[TAU_RATIO]
    wait = min_wait_s if min_wait_s > relax_s else relax_s   # min(max(relax_s, min_wait_s), max_wait_s)
    if max_wait_s < wait:
        wait = max_wait_s
    wait = max(1, math.ceil(wait / dt - 1e-9)) * dt
    # the map's displacement covers the burst and its relaxation; the wait differs by a cruise
    s = consts[SPEED] * (wait - relax_s)
    reached, how = fly_state(state, (state[0] + x0) + s * h0, (state[1] + x1) + s * h1, (state[2] + x2) + s * h2,
                             flown + wait, 0.0, burst_energy_j + consts[CRUISE_POWER] * wait, True, False, index,
                             table, consts)
    state[HEADING], state[HEADING + 1], state[HEADING + 2] = h0, h1, h2
    return reached, how, ratio, in_range


@njit(cache=True)
def turn_state(state: np.ndarray, t_c: float, beta: float, min_wait_s: float, max_wait_s: float,
               direction_bias: float, turn_scale: float, index: int, table: np.ndarray, consts: np.ndarray,
               t: np.ndarray, ph: np.ndarray, channels: np.ndarray, energies: np.ndarray) -> tuple[int, int, float, bool]:
    """``hover_state`` then, if the episode goes on, ``burst_state`` of a burst of ``t_c`` s ended by time: read at
    the map time t_c x ``TIME_FACTOR``, its energy the calibration's (``energies`` (2, K): burst lengths s, cumulative
    energies J; ``burst_energy_at``) x ``MU_RATIO`` (``SurrogateSwimmer.burst_energy_j``); the other arguments
    theirs. Returns (the waypoints reached by both, how the last leg ended, L'/L at the burst's end or NaN without a
    burst, within the burst lengths)."""
    reached, how = hover_state(state, beta, index, table, consts)
    if how != GOES_ON:
        return reached, how, math.nan, True
    t_map = t_c * consts[TIME_FACTOR]
    energy = burst_energy_at(t_map, energies[0], energies[1]) * consts[MU_RATIO]
    more, how, ratio, in_range = burst_state(state, t_map, t_c, beta, min_wait_s, max_wait_s, energy, direction_bias,
                                             turn_scale, index + reached, table, consts, t, ph, channels)
    return reached + more, how, ratio, in_range


def surrogate_info(path_name: str, tracker: PathTracker, run: SurrogateEpisode, turns: int) -> dict:
    """The ``info`` of a surrogate env (``FlagellumTurn-v0``'s keys, ``INFO_KEYS``, plus ``out_of_range`` and, when
    it is True, ``out_of_range_reason``)."""
    info = {"path": path_name, "is_success": bool(tracker.done), "waypoints_reached": int(tracker.index),
            "mean_cross_track_m": run.cross_integral / run.time_s if run.time_s > 0.0 else 0.0,
            "time_s": float(run.time_s), "energy_J": float(run.energy_j),
            "buckling_events": int(run.buckling_events), "turns": turns,
            "out_of_range": run.out_of_range is not None}
    if run.out_of_range is not None:
        info["out_of_range_reason"] = run.out_of_range
    return info
