"""The paper's rule-based turn planner (Sec. 3 of Huang & Jawed 2020), closed-loop.

Per corner: compute the turn theta* from the current heading to the wanted direction and the
burst length t_c* for it from the turn map (turns beyond the map's largest theta are made in
several bursts); hover at omega_l until the flagellum's rotation phase puts the turn's
direction (the map's psi, fixed relative to that phase) where the wanted direction is, which
sets the out-of-plane angle; burst at omega_h for t_c*; return to omega_l and swim straight.

Beyond the paper, the loop is closed: after every turn the planner waits until the heading is
steady, measures it and re-plans from the measured heading and position. A turn is chosen by
predicting every candidate (burst length x flagellum phase at the burst) with the map, including
the head's displacement during the turn (several cm), and taking the one whose new straight line
passes closest to the next waypoint; on straight stretches a predicted miss of the waypoint
triggers a correction turn the same way.

The planner sees only the environment's observation (the same ``predict`` call as a
stable-baselines3 policy): the head position is dead-reckoned from the relative waypoint
vectors (exact: the next waypoints relative to the head, rotated into the start frame with the
orientation part), the heading is the head displacement over one wobble period, and the phase
is the azimuth of the map's phase node (an observed shape node) about the heading.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from agents.candidate_miss import (candidate_frames, candidate_plan, line_miss, paper_rule_choice, paper_rule_misses,
                                   pick_least, turn_wanted)
from agents.turn_geometry import angle_between, azimuth, norm3, perpendicular_basis, unit, wrap_angle
from agents.turn_map import TurnMap, leading_within
from flagellum_env.config import DEFAULT_REACH_RADIUS_M
from physics.validation import require_finite


#: What a target behind a line's start adds to its distance in the paper's miss (``paper_line_miss``), m.
BEHIND_PENALTY_M = 0.05


@dataclass(frozen=True)
class PlannerConfig:
    """Tuning of the closed loop (angles in degrees, lengths in m).

    line_weight: 0 (default) chooses a turn by its miss of the target alone, the paper's rule. Above 0, a
    candidate also costs ``line_weight`` x the distance of its predicted end (the head after the turn) from the
    line of the segment being followed (previous waypoint, or the start, to the target; ``line_distance``), and
    swimming on the head's distance from it now; a turn is made when it lowers the miss or this score by
    ``improvement_m``, so the swimmer also turns back towards the path's line, not only towards the waypoint.
    """

    min_turn_deg: float = 5.0        # heading errors below this never trigger a turn
    hit_fraction: float = 0.6        # no correction while the predicted miss is below this x reach radius
    settle_tol_deg: float = 1.5      # heading steady when two one-period headings differ by less
    max_relax_factor: float = 3.0    # give up waiting for a steady heading after this x the map's relax time
    improvement_m: float = 0.005     # a turn must bring the predicted miss down by at least this
    phase_step_deg: float = 5.0      # resolution of the burst phases searched
    line_weight: float = 0.0         # m per m of the turn's end from the segment's line (0: the paper's rule)
    burst_cap_deg: float = math.inf  # largest turn one burst is planned for (larger turns take several bursts)

    def __post_init__(self) -> None:
        for name in ("min_turn_deg", "hit_fraction", "settle_tol_deg", "max_relax_factor", "improvement_m",
                     "phase_step_deg"):
            require_finite(f"PlannerConfig.{name}", getattr(self, name), 0.0, lo_open=True)
        require_finite("PlannerConfig.line_weight", self.line_weight, 0.0)
        if not (isinstance(self.burst_cap_deg, (int, float)) and self.burst_cap_deg > 0.0):
            raise ValueError(f"PlannerConfig.burst_cap_deg must be > 0 (inf: no cap), got {self.burst_cap_deg!r}")

    @classmethod
    def from_options(cls, options: dict[str, float]) -> PlannerConfig | None:
        """The config a controller spec's options ask for (``agents.controller_spec.controller_options``:
        ``line`` -> ``line_weight``, ``cap`` -> ``burst_cap_deg``), or None (the defaults) without options."""
        if not options:
            return None
        names = {"line": "line_weight", "cap": "burst_cap_deg"}
        return cls(**{names[k]: v for k, v in options.items()})


@dataclass(frozen=True)
class ObservationLayout:
    """Where the planner finds what it needs in a flat observation of ``FlagellumSteer-v0``."""

    waypoints: slice
    orientation: slice
    shape: slice
    length_scale_m: float
    phase_slot: int  # which observed shape node is the turn map's phase node
    time_left: slice | None = None  # the fraction of the episode's time budget left (None: not read)
    end_ratio: slice | None = None  # the flagellum's L'/L (None: not read)

    @classmethod
    def from_env(cls, env, turn_map: TurnMap) -> ObservationLayout:
        """From a ``FlagellumSteerEnv`` (or a wrapper of one); ValueError if it cannot serve the map."""
        base = env.unwrapped
        model = base.obs_model
        if model.observation_type != "flat":
            raise ValueError("the rule planner reads flat observations; make the env with observation_type='flat'")
        slots = np.flatnonzero(model.shape_nodes == turn_map.phase_node)
        if slots.size == 0:
            raise ValueError(f"the turn map's phase node {turn_map.phase_node} is not among the observed shape "
                             f"nodes {model.shape_nodes.tolist()}; use n_shape_nodes=8 (the default) or "
                             "calibrate for this observation")
        s = model.slices()
        return cls(s["waypoints"], s["orientation"], s["shape"], model.length_scale_m, int(slots[0]), s["time_left"],
                   s["end_to_end_ratio"])

    def read(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the observed targets minus the head, (k, 3); the phase node minus the head, (3,)), both m in the start
        frame, from one flat observation (float64), as the planner reads them."""
        rot = obs[self.orientation].reshape(3, 3).T  # columns X_b, Y_b, Z_b in the start frame
        rel = (obs[self.waypoints].reshape(-1, 3) * self.length_scale_m) @ rot.T  # targets - head, start frame
        node = obs[self.shape].reshape(-1, 3)[self.phase_slot] * self.length_scale_m @ rot.T
        return rel, node


