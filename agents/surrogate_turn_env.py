"""``FlagellumTurn-surrogate-v0``: ``FlagellumTurn-v0``'s task with no rod, jumping from decision to decision.

Same arguments, spaces, reward terms and ``info`` keys as ``FlagellumTurn-v0`` (``agents.turn_decision_env``),
so an agent or a planner runs in either. What differs is the swimmer: instead of ``FlagellumSteer-v0`` at 0.1 s
control steps, a kinematic swimmer (``agents.surrogate_swimmer``) swims straight at the calibrated cruise speed and
turns by the calibrated turn map, and the rule planner's loop is replayed at the level of its events:

1. cruise: the planner plans (``RulePlanner.rule_plan``, the same code as at ``faithful``) once a heading can be
   measured; with no turn wanted it swims on to the next event that can change that (the target reached, the
   heading error crossing ``min_turn_deg``, the target passed) or ``RECHECK_S`` later while off course
   (the physics planner re-checks every 0.1 s control step);
2. a turn planned: its features (``turn_features``) are the observation; the action corrects it
   (``corrected_plan``);
3. hover until the flagellum's phase (turning once per map period ``period_s``) reaches the burst phase, burst for
   the planned number of control steps, and relax for the planner's wait (at least two periods, the map's
   relaxation time for the swimmer, at most ``max_relax_factor`` x the map's median): the head moves along the
   chord of the map's displacement, the heading jumps to the map's new heading at the end;
4. then 1. again.

Waypoints (``flagellum_env.tracking.PathTracker``), rewards (``flagellum_env.rewards.reward_terms``: progress,
cross-track error integrated over time along the legs, energy, waypoints, the penalties), the time budget
(``time_factor`` x path length / cruise speed, in control steps) and the end of an episode are the physics env's,
evaluated on the legs (straight lines) instead of at every control step.

Calibrated range (one-line ``ValueError`` at construction): the default preset's map and swimmer (``preset``
"faithful", no ``params`` or ``numerics`` override, ``omega_l``/``omega_h`` of the map reachable by the action),
the rule planner, and randomisation fractions within ``FACTOR_RANGE`` (up to 15 %). A burst whose map time
leaves the map's burst lengths sets ``info["out_of_range"]`` for the
rest of the episode, with ``info["out_of_range_reason"]`` naming the value (and a warning once per env).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numba import njit
from gymnasium.utils import seeding

from agents.controller_spec import CONTROLLER_ENV_DEFAULTS
from agents.registration import TURN_SURROGATE_ENV_ID
from agents.residual_planner import (ResidualLimits, base_planner, clipped_residual, corrected_turn, feature_error,
                                     feature_vector)
from agents.surrogate_calibration import SurrogateCalibration, calibration_file
from agents.surrogate_episode import SurrogateEpisode, surrogate_info
from agents.surrogate_swimmer import FACTOR_RANGE, SurrogateSwimmer, TurnMapTable
from agents.turn_decision_env import (DEFAULT_ACTION_COST, DEFAULT_RANDOM_PATH, TurnEpisodes, fixed_paths,
                                      load_turn_map, parse_turn_action, refuse_unknown_arguments, residual_limits,
                                      turn_env_kwargs)
from agents.candidate_miss import (candidate_plan, first_improving_distance, first_improving_sample, paper_rule_choice,
                                   target_in_frame)
from agents.surrogate_episode import cruise_state
from agents.surrogate_legs import DT, GOES_ON, HEADING, REACH, SPEED, TIME
from agents.turn_geometry import angle_between
from agents.turn_map import TurnMap
from agents.turn_planner import BEHIND_PENALTY_M, PlannerEpisode, RulePlanner, paper_line_miss
from flagellum_env.config import DEFAULT_REACH_RADIUS_M, SteerConfig, draw_randomization, make_config
from flagellum_env.tracking import PathTracker
from physics.linalg.vec3 import dot3s
from physics.presets import DEFAULT_PRESET, RETIRED_PRESETS, retired_preset_message
from physics.validation import require_finite

#: With the target behind, or ``line_weight`` > 0, the planner re-plans every control step while no turn helps;
#: the surrogate every this, s (elsewhere it computes when the plan changes).
RECHECK_S = 1.0
#: How many RECHECK_S samples one look ahead with the target behind covers.
BEHIND_SAMPLES = 20


class SurrogateTurnEnv(TurnEpisodes, gym.Env):
    """
    ## Description

    ``FlagellumTurn-v0`` (``agents.turn_decision_env.TurnDecisionEnv``, whose docstring is the manual) on the
    turn-level surrogate swimmer (module docstring): ~10^4 decisions per CPU second instead of ~0.5.

    ## Spaces, rewards, ``info``

    ``FlagellumTurn-v0``'s with ``planner="rule"``: observation ``Box(-10, 10, (14,), float32)``, action
    ``Box(-1, 1, (2,), float32)``, the same reward terms and weights, ``info`` keys ``INFO_KEYS`` plus
    ``out_of_range`` (bool, the episode so far) and, when it is True, ``out_of_range_reason``.

    ## Arguments

    ``FlagellumTurn-v0``'s. Within ``env_kwargs`` the surrogate uses ``reward``, ``randomize`` (E, mu, the head
    radius and the helix geometry: the turn's timing, ``agents.surrogate_swimmer``; ``obs_noise_std``: no effect,
    the features are computed from the exact state), ``reach_radius_m``, ``max_sim_time_s``, ``time_factor``,
    ``off_path_m``, ``control_dt``,
    ``n_lookahead``, ``buckling_threshold``; the rest is validated as ``FlagellumSteer-v0`` validates it and has
    nothing to act on. ``render_mode`` must be None (no rod to draw). Outside the calibrated range (module
    docstring): ``ValueError`` naming the value and what is allowed.

    ## Version History

    - v0: initial version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}
    env_id: ClassVar[str] = TURN_SURROGATE_ENV_ID
    default_preset: ClassVar[str] = DEFAULT_PRESET

    def __init__(self, preset: str | None = None, turn_map: str | os.PathLike | None = None,
                 env_kwargs: Mapping[str, Any] | None = None, paths: Sequence[Any] | None = None,
                 random_path: Mapping[str, Any] | None = None, limits: ResidualLimits | Mapping[str, Any] | None = None,
                 action_cost: float = DEFAULT_ACTION_COST, render_mode: str | None = None, planner: str = "rule",
                 **unknown: Any) -> None:
        refuse_unknown_arguments(self.env_id, unknown)
        kind, _, planner_config = base_planner(planner)
        if kind != "rule":
            raise ValueError(f"planner={planner!r} is not available in {self.env_id}; allowed: 'rule' or "
                             "'rule@line=W' (the adaptive planner's online map reads the rod's cruise)")
        self.render_mode = None
        self.preset, self.config, self.turn_map, self.calibration = surrogate_setup(
            self.env_id, self.default_preset if preset is None else preset, turn_map, env_kwargs, render_mode,
            CONTROLLER_ENV_DEFAULTS[kind])
        cfg, tmap = self.config, self.turn_map
        self.table = TurnMapTable(tmap)
        self.params = tmap.params
        self.planner = RulePlanner(tmap, None, cfg.control_dt, DEFAULT_REACH_RADIUS_M, None, planner_config)
        self.limits = residual_limits(limits) or ResidualLimits()
        self.action_cost = require_finite("action_cost", action_cost, 0.0)
        self.paths = fixed_paths(paths)
        self.set_random_path(DEFAULT_RANDOM_PATH if random_path is None else random_path)
        self.observation_space = spaces.Box(-10.0, 10.0, (self.planner_features,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._max_theta = tmap.max_theta_deg
        pcfg = self.planner.config
        self._line = pcfg.line_weight > 0.0
        self._frames = self.planner.episode_frames(None)
        t_c, theta, psi, _ = self.planner.candidate_turns(None)
        #: the candidate turns' burst lengths (s), theta and psi (rad), and the burst phases (rad), for plan_or_cruise
        self._candidates, self._phases = np.stack([t_c, theta, psi]), self.planner.burst_phases
        self._curves = tmap.turn_curves()
        #: the plan (PLAN_SIZE) and the last turn flown (PREV_SIZE)
        self._plan, self._prev = np.zeros(PLAN_SIZE), np.zeros(PREV_SIZE)
        #: the hover's and relaxation's wait bounds (s): two map periods, max_relax_factor x the map's median
        self._relax_wait_s = (2 * self.planner.period_steps * cfg.control_dt, pcfg.max_relax_factor * tmap.relax_s)
        self._episode = 0
        self._swimmer_rng: np.random.Generator | None = None
        self._warned = False
        self._done = True

    planner_features: ClassVar[int] = 14  # agents.residual_planner.N_FEATURES (checked by the tests)

    # --- Gymnasium API ---------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        path = self._episode_path(seed, options)
        if seed is not None or self._swimmer_rng is None:
            # the physics env's own generator, seeded alike: the same seed draws the same swimmer there and here
            self._swimmer_rng, _ = seeding.np_random(seed)
        cfg = self.config
        params, _ = draw_randomization(self.params, cfg.randomize, self._swimmer_rng)
        self.swimmer = SurrogateSwimmer(self.turn_map, self.calibration, self.table, params)
        self.episode_params = params
        self.path = path
        reach = cfg.reach_radius_m or path.reach_radius_m or DEFAULT_REACH_RADIUS_M
        self.tracker = PathTracker(path, reach)
        self.planner.reach_radius_m = reach
        pcfg = self.planner.config
        self._checks = np.array([pcfg.hit_fraction * reach, pcfg.min_turn_deg, pcfg.improvement_m, pcfg.hit_fraction,
                                 math.tan(math.radians(pcfg.min_turn_deg)), pcfg.line_weight])
        max_time = (cfg.max_sim_time_s if cfg.max_sim_time_s is not None
                    else cfg.time_factor * path.length_m / self.calibration.cruise_speed_m_s)
        self.max_steps = max(1, math.ceil(max_time / cfg.control_dt - 1e-9))
        self.time_limit_s = self.max_steps * cfg.control_dt
        self.episode = SurrogateEpisode(self.swimmer, self.tracker, cfg, self.time_limit_s)
        self._ep = PlannerEpisode() if self._line else None
        self._planned = False
        self._n_turns = 0
        self._feature_consts = np.array([reach, self.calibration.cruise_end_to_end_ratio, self.max_steps,
                                         cfg.control_dt, self._max_theta])
        self._done = False
        # the planner measures a heading after one period at omega_l (RulePlanner._decide, cruise)
        end = self.episode.cruise((self.planner.period_steps + 1) * cfg.control_dt)
        if end is None:
            end = self._advance()
        self._pending = (self.episode.reward(), end)
        return self._features(), self._info()

    @property
    def heading(self) -> np.ndarray:
        """The swimmer's heading now, (3,) unit."""
        return self.episode.heading

    @property
    def last_turn(self) -> dict[str, Any] | None:
        """The last turn flown in this episode (None before the first): ``heading`` (the heading it was planned
        from, [3] unit), ``predicted_theta_deg`` and ``predicted_azimuth`` (rad), as ``corrected_plan`` predicts
        them."""
        if self._n_turns == 0:
            return None
        prev = self._prev
        return {"heading": prev[0:3].tolist(), "predicted_theta_deg": float(prev[PREV_THETA_DEG]),
                "predicted_azimuth": float(prev[PREV_AZIMUTH])}

    def step(self, action: Any):
        if self._done:
            raise RuntimeError("call reset() before step()")
        a = parse_turn_action(action)
        reward, end = self._pending
        self._pending = (0.0, None)
        if end is None:
            a0, a1 = clipped_residual(a)
            plan, prev, lim = self._plan, self._prev, self.limits
            t_c, phase, prev[PREV_THETA_DEG], prev[PREV_AZIMUTH] = corrected_turn(
                plan[PLAN_T_C], plan[PLAN_PHASE], a0, a1, lim.max_dtc_fraction, lim.max_dphase_deg, *self._curves)
            prev[0:3] = plan[PLAN_HEADING:PLAN_HEADING + 3]  # the planner's last turn (the next features')
            self._n_turns += 1
            end = self._turn(t_c, phase)
            if end is None:
                end = self._advance()
            reward += self.episode.reward() - self.action_cost * dot3s(a0, a1, 0.0, a0, a1, 0.0)  # a @ a
        terminated, truncated = end if end is not None else (False, False)
        self._done = terminated or truncated
        return self._features(), float(reward), bool(terminated), bool(truncated), self._info()

    # --- the planner's loop, event by event ---------------------------------------------------
    def _advance(self) -> tuple[bool, bool] | None:
        """Cruise until the planner plans a turn (``self._plan``, ``PLAN_SIZE``; returns None) or the episode ends
        (returns (terminated, truncated))."""
        pl, tr, run = self.planner, self.tracker, self.episode
        st, table, consts, checks = run.state, run.frames.table, run.consts, self._checks
        while True:
            if self._line:  # the line score moves with the segment: the planner's own plan (rule_plan)
                target = tr.path.waypoints[tr.index]
                pl.track_segment(self._ep, target)
                plan = pl.rule_plan(run.head, run.heading, target, self._ep, paper_line_miss)
                if plan is not None:
                    self._plan[:] = (plan["t_c"], plan["theta_deg"], plan["predicted_miss_m"],
                                     plan["miss_straight_m"], *plan["heading"], plan["burst_phase"])
                    self._planned = True
                    return None
                end = run.cruise(next_check_s(self._frames, st, target, consts, checks))
            else:  # the paper's rule without a line (the same plan, agents.candidate_miss.paper_rule_choice)
                wanted, k, reached, how = plan_or_cruise(st, self._frames, self._candidates, self._phases, tr.index,
                                                         table, consts, checks, self._plan)
                if wanted < 0:
                    angle_between(run.heading, tr.path.waypoints[tr.index] - run.head)  # raises: no direction
                if k >= 0:
                    self._planned = True
                    return None
                end = run.collect(reached, how)
            if end is not None:
                return end

    def _turn(self, t_c: float, phase: float) -> tuple[bool, bool] | None:
        """Fly a decided turn of ``t_c`` s at the burst phase ``phase`` rad (module docstring, 3.): hover, burst,
        relax."""
        dt, run = self.config.control_dt, self.episode
        end = run.turn(max(1, round(t_c / dt)) * dt, phase, self._relax_wait_s[0], self._relax_wait_s[1])
        if run.out_of_range is not None and not self._warned:
            self._warned = True
            gym.logger.warn(f"{self.env_id}: {run.out_of_range}; reported in info['out_of_range']")
        return end

    # --- what the agent sees ----------------------------------------------------------------
    def _features(self) -> np.ndarray:
        out = np.zeros(self.planner_features, np.float32)
        if self._done or self._pending[1] is not None or not self._planned:
            return out
        run = self.episode
        if not episode_features(self._plan, self._prev, self._n_turns, run.state, run.frames.table,
                                self.tracker.index, self.config.n_lookahead, self._feature_consts, out):
            d = self._plan[PLAN_HEADING:PLAN_HEADING + 3]
            feature_error(d, self.tracker.targets(self.config.n_lookahead) - run.head,
                          self._prev[0:3] if self._n_turns else d)
        return out

    def _info(self) -> dict[str, Any]:
        return surrogate_info(self.path.name, self.tracker, self.episode, self._n_turns)


def surrogate_setup(env_id: str, preset: str, turn_map: str | os.PathLike | None,
                    env_kwargs: Mapping[str, Any] | None, render_mode: str | None, defaults: Mapping[str, Any]
                    ) -> tuple[str, SteerConfig, TurnMap, SurrogateCalibration]:
    """(preset, config, turn map, calibration) of a surrogate env, ``env_kwargs`` (``turn_env_kwargs``: None is
    ``DEFAULT_ENV_KWARGS``) merged over ``defaults``; ValueError (one line, naming the value and what is allowed) for
    a request outside the calibration (``_check_calibrated``), a rendering or a bad argument."""
    if render_mode is not None:
        raise ValueError(f"render_mode={render_mode!r} is not allowed in {env_id} (no rod to draw); allowed: None")
    if preset in RETIRED_PRESETS:
        raise ValueError(retired_preset_message(preset))
    if preset != DEFAULT_PRESET:
        raise ValueError(f"preset={preset!r} is outside the surrogate's calibration; allowed: "
                         f"{DEFAULT_PRESET!r} (the map it replays)")
    try:
        cfg = make_config(**{**defaults, "preset": preset, **turn_env_kwargs(env_kwargs)})
    except ValueError as exc:
        raise ValueError(f"env_kwargs: {exc}") from None
    tmap = load_turn_map(turn_map, preset)
    calibration = SurrogateCalibration.load(calibration_file(DEFAULT_PRESET))
    _check_calibrated(cfg, tmap, calibration)
    return preset, cfg, tmap, calibration


def _check_calibrated(cfg, tmap: TurnMap, calibration: SurrogateCalibration) -> None:
    """ValueError (one line, naming the value and what is allowed) for a request outside the calibration."""
    for name in ("params", "numerics"):
        if getattr(cfg, name):
            raise ValueError(f"env_kwargs[{name!r}]={getattr(cfg, name)!r} is outside the surrogate's calibration; "
                             f"allowed: none (the swimmer of the map, {tmap.preset!r}); vary it with randomize=")
    if cfg.low_speed_rpm != tmap.omega_l_rpm or calibration.omega_l_rpm != tmap.omega_l_rpm:
        raise ValueError(f"low motor speed {cfg.low_speed_rpm!r} rpm is outside the surrogate's calibration; "
                         f"allowed: the map's omega_l = {tmap.omega_l_rpm} rpm")
    if cfg.action_type == "continuous":
        lo, hi = cfg.omega_range_rpm
        if not lo <= tmap.omega_h_rpm <= hi:
            raise ValueError(f"omega_range_rpm={cfg.omega_range_rpm!r} does not reach the map's omega_h = "
                             f"{tmap.omega_h_rpm} rpm; allowed: a range holding it")
    elif tmap.omega_h_rpm not in cfg.discrete_speeds_rpm:
        raise ValueError(f"discrete_speeds_rpm={cfg.discrete_speeds_rpm!r} lacks the map's omega_h = "
                         f"{tmap.omega_h_rpm} rpm; allowed: speeds holding it")
    if cfg.observation_type != "flat":
        raise ValueError(f"observation_type={cfg.observation_type!r}: the rule planner reads flat observations; "
                         "allowed: 'flat'")
    r = cfg.randomize
    if r is not None:
        lo, hi = FACTOR_RANGE
        for name in ("youngs_modulus", "viscosity", "head_radius", "geometry"):
            f = getattr(r, name)
            if not (lo <= 1.0 - f and 1.0 + f <= hi):
                raise ValueError(f"randomize {name}={f:g} draws factors from {1 - f:.3g} to {1 + f:.3g}, outside the "
                                 f"surrogate's calibrated range [{lo}, {hi}]; allowed: fractions up to "
                                 f"{min(1 - lo, hi - 1):.2g}")


#: ``SurrogateTurnEnv``'s planner constants for ``plan_or_cruise`` and ``next_check_s``, float64 (CHECKS_SIZE,): the
#: miss below which no turn is wanted (m), ``min_turn_deg`` (deg), ``improvement_m`` (m), ``hit_fraction``,
#: tan(``min_turn_deg``) and ``line_weight`` (``PlannerConfig``).
HIT_MISS, MIN_TURN_DEG, IMPROVEMENT, HIT_FRACTION, TAN_MIN_TURN, LINE_WEIGHT = 0, 1, 2, 3, 4, 5
CHECKS_SIZE = 6


@njit(cache=True)
def next_check_s(frames: np.ndarray, state: np.ndarray, target: np.ndarray, consts: np.ndarray, checks: np.ndarray
                 ) -> float:
    """How long (s, whole control steps) to swim straight before the plan can change (module docstring, 1.), from
    the head and heading of ``state`` (``agents.surrogate_legs.STATE_SIZE``) with the target ``target`` (3,) m:
    ``frames`` the planner's candidate frames (``RulePlanner.episode_frames``), ``consts`` the legs' constants
    (``LEG_SIZE``: the cruise speed, the reach radius, the control step), ``checks`` the planner's (``CHECKS_SIZE``)."""
    head, d = state[0:3], state[HEADING:HEADING + 3]
    v, reach, dt = consts[SPEED], consts[REACH], consts[DT]
    r0, r1, r2 = target[0] - head[0], target[1] - head[1], target[2] - head[2]
    along = dot3s(r0, r1, r2, d[0], d[1], d[2])
    lateral = math.sqrt(max(dot3s(r0, r1, r2, r0, r1, r2) - along * along, 0.0))
    if along <= 0.0:
        # the target behind: swimming on's miss grows; the first of the next BEHIND_SAMPLES samples
        # RECHECK_S apart at which a turn helps (agents.candidate_miss.first_improving_sample)
        q0, q1, q2 = target_in_frame(head, d, target)
        k = first_improving_sample(frames, q0, q1, q2, BEHIND_PENALTY_M, checks[IMPROVEMENT], v * RECHECK_S,
                                   BEHIND_SAMPLES)
        wait = (k if k > 0 else BEHIND_SAMPLES) * RECHECK_S
    elif lateral < checks[HIT_FRACTION] * reach:
        wait = along / v  # on course: nothing changes before the target is reached (or abeam)
        if lateral < reach:
            wait = (along - math.sqrt(reach * reach - lateral * lateral)) / v
    else:
        # off course: the plan is the same until the heading error passes min_turn_deg, a candidate turn
        # improves the miss by improvement_m (agents.candidate_miss.first_improving_distance) or the target
        # comes abeam; with line_weight > 0 the score moves too: re-plan every RECHECK_S
        start = along - lateral / checks[TAN_MIN_TURN]
        wait = along / v
        if lateral < reach:
            x = (along - math.sqrt(reach * reach - lateral * lateral)) / v
            if x < wait:
                wait = x
        if start > 0.0:
            if start / v < wait:
                wait = start / v
        elif checks[LINE_WEIGHT] > 0.0:
            if RECHECK_S < wait:
                wait = RECHECK_S
        else:
            q0, q1, q2 = target_in_frame(head, d, target)
            x = first_improving_distance(frames, q0, q1, q2, BEHIND_PENALTY_M, lateral - checks[IMPROVEMENT], 0.0,
                                         along) / v
            if x < wait:
                wait = x
    return max(1, math.ceil(wait / dt - 1e-9)) * dt


@njit(cache=True)
def plan_or_cruise(state: np.ndarray, frames: np.ndarray, candidates: np.ndarray, beta: np.ndarray, index: int,
                   table: np.ndarray, consts: np.ndarray, checks: np.ndarray, plan: np.ndarray
                   ) -> tuple[int, int, int, int]:
    """One event of the planner's loop without a line score: the rule planner's plan at the head and heading of
    ``state`` with the target waypoint ``index`` (``paper_rule_choice``; ``frames`` its argument) written to
    ``plan`` (``PLAN_SIZE``; ``candidates`` (3, T): the candidate turns' t_c s, theta and psi rad, ``beta`` (B,) the
    burst phases rad, ``RulePlanner.plan_of``'s), or, with no turn chosen, the cruise to the
    next check (``next_check_s``, ``cruise_state``; ``table`` and ``consts`` the legs'). Returns (``turn_wanted``,
    the chosen candidate's flat index or -1, the waypoints reached, how the cruise ended:
    ``agents.surrogate_legs.GOES_ON`` ...)."""
    head, d = state[0:3], state[HEADING:HEADING + 3]
    target = table[index, 7:10]
    wanted, miss0, k, best = paper_rule_choice(head, d, target, frames, BEHIND_PENALTY_M, checks[HIT_MISS],
                                               checks[MIN_TURN_DEG], checks[IMPROVEMENT])
    if wanted < 0:
        return wanted, -1, 0, GOES_ON
    if k >= 0:
        i, j = divmod(k, beta.shape[0])
        plan[PLAN_T_C], plan[PLAN_THETA_DEG], plan[PLAN_PHASE], _ = candidate_plan(
            candidates[0], candidates[1], candidates[2], beta, i, j)
        plan[PLAN_MISS], plan[PLAN_MISS_STRAIGHT] = best, miss0
        plan[PLAN_HEADING], plan[PLAN_HEADING + 1], plan[PLAN_HEADING + 2] = d[0], d[1], d[2]
        return wanted, k, 0, GOES_ON
    reached, how = cruise_state(state, next_check_s(frames, state, target, consts, checks), True, index, table,
                                consts)
    return wanted, -1, reached, how


#: A plan of ``SurrogateTurnEnv`` (float64, PLAN_SIZE): its burst length (s), theta (deg), its miss and swimming on's
#: (m), the heading it was planned from (3, unit) and its burst phase (rad) (``RulePlanner.plan_of``'s numbers).
PLAN_T_C, PLAN_THETA_DEG, PLAN_MISS, PLAN_MISS_STRAIGHT, PLAN_HEADING, PLAN_PHASE = 0, 1, 2, 3, 4, 7
PLAN_SIZE = 8
#: The last turn flown (float64, PREV_SIZE): the heading it was planned from (3, unit), the corrected turn's predicted
#: theta (deg) and azimuth (rad) (``corrected_turn``).
PREV_THETA_DEG, PREV_AZIMUTH = 3, 4
PREV_SIZE = 5
#: ``episode_features``' constants (float64, 5): the reach radius (m), L'/L while cruising, the time budget
#: (control steps), the control step (s) and the map's largest turn (deg).
F_REACH, F_RATIO, F_MAX_STEPS, F_DT, F_MAX_THETA = 0, 1, 2, 3, 4


@njit(cache=True)
def episode_features(plan: np.ndarray, prev: np.ndarray, n_turns: int, state: np.ndarray, table: np.ndarray,
                     index: int, n_lookahead: int, fconsts: np.ndarray, out: np.ndarray) -> bool:
    """``turn_features`` of the plan ``plan`` (``PLAN_SIZE``) after ``n_turns`` turns, the last ``prev``
    (``PREV_SIZE``), from the head and time of ``state`` with the next ``n_lookahead`` waypoints from ``index`` on
    (``table``: ``SegmentFrames.table``; the last repeated, ``PathTracker.targets``) and ``fconsts`` (``F_REACH``
    ...), written to ``out`` (N_FEATURES,) float32 (``feature_vector``; False: a direction it measures an angle of
    was zero or not finite)."""
    last = table.shape[0] - 1
    targets = np.empty((n_lookahead, 3))
    for k in range(n_lookahead):
        w = min(index + k, last)
        targets[k, 0], targets[k, 1], targets[k, 2] = (table[w, 7] - state[0], table[w, 8] - state[1],
                                                       table[w, 9] - state[2])
    steps = math.floor(state[TIME] / fconsts[F_DT] + 1e-9)
    time_left = 1.0 - steps / int(fconsts[F_MAX_STEPS])
    if not time_left > 0.0:
        time_left = 0.0
    d = plan[PLAN_HEADING:PLAN_HEADING + 3]
    had = n_turns > 0
    return feature_vector(plan[PLAN_THETA_DEG], plan[PLAN_T_C], plan[PLAN_MISS], plan[PLAN_MISS_STRAIGHT], d, targets,
                          fconsts[F_REACH], fconsts[F_RATIO], time_left, n_turns, fconsts[F_MAX_THETA], had,
                          prev[0:3] if had else d, prev[PREV_THETA_DEG] if had else 1.0,
                          prev[PREV_AZIMUTH] if had else 0.0, out)
