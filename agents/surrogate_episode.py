"""One episode of the turn-level surrogate swimmer: the head's legs, the bookkeeping of the physics env, a burst.

Shared by the surrogate envs (``agents.surrogate_turn_env``, the planner's loop; ``agents.surrogate_burst_env``,
an agent's burst commands). The swimmer (``agents.surrogate_swimmer.SurrogateSwimmer``) says what a burst does;
this object moves the head along straight legs (``agents.surrogate_legs.fly_leg``: cruise, hover, the chord of a
turn) and keeps what ``FlagellumSteer-v0`` keeps: the time, the motor energy, int e dt of the cross-track error,
the waypoints, leaving the path, the time budget, and the reward of the legs flown since it was last asked
(``flagellum_env.rewards.reward_terms``).
"""

from __future__ import annotations

import math

import numpy as np

from agents.surrogate_legs import LegResult, SegmentFrames, fly_leg
from agents.surrogate_swimmer import SurrogateSwimmer, SurrogateTurn
from flagellum_env.config import SteerConfig
from flagellum_env.rewards import TERMS, reward_terms
from flagellum_env.tracking import PathTracker


class SurrogateEpisode:
    """The state of one surrogate episode. ``head`` (3,) m, ``heading`` (3,) unit, ``time_s``, ``energy_j`` (J),
    ``cross_integral`` (m s), ``buckling_events``; ``out_of_range`` names the first burst read beyond the map's
    burst lengths (None while every burst was within them)."""

    def __init__(self, swimmer: SurrogateSwimmer, tracker: PathTracker, config: SteerConfig,
                 time_limit_s: float) -> None:
        self.swimmer, self.tracker, self.config = swimmer, tracker, config
        self.frames = SegmentFrames(tracker)
        self.time_limit_s = time_limit_s
        self.head, self.heading = np.zeros(3), np.array([1.0, 0.0, 0.0])
        self.time_s, self.energy_j, self.cross_integral, self.buckling_events = 0.0, 0.0, 0.0, 0
        self.out_of_range: str | None = None
        self._progress = 0.0
        self._acc_energy, self._acc_cross, self._acc_reached, self._off_path = 0.0, 0.0, 0, False

    # --- legs ------------------------------------------------------------------------------------
    def fly(self, end_point: np.ndarray, duration: float, stop_at_waypoint: bool, power_w: float = 0.0,
            energy_j: float | None = None) -> LegResult:
        """The leg from the head to ``end_point`` (3,) m over ``duration`` s (not applied: see ``collect``);
        its energy is ``energy_j`` (J, prorated if the leg stops early) or ``power_w`` (W) x its duration."""
        leg = fly_leg(self.tracker, self.frames, self.head, end_point, duration, self.time_s, self.time_limit_s,
                      self.config.off_path_m, stop_at_waypoint)
        frac = leg.duration_s / duration if duration > 0.0 else 1.0
        leg.energy_j = (energy_j * frac) if energy_j is not None else power_w * leg.duration_s
        return leg

    def collect(self, leg: LegResult) -> tuple[bool, bool] | None:
        """Apply a flown leg (its energy, waypoints and cross-track integral wait for ``reward``); None or
        (terminated, truncated)."""
        self.head = leg.end
        self.time_s += leg.duration_s
        self.energy_j += leg.energy_j
        self.cross_integral += leg.cross_integral
        self._acc_energy += leg.energy_j
        self._acc_cross += leg.cross_integral
        self._acc_reached += leg.reached
        self._off_path = self._off_path or leg.off_path
        if self.tracker.done or leg.off_path:
            return True, False
        if leg.timed_out:
            return False, True
        return None

    def cruise(self, duration: float, stop_at_waypoint: bool = True) -> tuple[bool, bool] | None:
        """Swim straight at omega_l for ``duration`` s (stopping at a waypoint if asked); the episode's end or None."""
        sw = self.swimmer
        step = sw.speed_m_s * duration
        h, d = self.head, self.heading
        end = np.array([h[0] + step * d[0], h[1] + step * d[1], h[2] + step * d[2]])  # head + step d, on floats
        return self.collect(self.fly(end, duration, stop_at_waypoint, power_w=sw.cruise_power_w))

    def reward(self) -> float:
        """The reward of the legs flown since the last call: ``reward_terms`` (``flagellum_env.rewards``) of the
        progress made, int e dt (passed as e x tau with tau = 1 s), the motor energy, the waypoints reached and the
        off-path penalty."""
        progress = self.tracker.progress(self.head)
        terms = reward_terms(self.config.reward, progress - self._progress, self._acc_cross, 1.0, self._acc_energy,
                             self._acc_reached, off_path=self._off_path)
        self._progress = progress
        self._acc_energy, self._acc_cross, self._acc_reached = 0.0, 0.0, 0
        return float(sum([terms[t] for t in TERMS]))

    # --- a burst ----------------------------------------------------------------------------------
    def hover_to_phase(self, beta: float) -> tuple[bool, bool] | None:
        """Cruise (whole control steps, at least one) until the phase node's azimuth about the heading, which turns
        once per map period from phase 0 at t = 0, reaches ``beta`` (rad); the episode's end or None."""
        sw, dt = self.swimmer, self.config.control_dt
        omega_phase = 2.0 * math.pi / sw.period_s
        togo = (beta - omega_phase * self.time_s) % (2.0 * math.pi)
        return self.cruise(max(1, math.ceil(togo / omega_phase / dt - 1e-9)) * dt, stop_at_waypoint=False)

    def burst(self, t_c: float, beta: float, min_wait_s: float, max_wait_s: float, burst_end: str = "time"
              ) -> tuple[SurrogateTurn, tuple[bool, bool] | None]:
        """A burst of ``t_c`` s (whole control steps; ended by ``burst_end``, ``SurrogateSwimmer.burst_times``, its
        flight time rounded to whole control steps) started at azimuth ``beta`` (rad), then the relaxation at
        omega_l, waiting the map's relaxation time for this swimmer clamped to [``min_wait_s``, ``max_wait_s``]
        (whole control steps): the head moves along the chord of the map's displacement (plus any cruise past the
        relaxation) and the heading jumps to the new one at the end. Returns the turn and the episode's end or None."""
        sw, dt = self.swimmer, self.config.control_dt
        out = sw.turn(self.heading, t_c, beta, burst_end)
        flown = max(1, round(sw.burst_times(t_c, burst_end)[0] / dt)) * dt if burst_end != "time" else t_c
        if not out.in_range and self.out_of_range is None:
            t_max = sw.table.t_c[-1]
            self.out_of_range = (f"burst of {t_c:.3g} s reads the map at t_c = {out.map_time_s:.4g} s, beyond its "
                                 f"calibrated burst lengths [0, {t_max:g}] s (the longest used)")
        if out.end_ratio < self.config.buckling_threshold:
            self.buckling_events += 1
        wait = min(max(out.relax_s, min_wait_s), max_wait_s)
        wait = max(1, math.ceil(wait / dt - 1e-9)) * dt
        # the map's displacement covers the burst and its relaxation; the wait differs by a cruise
        end_point = self.head + out.displacement + sw.speed_m_s * (wait - out.relax_s) * out.heading
        energy = sw.burst_energy_j(t_c, burst_end) + sw.cruise_power_w * wait
        end = self.collect(self.fly(end_point, flown + wait, stop_at_waypoint=False, energy_j=energy))
        self.heading = out.heading
        return out, end


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