@dataclass
class PlannerEpisode:
    """What the planner remembers within one episode."""

    step: int = 0
    head: np.ndarray = field(default_factory=lambda: np.zeros(3))
    prev_rel: np.ndarray | None = None          # (2, 3) targets relative to the head, start frame
    heads: list[np.ndarray] = field(default_factory=list)
    mode: str = "cruise"                        # cruise | hover | burst | relax
    low_since: int = 0                          # step from which the motor has been at omega_l
    burst_left: int = 0
    target_phase: float = 0.0                   # rad, azimuth of the phase node at which to burst
    axis: np.ndarray | None = None              # heading the hover phase is measured about
    prev_phase: float | None = None
    hover_steps: int = 0
    hover_travel: float = 0.0                   # rad the phase node turned (signed) since the hover began
    hover_restarts: int = 0                     # hovers given up for this turn (``hover_phase_stuck``)
    plan: dict = field(default_factory=dict)
    turns: list[dict] = field(default_factory=list)
    segment: tuple[np.ndarray, np.ndarray] | None = None  # (start, target) of the current path segment


def burst_phase_reached(prev_phase: float, phase: float, target: float) -> bool:
    """Whether the hover should burst now: the phase node's azimuth (rad) moved from ``prev_phase`` to
    ``phase`` in the last control step and ``target`` is within half of that step ahead of ``phase`` along
    the rotation, or was passed during that step (the rotation's rate varies from step to step, so a window of
    half a step either side alone can be jumped). Both can hold on two steps in a row; the hover bursts at the
    first, so never later than the first step past the target."""
    moved = wrap_angle(phase - prev_phase)
    sense = 1.0 if moved > 0 else -1.0
    togo = wrap_angle(target - phase) * sense          # along the rotation, ahead > 0
    passed = wrap_angle(target - prev_phase) * sense   # where the target lay when the step began
    return 0.0 <= togo <= 0.5 * abs(moved) or 0.0 <= passed <= abs(moved)


def hover_phase_stuck(hover_steps: int, travel_rad: float, period_steps: int, restarts: int,
                      max_restarts: int) -> bool:
    """Whether a hover should be given up: after 1.5 map periods (``period_steps`` control steps each; the phase
    node's lab-frame azimuth turns about once per period at omega_l) the azimuth has turned (``travel_rad``, signed
    sum of its steps) less than once, so it swings about the measured heading instead of turning round it, and
    fewer than ``max_restarts`` hovers of this turn were given up already (replayed: a heading measured while the
    swimmer still turned after a 128 deg burst lay 22 deg off the flagellum's axis; the azimuth about it swung
    between -32 and +13 deg for 27 s)."""
    return hover_steps > 1.5 * period_steps and abs(travel_rad) < 2.0 * math.pi and restarts < max_restarts


