"""Flying one burst command on the rod, one control step at a time: the code ``FlagellumBurst-v0`` and the
``ppo-scratch`` controller share.

A ``BurstFlight`` measures what the rule planner measures (``agents.turn_planner``): the heading over the last wobble
period (``period_heading``), the phase node's azimuth about it (``ObservationLayout.read``), and it flies a
``BurstCommand`` (``agents.burst_design``) as the planner flies a turn:

1. hover at omega_l until the phase node's azimuth about the heading reaches the command's beta, with the planner's
   guards (``hover_check``: a hover whose phase swings instead of turning measures the heading again, up to
   ``RulePlanner.HOVER_RESTARTS`` times; after ``RulePlanner.HOVER_LIMIT_PERIODS`` map periods it bursts at the phase
   it has); then t_c at omega_h; then omega_l until ``relax_over`` (>= 2 wobble periods and the heading steady, at
   most ``max_relax_factor`` x the map's relaxation time). Skipped when t_c = 0;
2. cruise at omega_l for the command's cruise time, ending at the first control step that reaches a waypoint.

A command with ``burst_end`` "ratio" ends its burst by the ratio clock of the adaptive planner
(``agents.online_turn_map``, ``OnlineMapConfig``'s "Flying by L'/L"): the map records L'/L at each burst's end, and
on its rising branch L'/L falls steadily once the flagellum buckles, so the L'/L the map's swimmer shows after t_c
is a clock that runs with the swimmer's own buckling. The burst ends at the control step nearest to where the
observed L'/L reaches the map's L'/L for t_c (``RatioClock``), so that a swimmer that buckles earlier
or later than the map's turns about as the map says for t_c; at most ``RATIO_BURST_FACTOR`` x t_c +
``RATIO_BURST_MARGIN_S`` (a swimmer that buckles much later), and by time when t_c is too short for the map's L'/L
to fall below ``OnlineMapConfig.ratio_valid`` (turns below ~15 deg).

The flight is a generator of motor speeds (rpm): whoever drives it steps the swimmer at the speed it yields, then
calls ``observe`` with what the step showed, then asks for the next speed. It never sees the episode's end: the
driver stops asking. ``FlagellumBurst-v0`` drives it with the base env's exact head position and waypoint index;
the controller (``agents.burst_pilot``) with the head and index it reads from the observations, as the planner does.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from agents.burst_design import BurstCommand
from agents.online_turn_map import RatioClock
from agents.turn_geometry import azimuth, unit, wrap_angle
from agents.turn_map import TurnMap
from agents.turn_planner import (ObservationLayout, PlannerConfig, RulePlanner, hover_check, period_heading,
                                 relax_over, wobble_period_steps)

#: The start frame's x axis: the swimming direction when an episode starts (the heading before one is measured).
START_HEADING = np.array([1.0, 0.0, 0.0])
#: A burst ended by the ratio clock lasts at most this x t_c + ``RATIO_BURST_MARGIN_S``: the burst time law of
#: ``agents.surrogate_swimmer`` puts swimmers within +-10 % (E, mu, b) and +-4 % (helix) at most ~1.5x the map's.
RATIO_BURST_FACTOR = 1.6
RATIO_BURST_MARGIN_S = 0.5


class BurstFlight:
    """The measurements of one episode and the flying of its commands (module docstring).

    turn_map: omega_l, omega_h (rpm), the wobble period and relaxation time (s) of the swimmer's map;
    layout: where the phase node is in a ``FlagellumSteer-v0`` observation; control_dt: the env's step (s);
    config: the planner settings of the relaxation's end (``PlannerConfig``).
    """

    def __init__(self, turn_map: TurnMap, layout: ObservationLayout, control_dt: float,
                 config: PlannerConfig | None = None) -> None:
        self.turn_map, self.layout, self.control_dt = turn_map, layout, float(control_dt)
        self.config = config or PlannerConfig()
        self.period_steps = wobble_period_steps(turn_map.period_s, self.control_dt)
        #: the map's L'/L against burst length (bursts ended by L'/L)
        self.clock = RatioClock(turn_map)
        self.start(np.zeros(3), np.zeros(0), 0, 0.0)

    @classmethod
    def for_planner(cls, planner: RulePlanner) -> BurstFlight:
        """A flight measuring and timing as ``planner`` (its map, observation layout, step and settings)."""
        return cls(planner.turn_map, planner.layout, planner.control_dt, planner.config)

    # --- what the driver tells the flight ------------------------------------------------------------
    def start(self, head: np.ndarray, obs: np.ndarray, waypoint_index: int, time_s: float) -> None:
        """A new episode: the head (3,) m and the observation at its start, the waypoint index, the time (s)."""
        self.heads: list[np.ndarray] = [np.asarray(head, dtype=np.float64)]
        self.obs = np.asarray(obs, dtype=np.float64)
        self.waypoint_index, self.time_s = int(waypoint_index), float(time_s)
        self.bursts = 0
        #: What the last burst's hover did: the phase's miss of beta (rad), whether it timed out, how often the
        #: heading was measured again, its time and the relaxation's (s); None before any burst.
        self.last_burst: dict[str, Any] | None = None

    def observe(self, head: np.ndarray, obs: np.ndarray, waypoint_index: int, time_s: float) -> None:
        """What the control step just flown showed: the head (3,) m, the observation, the waypoint index, the
        time (s)."""
        self.heads.append(np.asarray(head, dtype=np.float64))
        self.obs = np.asarray(obs, dtype=np.float64)
        self.waypoint_index, self.time_s = int(waypoint_index), float(time_s)

    # --- measurements -----------------------------------------------------------------------------
    @property
    def head(self) -> np.ndarray:
        """The head's position now, (3,) m, start frame."""
        return self.heads[-1]

    @property
    def heading(self) -> np.ndarray:
        """The heading now, (3,) unit: the head's displacement over the last wobble period (``period_heading``);
        before a period was flown, since the start, or the start's."""
        if len(self.heads) > self.period_steps:
            return period_heading(self.heads, self.period_steps)
        move = self.heads[-1] - self.heads[0]
        return unit(move) if float(move @ move) > 0.0 else START_HEADING.copy()

    def phase(self, axis: np.ndarray) -> float:
        """The phase node's azimuth about ``axis`` now (rad), read from the observation as the planner reads it."""
        return azimuth(self.layout.read(self.obs)[1], axis)

    # --- flying (generators of motor speeds, rpm) -----------------------------------------------------
    def fly(self, command: BurstCommand) -> Iterator[float]:
        """Hover, burst and relax (if t_c > 0), then cruise."""
        if command.t_c_s > 0.0:
            yield from self.hover_to_phase(command.beta_rad)
            self.bursts += 1
            yield from self.burst(command.t_c_s, command.burst_end)
        yield from self.cruise(round(command.cruise_s / self.control_dt), stop_at_waypoint=True)

    def cruise(self, steps: int, stop_at_waypoint: bool) -> Iterator[float]:
        """``steps`` control steps at omega_l, fewer if (as asked) a waypoint is reached."""
        index = self.waypoint_index
        for _ in range(steps):
            yield self.turn_map.omega_l_rpm
            if stop_at_waypoint and self.waypoint_index != index:
                return

    def hover_to_phase(self, beta: float) -> Iterator[float]:
        """omega_l (at least one control step) until the phase node's azimuth about the heading reaches ``beta``
        (rad), with the rule planner's guards (``hover_check``)."""
        k, t0 = self.period_steps, self.time_s
        restarts = 0
        while True:
            axis = self.heading
            prev, steps, travel = self.phase(axis), 0, 0.0
            while True:
                yield self.turn_map.omega_l_rpm
                phase = self.phase(axis)
                steps += 1
                travel += wrap_angle(phase - prev)
                reached, timed_out, stuck = hover_check(prev, phase, beta, steps, travel, k, restarts,
                                                        RulePlanner.HOVER_LIMIT_PERIODS, RulePlanner.HOVER_RESTARTS)
                if reached or timed_out:
                    self.last_burst = {"phase_error_rad": wrap_angle(phase - beta), "hover_timed_out": timed_out,
                                       "hover_restarts": restarts, "hover_s": self.time_s - t0}
                    return
                if stuck:
                    break
                prev = phase
            # the phase swings about a heading off the flagellum's axis: measure the heading again, as the planner
            restarts += 1
            yield from self.cruise(k + 1, stop_at_waypoint=False)

    def burst(self, t_c: float, burst_end: str = "time") -> Iterator[float]:
        """A burst at omega_h, then omega_l until ``relax_over``. ``burst_end`` "time": ``t_c`` s (whole control
        steps); "ratio": until L'/L reaches the map's after ``t_c`` (module docstring)."""
        tm, dt = self.turn_map, self.control_dt
        target = self.clock.ratio_for(t_c) if burst_end == "ratio" else None
        if target is not None and self.layout.end_ratio is None:
            raise ValueError("a burst ended by L'/L needs the observation's end_to_end_ratio (ObservationLayout)")
        t0 = self.time_s
        if target is None:
            for _ in range(max(1, round(t_c / dt))):
                yield tm.omega_h_rpm
            stopped_by = "time"
        else:
            longest = max(1, round((RATIO_BURST_FACTOR * t_c + RATIO_BURST_MARGIN_S) / dt))
            steps, prev = 0, math.inf
            stopped_by = "time"
            while steps < longest:
                yield tm.omega_h_rpm
                steps += 1
                ratio = float(self.obs[self.layout.end_ratio][0])
                # the step nearest to the crossing: stop once the next step's fall would overshoot more than half
                drop = prev - ratio if math.isfinite(prev) else 0.0
                if ratio - target <= 0.5 * max(drop, 0.0):
                    stopped_by = "ratio"
                    break
                prev = ratio
        self.last_burst.update(burst_s=self.time_s - t0, end_ratio=self._end_ratio(), stopped_by=stopped_by)
        t1, waited = self.time_s, 0
        while True:
            yield tm.omega_l_rpm
            waited += 1
            if relax_over(self.heads, waited, self.period_steps, self.config, tm.relax_s, dt):
                break
        self.last_burst["relax_s"] = self.time_s - t1

    def _end_ratio(self) -> float | None:
        """L'/L in the observation now (None if the layout does not read it)."""
        return None if self.layout.end_ratio is None else float(self.obs[self.layout.end_ratio][0])