def hover_check(prev_phase: float, phase: float, target: float, hover_steps: int, travel_rad: float,
                period_steps: int, restarts: int, limit_periods: float, max_restarts: int) -> tuple[bool, bool, bool]:
    """(reached, timed_out, stuck) after a hover's ``hover_steps``-th control step: the phase reached ``target``
    (``burst_phase_reached``), more than ``limit_periods`` map periods hovered (burst at the phase it has), or,
    neither holding, the phase swings instead of turning (``hover_phase_stuck``: measure the heading again)."""
    reached = burst_phase_reached(prev_phase, phase, target)
    timed_out = hover_steps > limit_periods * period_steps
    stuck = not reached and not timed_out and hover_phase_stuck(hover_steps, travel_rad, period_steps, restarts,
                                                                max_restarts)
    return reached, timed_out, stuck


def dead_reckon(head: np.ndarray, prev_rel: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """The head now (3,) m from the head at the last control step and the targets relative to it then and now
    ((k, 3) m, ``ObservationLayout.read``): the head moved by prev - now for the same target; if the target switched,
    the old second target is the new first one. The smaller implied move is the right one."""
    moves = [prev_rel[0] - rel[0]]
    if prev_rel.shape[0] > 1:
        moves.append(prev_rel[1] - rel[0])
    return head + min(moves, key=lambda m: math.sqrt(float(m @ m)))  # np.linalg.norm, cheaper


def wobble_period_steps(period_s: float, control_dt: float) -> int:
    """Control steps of one wobble period (the map's ``period_s``, s, at ``control_dt`` s), at least 2."""
    return max(2, round(period_s / control_dt))


def period_heading(heads: list[np.ndarray], period_steps: int) -> np.ndarray:
    """The heading as the planner measures it: the unit head displacement over the last ``period_steps`` control
    steps (one wobble period); ``heads`` the head after each control step (m), at least ``period_steps`` + 1."""
    return unit(heads[-1] - heads[-1 - period_steps])


def heading_steady(heads: list[np.ndarray], period_steps: int, settle_tol_deg: float) -> bool:
    """Whether the headings over the last two periods (``period_heading``) differ by less than ``settle_tol_deg``."""
    k = period_steps
    if len(heads) < 2 * k + 1:
        return False
    a = heads[-1] - heads[-1 - k]
    b = heads[-1 - k] - heads[-1 - 2 * k]
    return math.degrees(angle_between(a, b)) < settle_tol_deg


def relax_over(heads: list[np.ndarray], waited_steps: int, period_steps: int, config: PlannerConfig,
               map_relax_s: float, control_dt: float) -> bool:
    """Whether the relaxation after a burst is over, ``waited_steps`` control steps (``control_dt`` s) at omega_l
    after it: at least two periods and the heading steady (``heading_steady``), or ``config.max_relax_factor`` x
    the map's relaxation ``map_relax_s`` (s) waited."""
    limit = config.max_relax_factor * map_relax_s / control_dt
    return waited_steps >= 2 * period_steps and (heading_steady(heads, period_steps, config.settle_tol_deg)
                                                 or waited_steps >= limit)


def paper_line_miss(starts: np.ndarray, directions: np.ndarray, target: np.ndarray,
                    behind_penalty: float = BEHIND_PENALTY_M) -> np.ndarray:
    """How far the straight lines start + s direction (s >= 0) pass from ``target``, (k,) m; a target
    behind a start counts its distance plus ``behind_penalty`` (m). starts, directions (k, 3); compiled
    (``agents.candidate_miss.line_miss``)."""
    return line_miss(np.asarray(starts, dtype=np.float64), np.asarray(directions, dtype=np.float64),
                     np.asarray(target, dtype=np.float64), float(behind_penalty))


class RulePlanner:
    """Rule-based controller with a stable-baselines3-like ``predict``.

    turn_map: the calibration for this swimmer (``TurnMap.load``). layout: from
    ``ObservationLayout.from_env(env, turn_map)``. control_dt: the env's step (s).
    ``action_of(rpm)`` maps a motor speed to the env's action (``for_env`` sets it up).
    """

    #: A hover that has not met its phase after this many map periods bursts at the phase it has (a guard against
    #: a phase that does not rotate; the phase node's lab-frame azimuth turns about once per map period at omega_l,
    #: so the earlier limit of 1.5 periods fired a turn at the wrong phase whenever one pass was missed).
    HOVER_LIMIT_PERIODS = 3.0
    #: How many times a hover whose phase does not turn (``hover_phase_stuck``) is given up for a new heading
    #: before the time-out fires the turn as it stands.
    HOVER_RESTARTS = 2

    def __init__(self, turn_map: TurnMap, layout: ObservationLayout, control_dt: float, reach_radius_m: float,
                 action_of, config: PlannerConfig | None = None) -> None:
        self.turn_map = turn_map
        self.layout = layout
        self.control_dt = float(control_dt)
        self.reach_radius_m = float(reach_radius_m)
        self.action_of = action_of
        self.config = config or PlannerConfig()
        self.period_steps = wobble_period_steps(turn_map.period_s, self.control_dt)
        self.min_turn_rad = math.radians(max(self.config.min_turn_deg, 0.0))
        self._episodes: list[PlannerEpisode] = []

    @classmethod
    def for_env(cls, env, turn_map: TurnMap, config: PlannerConfig | None = None) -> RulePlanner:
        """A planner for this environment: checks the map against the env's swimmer and speeds."""
        base = env.unwrapped
        cfg = base.config
        turn_map.check_compatible(base.params)
        lo = base.low_speed_rpm
        if lo != turn_map.omega_l_rpm:
            raise ValueError(f"the env's low motor speed is {lo} rpm but the turn map was made at omega_l = "
                             f"{turn_map.omega_l_rpm} rpm; make the env with that low speed")
        if cfg.action_type == "continuous":
            a_lo, a_hi = cfg.omega_range_rpm
            if not a_lo <= turn_map.omega_h_rpm <= a_hi:
                raise ValueError(f"the turn map's omega_h = {turn_map.omega_h_rpm} rpm is outside the env's "
                                 f"omega_range_rpm {cfg.omega_range_rpm}")

            def action_of(rpm: float) -> np.ndarray:
                return np.array([2.0 * (rpm - a_lo) / (a_hi - a_lo) - 1.0], dtype=np.float32)
        else:
            speeds = list(cfg.discrete_speeds_rpm)
            if turn_map.omega_h_rpm not in speeds:
                raise ValueError(f"the turn map's omega_h = {turn_map.omega_h_rpm} rpm is not one of the env's "
                                 f"discrete_speeds_rpm {speeds}")

            def action_of(rpm: float) -> np.ndarray:
                return np.int64(speeds.index(rpm))
        if base.tracker is not None:
            reach = base.tracker.reach_radius_m
        else:
            fixed = cfg.fixed_path.reach_radius_m if cfg.fixed_path is not None else None
            reach = cfg.reach_radius_m or fixed or DEFAULT_REACH_RADIUS_M
        return cls(turn_map, ObservationLayout.from_env(env, turn_map), cfg.control_dt, reach, action_of, config)

    # --- stable-baselines3-like interface --------------------------------------------------
    def reset(self) -> None:
        """Forget every episode (the next ``predict`` starts afresh)."""
        self._episodes = []

    def predict(self, observation: np.ndarray, state=None, episode_start=None, deterministic: bool = True):
        """(actions, None) for one observation (D,) or a batch (n_envs, D), like ``BasePolicy.predict``.

        ``episode_start``: bools per env (True on the first observation of an episode); without
        it, the first call starts an episode. The planner is deterministic either way.
        """
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        batch = obs[None, :] if single else obs
        n = batch.shape[0]
        starts = np.ones(n, bool) if episode_start is None and not self._episodes else (
            np.zeros(n, bool) if episode_start is None else np.asarray(episode_start, bool).reshape(n))
        while len(self._episodes) < n:
            self._episodes.append(self._new_episode())
            starts[len(self._episodes) - 1] = True
        actions = []
        for i in range(n):
            if starts[i]:
                self._episodes[i] = self._new_episode()
            actions.append(self.action_of(self._decide(self._episodes[i], batch[i])))
        out = np.stack(actions)
        return (out[0] if single else out), None

    @property
    def turns(self) -> list[dict]:
        """The turns planned so far in the first env's episode (for reports and plots)."""
        return self._episodes[0].turns if self._episodes else []

    # --- the rules -------------------------------------------------------------------------
    def _decide(self, ep: PlannerEpisode, obs: np.ndarray) -> float:
        """Motor speed (rpm) for the next control step."""
        tm = self.turn_map
        rel, node = self.layout.read(obs)
        if ep.prev_rel is not None:
            ep.head = dead_reckon(ep.head, ep.prev_rel, rel)
        ep.prev_rel = rel
        ep.heads.append(ep.head.copy())
        ep.step += 1
        target = ep.head + rel[0]
        wl, wh = tm.omega_l_rpm, tm.omega_h_rpm

        if ep.mode == "burst":
            if self._continue_burst(ep, obs):
                return wh
            ep.mode, ep.low_since = "relax", ep.step
            return wl
        if ep.mode == "relax":
            if relax_over(ep.heads, ep.step - ep.low_since, self.period_steps, self.config, tm.relax_s,
                          self.control_dt):
                ep.mode = "cruise"
                self._turn_settled(ep)
            return wl
        if ep.mode == "hover":
            phase = azimuth(node, ep.axis)
            if ep.prev_phase is not None:
                ep.hover_steps += 1
                ep.hover_travel += wrap_angle(phase - ep.prev_phase)
                reached, timed_out, stuck = hover_check(
                    ep.prev_phase, phase, ep.target_phase, ep.hover_steps, ep.hover_travel, self.period_steps,
                    ep.hover_restarts, self.HOVER_LIMIT_PERIODS, self.HOVER_RESTARTS)
                if stuck:
                    # the phase swings instead of turning: the heading it is measured about is off the
                    # flagellum's axis (a heading still turning after the last burst); measure it again
                    ep.hover_restarts += 1
                    ep.mode, ep.low_since = "cruise", ep.step
                    return wl
                if reached or timed_out:
                    # this step is the first of max(1, t_c / control_dt) steps at omega_h
                    ep.mode, ep.burst_left = "burst", max(1, round(ep.plan["t_c"] / self.control_dt)) - 1
                    ep.plan["burst_step"] = ep.step
                    ep.plan["phase_error_deg"] = math.degrees(wrap_angle(phase - ep.target_phase))
                    ep.plan["hover_timed_out"] = bool(timed_out)
                    ep.plan["hover_restarts"] = ep.hover_restarts
                    ep.hover_restarts = 0
                    ep.turns.append(dict(ep.plan))
                    return wh
            ep.prev_phase = phase
            return wl
        # cruise: decide once a heading can be measured at omega_l
        if ep.step - ep.low_since < self.period_steps + 1:
            return wl
        d = self._heading(ep)
        self.track_segment(ep, target)
        plan = self._plan_turn(ep.head, d, target, node, ep)
        if plan is not None:
            plan = self._review_plan(ep, plan, obs)
        if plan is None:
            ep.hover_restarts = 0
            return wl
        # hover at omega_l from here until the phase node reaches the planned azimuth
        ep.mode, ep.plan, ep.axis = "hover", plan, d
        ep.target_phase, ep.prev_phase, ep.hover_steps, ep.hover_travel = plan["burst_phase"], azimuth(node, d), 0, 0.0
        return wl

    def _new_episode(self) -> PlannerEpisode:
        """The memory of a new episode (subclasses may remember more)."""
        return PlannerEpisode()

    @staticmethod
    def track_segment(ep: PlannerEpisode, target: np.ndarray) -> None:
        """Keep ``ep.segment`` the (start, target) of the path segment being followed (start frame, m)."""
        if ep.segment is None:
            ep.segment = (np.zeros(3), target.copy())  # the path starts at the head's start
        elif norm3(target - ep.segment[1]) > 1e-3:
            ep.segment = (ep.segment[1].copy(), target.copy())  # the target switched: the old one starts the segment

    def _continue_burst(self, ep: PlannerEpisode, obs: np.ndarray) -> bool:
        """During a burst: True to stay at omega_h for the next control step. The rule planner
        flies the planned number of steps; ``agents.adaptive_planner`` watches L'/L."""
        if ep.burst_left > 0:
            ep.burst_left -= 1
            return True
        return False

    def _turn_settled(self, ep: PlannerEpisode) -> None:
        """Called once the heading after the last turn (``ep.turns[-1]``) is steady (or the wait
        ran out); ``_heading(ep)`` is then the new heading. The rule planner does not learn from it;
        ``agents.adaptive_planner`` corrects its map."""

    def _review_plan(self, ep: PlannerEpisode, plan: dict, obs: np.ndarray) -> dict | None:
        """Last look at a planned turn before the hover starts: the plan to fly, or None to keep
        cruising this step. The rule planner flies its plan; ``agents.residual_planner`` adjusts it."""
        return plan

    def _heading(self, ep: PlannerEpisode) -> np.ndarray:
        return period_heading(ep.heads, self.period_steps)

    def _plan_turn(self, head: np.ndarray, d: np.ndarray, target: np.ndarray, node: np.ndarray,
                   ep: PlannerEpisode | None = None) -> dict | None:
        """The next turn (burst length, phase to burst at), or None to keep swimming straight
        (``rule_plan`` with this planner's miss of a line)."""
        return self.rule_plan(head, d, target, ep, self._line_miss)

    def rule_plan(self, head: np.ndarray, d: np.ndarray, target: np.ndarray, ep: PlannerEpisode | None,
                  line_miss) -> dict | None:
        """The paper's rule: the next turn (burst length, phase to burst at), or None to keep swimming straight.

        Every candidate turn (burst length on the map's rising branch x phase of the flagellum at
        the burst) is predicted from the map: the head moves by the map's displacement and then
        swims along the new heading. The candidate whose straight line passes closest to the
        target is chosen if it beats swimming on by ``improvement_m``; the miss of a line is the
        target's distance from it, or the distance to the target plus a penalty when the target
        is behind (``line_miss(starts, directions, target)``, m). With ``PlannerConfig.line_weight`` > 0
        (and ``ep.segment`` known) the candidates are scored by miss + line_weight x the distance of the
        turn's end from the segment's line, and a turn is made if it improves the miss or the score.
        """
        cfg = self.config
        t_c, theta, psi, off = self._candidate_turns(ep)
        beta = self._burst_phases
        segment = ep.segment if ep is not None else None
        with_line = cfg.line_weight > 0.0 and segment is not None
        if line_miss is paper_line_miss:
            # the paper's miss, compiled (agents.candidate_miss.paper_rule_misses: the same formulas as below)
            frames = self.candidate_frames(theta, psi, off, beta)
            hit = cfg.hit_fraction * self.reach_radius_m
            if not with_line:  # the choice by the miss alone, compiled too (pick_turn's without a line)
                wanted, miss0, k, best = paper_rule_choice(head, d, target, frames, BEHIND_PENALTY_M, hit,
                                                           cfg.min_turn_deg, cfg.improvement_m)
                if wanted < 0:
                    angle_between(d, target - head)  # raises: the heading or the target's direction is zero
                if wanted <= 0 or k < 0:
                    return None
                i, j = divmod(k, len(beta))
                return self.plan_of(head, d, i, j, best, miss0, ep)
            miss = np.empty((len(theta), len(beta)))
            wanted, miss0 = paper_rule_misses(head, d, target, frames, BEHIND_PENALTY_M, hit, cfg.min_turn_deg, miss)
            if wanted < 0:
                angle_between(d, target - head)  # raises: the heading or the target's direction is zero
            if wanted <= 0:
                return None
            after = turn_ends(head, d, off, beta)
        else:
            miss0 = self._miss_if_off_course(head, d, target, line_miss)
            if miss0 is None:
                return None
            miss, after = candidate_misses(head, d, theta, psi, off, beta, target, line_miss)
        line = None  # the line term only where it counts (PlannerConfig.line_weight > 0)
        if with_line:
            line = (line_distance(after, *segment), float(line_distance(head, *segment)))
        chosen = pick_turn(miss, miss0, cfg, line)
        if chosen is None:
            return None
        i, j, score, score0 = chosen
        plan = self.plan_of(head, d, i, j, miss.item(i, j), miss0, ep)
        if line is not None:
            plan.update(line_score_m=score, line_score_straight_m=score0)
        return plan

    def plan_of(self, head: np.ndarray, d: np.ndarray, i: int, j: int, miss: float, miss_straight: float,
                ep: PlannerEpisode | None) -> dict:
        """The plan of candidate turn ``i`` (``candidate_turns``) at burst phase ``j`` (``burst_phases``) from the head
        ``head`` (3,) m along the unit heading ``d`` (3,): its ``miss`` and swimming on's, m (``rule_plan``)."""
        t_c, theta, psi, _ = self._candidate_turns(ep)
        t, theta_deg, phase, azimuth_rad = candidate_plan(t_c, theta, psi, self._burst_phases, i, j)
        return {"t_c": t, "theta_deg": theta_deg, "burst_phase": phase, "predicted_azimuth": azimuth_rad,
                "predicted_miss_m": float(miss), "miss_straight_m": float(miss_straight),
                "heading": d.tolist(), "head": head.tolist()}

    def _miss_if_off_course(self, head: np.ndarray, d: np.ndarray, target: np.ndarray,
                            line_miss=None) -> float | None:
        """How far swimming straight on misses the target (m; ``line_miss``, default this planner's), or None when
        no turn is wanted: on course (below ``hit_fraction`` x the reach radius) or the target less than
        ``min_turn_deg`` off the heading (re-checked every step)."""
        cfg = self.config
        miss0 = float((line_miss or self._line_miss)(head[None, :], d[None, :], target)[0])
        wanted = turn_wanted(miss0, d, target - head, cfg.hit_fraction * self.reach_radius_m, cfg.min_turn_deg)
        if wanted < 0:
            angle_between(d, target - head)  # raises: the heading or the target's direction is zero
        return miss0 if wanted > 0 else None

    #: how far each straight line misses the target, (k,) m: the paper's miss (``paper_line_miss``; the adaptive
    #: planner grades a target behind instead)
    _line_miss = staticmethod(paper_line_miss)

    def _candidate_turns(self, ep: PlannerEpisode | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The turns a plan chooses from in this episode: (t_c s, theta rad, psi rad, offset (T, 3) m)."""
        return self._candidates

    def candidate_turns(self, ep: PlannerEpisode | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The turns a plan chooses from in this episode: (t_c s, theta rad, psi rad, offset (T, 3) m)."""
        return self._candidate_turns(ep)

    @property
    def burst_phases(self) -> np.ndarray:
        """The burst phases a plan searches, (B,) rad."""
        return self._burst_phases

    def episode_frames(self, ep: PlannerEpisode | None) -> np.ndarray:
        """``candidate_frames`` of the turns a plan chooses from in this episode at the burst phases searched,
        (T, B, 6)."""
        _, theta, psi, off = self._candidate_turns(ep)
        return self.candidate_frames(theta, psi, off, self._burst_phases)

    def candidate_frames(self, theta: np.ndarray, psi: np.ndarray, off: np.ndarray, beta: np.ndarray) -> np.ndarray:
        """``agents.candidate_miss.candidate_frames`` of these candidates, (T, B, 6), remembered for the last set
        (the rule planner's are the same every plan)."""
        cached = getattr(self, "_frames", None)
        if cached is None or not (cached[0] is theta and cached[1] is psi and cached[2] is off and cached[3] is beta):
            cached = (theta, psi, off, beta, candidate_frames(theta, psi, off, beta))
            self._frames = cached
        return cached[4]

    @functools.cached_property
    def _burst_phases(self) -> np.ndarray:
        """The burst phases a plan searches, (B,) rad (every ``PlannerConfig.phase_step_deg``)."""
        return np.radians(np.arange(0.0, 360.0, self.config.phase_step_deg))

    @functools.cached_property
    def _candidates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Burst lengths on the rising branch every control step, with theta (rad), psi (rad), offset (m); only
        turns up to ``PlannerConfig.burst_cap_deg`` (at least the first)."""
        tm = self.turn_map
        t_branch, theta_branch = tm.rising_branch()
        t_c = np.arange(self.control_dt, t_branch[-1] + 1e-9, self.control_dt)
        theta = np.radians(np.interp(t_c, t_branch, theta_branch))
        keep = leading_within(theta, math.radians(self.config.burst_cap_deg))
        t_c, theta = t_c[:keep], theta[:keep]
        psi = np.radians([tm.psi_for(t) for t in t_c])
        off = np.array([tm.offset_for(t) for t in t_c])
        return t_c, theta, psi, off


def candidate_misses(head: np.ndarray, d: np.ndarray, theta: np.ndarray, psi: np.ndarray, offset: np.ndarray,
                     beta: np.ndarray, target: np.ndarray, line_miss) -> tuple[np.ndarray, np.ndarray]:
    """(miss (T, B) m, turn ends (T, B, 3) m) of the candidate turns: theta, psi (T,) rad and ``offset`` (T, 3) m
    of the map's turns flown at the burst phases ``beta`` (B,) rad about the heading ``d``, scored by
    ``line_miss(starts, directions, target)`` (the world-frame form of ``agents.candidate_miss.candidate_miss``)."""
    e1, e2 = perpendicular_basis(d)
    az = beta[None, :] + psi[:, None]                                        # (T, B)
    across = (np.cos(az)[..., None] * e1 + np.sin(az)[..., None] * e2)       # (T, B, 3)
    heading = np.cos(theta)[:, None, None] * d + np.sin(theta)[:, None, None] * across
    after = turn_ends(head, d, offset, beta)                                 # (T, B, 3)
    miss = line_miss(after.reshape(-1, 3), heading.reshape(-1, 3), target).reshape(after.shape[:2])
    return miss, after


def turn_ends(head: np.ndarray, d: np.ndarray, offset: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Where the head is after each turn (m, shape offset.shape[:-1] + (B, 3)): ``offset`` (..., 3) is the map's
    displacement (along the heading ``d``, along the flagellum's reference direction at the burst, across both)
    and ``beta`` (B,) rad the reference direction's azimuth about ``d`` (``perpendicular_basis``)."""
    e1, e2 = perpendicular_basis(d)
    e_ref = np.cos(beta)[:, None] * e1 + np.sin(beta)[:, None] * e2                       # (B, 3)
    e_perp = np.cross(d, e_ref)
    return (head + offset[..., 0, None, None] * d + offset[..., 1, None, None] * e_ref
            + offset[..., 2, None, None] * e_perp)


def pick_turn(miss: np.ndarray, miss_straight: float, config: PlannerConfig,
              line: tuple[np.ndarray, float] | None = None) -> tuple[int, int, float, float] | None:
    """The candidate to fly, (i, j, its score, swimming on's score), or None to swim on. ``miss`` (T, B) m: each
    candidate's miss (``miss_straight``: swimming on's); ``line``: (distance of each candidate's end from the
    segment's line, shape of ``miss``; the head's now), m. Without a line or with ``config.line_weight`` 0 the score
    is the miss; otherwise miss + line_weight x distance, and a candidate is flown if it improves the miss or the
    score by ``config.improvement_m`` (``PlannerConfig``)."""
    w, imp = config.line_weight, config.improvement_m
    if w > 0.0 and line is not None:
        score, straight = miss + w * line[0], miss_straight + w * line[1]
        i, j = divmod(int(score.argmin()), score.shape[1])  # np.unravel_index's, cheaper
        if miss[i, j] > miss_straight - imp and score[i, j] > straight - imp:
            return None
        return int(i), int(j), float(score[i, j]), float(straight)
    k, best = pick_least(np.ascontiguousarray(miss, dtype=np.float64), float(miss_straight), float(imp))
    if k < 0:
        return None
    i, j = divmod(k, miss.shape[1])  # np.unravel_index's
    return i, j, best, float(miss_straight)


def line_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of points (..., 3) from the infinite line through a and b (from a if they coincide),
    shape (...)."""
    u = b - a
    n = math.sqrt(float(u @ u))
    rel = points - a
    if n < 1e-12:
        return np.linalg.norm(rel, axis=-1)
    u = u / n
    return np.linalg.norm(rel - (rel @ u)[..., None] * u, axis=-1)


def graded_line_miss(starts: np.ndarray, directions: np.ndarray, target: np.ndarray, behind_penalty: float = 0.2
                     ) -> np.ndarray:
    """Like ``paper_line_miss``, but a target behind costs its distance plus ``behind_penalty`` (m) times
    the cosine of how far behind it is (0 abeam, the whole penalty straight behind), so that a
    partial turn towards a target behind counts as progress (turns too large for one burst). The
    penalty outweighs the several centimetres a turn displaces the head (the map's offsets), or
    a swimmer that has passed its target would never turn back."""
    rel = target - starts
    along = np.einsum("ij,ij->i", rel, directions)
    dist = np.linalg.norm(rel, axis=1)
    lateral = np.linalg.norm(rel - along[:, None] * directions, axis=1)
    return np.where(along > 0.0, lateral, dist - behind_penalty * along / np.maximum(dist, 1e-12))
