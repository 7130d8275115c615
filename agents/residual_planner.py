"""The turn planner with a learned correction of each turn it plans (residual policy learning).

The rule planner (``agents.turn_planner``) chooses every turn from the turn map: a burst length
t_c (hence a turning angle theta) and the flagellum phase beta at which to burst. The map is a
calibration of the nominal swimmer, averaged over phases and measured from a fully relaxed
straight start; a real turn differs (the flagellum may not have relaxed, the parameters may be
off by some per cent, which moves the buckling time and so the turn). ``ResidualPlanner`` asks a
*residual policy* for a correction of each planned turn,

    t_c' = t_c * (1 + a_0 * max_dtc_fraction),     beta' = beta + a_1 * max_dphase_deg,

with the action a in [-1, 1]^2 (a = 0 is the rule planner's plan; Silver et al. 2018, "Residual
policy learning", and Johannink et al. 2019, "Residual reinforcement learning for robot
control", use the same split: a model-based controller plus a learned correction). The burst
length is scaled because a parameter error rescales time: the viscous time mu L^4 / EI sets
when the flagellum buckles. Everything else (hovering to the phase, the burst, waiting for a
steady heading, re-planning) is the rule planner's. ``turn_features`` is what the policy sees at
a decision (``N_FEATURES`` numbers, each O(1)), including how the previous turn came out
against its prediction, so that a policy can adapt to a swimmer that differs from the map.

Two ways to supply the correction:

- ``policy``: a callable ``features (N_FEATURES,) float32 -> action (2,)``, called at once (a
  trained agent, ``agents.ppo_policy``);
- no policy (training, ``agents.turn_decision_env``): the planner stops at each planned turn
  with ``awaiting`` set to the features and keeps cruising until ``decide(action)`` is called;
  the next control step re-plans and flies the corrected turn.

Two planners to correct: ``ResidualPlanner`` corrects the rule planner; ``AdaptiveResidualPlanner`` corrects the
adaptive planner (``agents.adaptive_planner``, the best planner on swimmers that differ from the map), whose
corrected turn keeps the online map's timing (the corrected burst's map time, ratio clock and longest burst:
``corrected_adaptive_plan``) and whose features add the online map's state (``map_features``: the buckling-time
shift and its uncertainty, the ratio clock's bias, the direction offset, whether the swimmer still follows the
map and whether turns have confirmed it), so that a policy can learn what the planner's correction misses.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

from agents.turn_geometry import angle_between, angle_of, azimuth, azimuth_of, norm3, wrap_angle
from agents.adaptive_planner import AdaptiveConfig, AdaptivePlanner
from agents.controller_spec import controller_kind, controller_options
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap
from agents.turn_map import TurnMap, branch_theta_deg, psi_deg_at
from agents.turn_planner import PlannerConfig, RulePlanner, PlannerEpisode
from physics.validation import require_finite

#: Length of the feature vector the residual policy of the rule planner sees.
N_FEATURES = 14
#: Features of the online map's state (``map_features``) and the length of the vector the residual policy of
#: the adaptive planner sees (``turn_features`` then ``map_features``).
N_MAP_FEATURES = 6
N_ADAPTIVE_FEATURES = N_FEATURES + N_MAP_FEATURES
#: Distances in the features are in units of this, m (about a path segment).
FEATURE_LENGTH_M = 0.1


@dataclass(frozen=True)
class ResidualLimits:
    """How far the residual may move a planned turn: the burst length by up to the fraction
    ``max_dtc_fraction`` (in (0, 1)), the burst phase by up to ``max_dphase_deg`` (degrees, > 0).

    The defaults are the first agent's (its config retired with its preset; in git history): 5 % of the
    burst and 15 degrees."""

    max_dtc_fraction: float = 0.05
    max_dphase_deg: float = 15.0

    def __post_init__(self) -> None:
        for name, hi in (("max_dtc_fraction", 1.0), ("max_dphase_deg", 180.0)):
            object.__setattr__(self, name, require_finite(f"ResidualLimits.{name}", getattr(self, name), 0.0, hi,
                                                          lo_open=True, hi_open=True))


def turn_features(plan: dict, targets: np.ndarray, reach_radius_m: float, end_to_end_ratio: float,
                  time_left: float, previous: dict | None, n_turns: int, max_theta_deg: float) -> np.ndarray:
    """What the residual policy sees when a turn is planned, (N_FEATURES,) float32.

    plan: the rule planner's plan (``RulePlanner._plan_turn``: t_c, theta_deg, predicted and
    straight misses, heading). targets: (W, 3) the next waypoints minus the head, start frame, m
    (W = n_lookahead; the second repeats the first on the last segment). previous: the last turn
    flown in this episode (a ``corrected_plan``), or None.

    Features: planned theta / map maximum; planned t_c / 10 s; predicted miss and straight miss /
    reach radius; distance to the target / 0.1 m; angle between heading and target / 90 deg;
    the turn at the target (angle between the two segments) / 90 deg and the next segment's
    length / 0.1 m; L'/L; fraction of the time budget left; turns so far / 5; and the previous
    turn's outcome: 1 if there was one, its actual / predicted turning angle, and the error of
    its direction (azimuth about the old heading, actual - predicted) / 90 deg (0, 1, 0 without one).
    """
    d = np.asarray(plan["heading"], dtype=np.float64)
    targets = np.asarray(targets, dtype=np.float64)
    had = previous is not None and "predicted_theta_deg" in previous
    d0 = np.asarray(previous["heading"], dtype=np.float64) if had else d
    f = np.empty(N_FEATURES, dtype=np.float32)
    ok = feature_vector(plan["theta_deg"], plan["t_c"], plan["predicted_miss_m"], plan["miss_straight_m"], d, targets,
                        reach_radius_m, end_to_end_ratio, time_left, n_turns, max_theta_deg, had, d0,
                        previous["predicted_theta_deg"] if had else 1.0, previous["predicted_azimuth"] if had else 0.0,
                        f)
    if not ok:
        feature_error(d, targets, d0)
    return f


def feature_error(d: np.ndarray, targets: np.ndarray, d0: np.ndarray) -> None:
    """For features ``feature_vector`` found no angle of (a zero or non-finite direction): the ValueError of the
    geometry that cannot take it. d, d0 (3,) the headings, targets (W, 3) m (``turn_features``)."""
    angle_between(d, targets[0]), angle_between(d0, d), azimuth(d, d0)
    if len(targets) > 1:
        angle_between(targets[0], targets[1] - targets[0])


@njit(cache=True)
def feature_vector(theta_deg: float, t_c: float, miss_m: float, miss_straight_m: float, d: np.ndarray,
                   targets: np.ndarray, reach_radius_m: float, end_to_end_ratio: float, time_left: float,
                   n_turns: int, max_theta_deg: float, had_previous: bool, d0: np.ndarray,
                   previous_theta_deg: float, previous_azimuth: float, out: np.ndarray) -> bool:
    """``turn_features`` (its docstring) compiled: the features written to ``out`` (N_FEATURES,) float32; False if a
    direction it measures an angle of was zero or not finite. The plan's theta_deg (deg), t_c (s), miss_m and miss_straight_m
    (m), the heading ``d`` (3,) unit; ``targets`` (W, 3) m; the previous turn's heading ``d0`` (3,), its predicted
    theta (deg) and azimuth (rad), read if ``had_previous``."""
    to_target = targets[0]
    after = targets[1] - targets[0] if targets.shape[0] > 1 else np.zeros(3)
    next_len = norm3(after)
    corner = angle_of(to_target, after) if next_len > 1e-9 else 0.0
    had, ratio, az_err = 0.0, 1.0, 0.0
    if had_previous:
        had = 1.0
        ratio = math.degrees(angle_of(d0, d)) / max(previous_theta_deg, 1.0)
        az_err = math.degrees(wrap_angle(azimuth_of(d, d0) - previous_azimuth)) / 90.0
    heading_error = angle_of(d, to_target)
    ok = not (math.isnan(corner) or math.isnan(ratio) or math.isnan(az_err) or math.isnan(heading_error))
    f = np.array([
        theta_deg / max_theta_deg,
        t_c / 10.0,
        miss_m / reach_radius_m,
        miss_straight_m / reach_radius_m,
        norm3(to_target) / FEATURE_LENGTH_M,
        math.degrees(heading_error) / 90.0,
        math.degrees(corner) / 90.0,
        next_len / FEATURE_LENGTH_M,
        end_to_end_ratio,
        time_left,
        n_turns / 5.0,
        had,
        ratio,
        az_err,
    ])
    _bounded_into(f, out)
    return ok


def bounded(f: np.ndarray) -> np.ndarray:
    """Features as the policy sees them: NaN -> 0, clipped to [-10, 10] (+-inf to +-10), float32; f (n,) float64."""
    out = np.empty(f.shape[0], dtype=np.float32)
    _bounded_into(np.asarray(f, dtype=np.float64), out)
    return out


@njit(cache=True)
def _bounded_into(f: np.ndarray, out: np.ndarray) -> None:
    """``bounded``'s features written to ``out`` (n,) float32."""
    for i in range(f.shape[0]):
        x = f[i]
        out[i] = 0.0 if math.isnan(x) else min(max(x, -10.0), 10.0)


def corrected_plan(plan: dict, action: np.ndarray, turn_map: TurnMap, limits: ResidualLimits) -> dict:
    """The plan with the residual ``action`` (2,) in [-1, 1] applied (module docstring), with the
    map's prediction of the corrected turn: ``predicted_theta_deg`` (the rising branch, held at
    its maximum beyond it) and ``predicted_azimuth`` (rad, of the new heading about the old one in
    ``perpendicular_basis(heading)``, as the planner predicts it: phase + psi)."""
    a0, a1 = clipped_residual(action)
    t_c, phase, theta_deg, azimuth_rad = corrected_turn(float(plan["t_c"]), float(plan["burst_phase"]), a0, a1,
                                                        limits.max_dtc_fraction, limits.max_dphase_deg,
                                                        *turn_map.turn_curves())
    out = dict(plan)
    out.update(t_c=t_c, burst_phase=phase, residual=[a0, a1],
               planned_t_c=float(plan["t_c"]), planned_theta_deg=float(plan["theta_deg"]),
               predicted_theta_deg=theta_deg, predicted_azimuth=azimuth_rad)
    return out


def clipped_residual(action: np.ndarray) -> tuple[float, float]:
    """The residual action (2,) clipped to [-1, 1] (``np.clip``'s), (a_0, a_1); ValueError unless it is two finite
    numbers."""
    a = np.asarray(action, dtype=np.float64).reshape(-1)
    a0, a1 = a.tolist() if a.size == 2 else (math.nan, math.nan)
    a0, a1 = min(max(a0, -1.0), 1.0), min(max(a1, -1.0), 1.0)  # np.clip's
    if not (math.isfinite(a0) and math.isfinite(a1)):
        raise ValueError(f"residual action={action!r} must be two finite numbers in [-1, 1]")
    return a0, a1


@njit(cache=True)
def corrected_turn(t_c: float, burst_phase: float, a0: float, a1: float, max_dtc_fraction: float,
                   max_dphase_deg: float, branch_t: np.ndarray, branch_theta_deg_: np.ndarray, psi_t: np.ndarray,
                   psi_unwrapped_deg: np.ndarray) -> tuple[float, float, float, float]:
    """A planned turn (``t_c`` s, ``burst_phase`` rad) with the clipped residual (a0, a1) applied (module
    docstring; ``ResidualLimits``' ``max_dtc_fraction`` and ``max_dphase_deg``) and the map's prediction of it
    (``TurnMap.turn_curves``' four arrays): (t_c' s, phase' rad, predicted theta deg (``TurnMap.theta_for``),
    predicted azimuth rad of the new heading about the old one, phase' + psi (``TurnMap.psi_for``))."""
    t = t_c * (1.0 + a0 * max_dtc_fraction)
    phase = wrap_angle(burst_phase + math.radians(a1 * max_dphase_deg))
    return (t, phase, branch_theta_deg(t, branch_t, branch_theta_deg_),
            wrap_angle(phase + math.radians(psi_deg_at(t, psi_t, psi_unwrapped_deg))))


def map_features(online: OnlineTurnMap) -> np.ndarray:
    """The online map's state as the residual policy sees it, (N_MAP_FEATURES,) float32: the buckling-time
    shift and its standard deviation (s), the ratio clock's bias (s), the direction offset / 90 deg, 1 if the
    swimmer still follows the map (``OnlineTurnMap.follows_model``) and 1 if turns have confirmed the map."""
    f = np.array([online.shift_s, online.shift_std_s, online.bias_s, math.degrees(online.psi_offset_rad) / 90.0,
                  float(online.follows_model), float(online.map_confirmed)])
    return bounded(f)


def corrected_adaptive_plan(plan: dict, action: np.ndarray, online: OnlineTurnMap, turn_map: TurnMap,
                            limits: ResidualLimits) -> dict:
    """An adaptive planner's plan with the residual ``action`` (2,) applied (``corrected_plan``), its
    prediction and timing kept consistent with the planner's: a turn chosen on the corrected map flies the
    corrected burst t_c' by the map's clock (``OnlineTurnMap.burst_plan(t_c')``: map time, ratio clock, longest
    burst) and is predicted at map time t_c' + shift (``turn_at``: ``theta_deg``, ``predicted_azimuth``); a
    turn chosen by the paper's rule (``follows_model``) keeps the rule's timing, its ``theta_deg`` the map's
    turn at t_c'. The planner learns from ``theta_deg`` and ``predicted_azimuth`` after the turn."""
    out = corrected_plan(plan, action, turn_map, limits)
    if plan.get("follows_model"):
        out["theta_deg"] = out["predicted_theta_deg"]
        return out
    timing = online.burst_plan(out["t_c"])
    theta, psi = online.turn_at(timing["map_t"])
    out.update(timing, theta_deg=math.degrees(theta), predicted_theta_deg=math.degrees(theta),
               predicted_azimuth=wrap_angle(out["burst_phase"] + psi))
    return out


class ResidualDecisions:
    """The residual policy's hooks on a planner (a mixin named before ``RulePlanner`` or one of its
    subclasses): ``awaiting`` / ``decide`` and the review of each planned turn (module docstring).
    ``n_features`` is the length of the feature vector."""

    n_features = N_FEATURES

    def _init_residual(self, end_slice: slice, time_slice: slice, limits: ResidualLimits | None,
                       policy: Callable[[np.ndarray], np.ndarray] | None) -> None:
        self.limits = limits or ResidualLimits()
        self.policy = policy
        self.end_slice, self.time_slice = end_slice, time_slice
        self.awaiting: np.ndarray | None = None
        self._decision: np.ndarray | None = None

    def reset(self) -> None:
        super().reset()  # type: ignore[misc]
        self.awaiting, self._decision = None, None

    def decide(self, action: np.ndarray) -> None:
        """The residual action for the turn in ``awaiting`` (flown from the next control step)."""
        if self.awaiting is None:
            raise RuntimeError("no planned turn is waiting for a decision")
        self._decision = np.asarray(action, dtype=np.float64).reshape(-1)
        self.awaiting = None

    def _review_plan(self, ep: PlannerEpisode, plan: dict, obs: np.ndarray) -> dict | None:
        if self._decision is not None:
            action, self._decision = self._decision, None
            return self._corrected(ep, plan, action)
        features = self._turn_features(ep, plan, obs)
        if self.policy is None:
            self.awaiting = features
            return None  # cruise on for this step; the next one flies the decided turn
        return self._corrected(ep, plan, self.policy(features))

    def _turn_features(self, ep: PlannerEpisode, plan: dict, obs: np.ndarray) -> np.ndarray:
        return turn_features(plan, ep.prev_rel, self.reach_radius_m, float(obs[self.end_slice][0]),
                             float(obs[self.time_slice][0]), ep.turns[-1] if ep.turns else None, len(ep.turns),
                             self.turn_map.max_theta_deg)

    def _corrected(self, ep: PlannerEpisode, plan: dict, action: np.ndarray) -> dict:
        return corrected_plan(plan, action, self.turn_map, self.limits)


class ResidualPlanner(ResidualDecisions, RulePlanner):
    """``RulePlanner`` whose planned turns are corrected by a residual policy (module docstring).

    policy: ``features -> action`` or None (then ``awaiting`` / ``decide``). The other
    arguments are ``RulePlanner``'s; ``end_slice`` and ``time_slice`` locate L'/L and the time
    left in the flat observation.
    """

    def __init__(self, turn_map: TurnMap, layout, control_dt: float, reach_radius_m: float, action_of,
                 end_slice: slice, time_slice: slice, config: PlannerConfig | None = None,
                 limits: ResidualLimits | None = None,
                 policy: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        RulePlanner.__init__(self, turn_map, layout, control_dt, reach_radius_m, action_of, config)
        self._init_residual(end_slice, time_slice, limits, policy)

    @classmethod
    def for_env(cls, env, turn_map: TurnMap, config: PlannerConfig | None = None,  # type: ignore[override]
                limits: ResidualLimits | None = None,
                policy: Callable[[np.ndarray], np.ndarray] | None = None) -> ResidualPlanner:
        """A residual planner for this env (the rule planner's checks apply)."""
        base = RulePlanner.for_env(env, turn_map, config)
        s = env.unwrapped.obs_model.slices()
        return cls(turn_map, base.layout, base.control_dt, base.reach_radius_m, base.action_of,
                   s["end_to_end_ratio"], s["time_left"], config, limits, policy)


class AdaptiveResidualPlanner(ResidualDecisions, AdaptivePlanner):
    """``AdaptivePlanner`` whose planned turns are corrected by a residual policy (module docstring): features
    ``turn_features`` then ``map_features`` (N_ADAPTIVE_FEATURES), corrections by ``corrected_adaptive_plan``.
    Arguments: ``ResidualPlanner``'s, then ``AdaptivePlanner``'s (``online``, ``carry_over``, ``reference``,
    ``adaptive``)."""

    n_features = N_ADAPTIVE_FEATURES

    def __init__(self, turn_map: TurnMap, layout, control_dt: float, reach_radius_m: float, action_of,
                 end_slice: slice, time_slice: slice, config: PlannerConfig | None = None,
                 limits: ResidualLimits | None = None, policy: Callable[[np.ndarray], np.ndarray] | None = None,
                 online: OnlineMapConfig | None = None, carry_over: bool = False, reference=None,
                 adaptive: AdaptiveConfig | None = None) -> None:
        AdaptivePlanner.__init__(self, turn_map, layout, control_dt, reach_radius_m, action_of, config, online,
                                 carry_over, end_slice, reference, adaptive)
        self._init_residual(end_slice, time_slice, limits, policy)

    @classmethod
    def for_env(cls, env, turn_map: TurnMap, config: PlannerConfig | None = None,  # type: ignore[override]
                limits: ResidualLimits | None = None, policy: Callable[[np.ndarray], np.ndarray] | None = None,
                online: OnlineMapConfig | None = None, carry_over: bool = False,
                adaptive: AdaptiveConfig | None = None) -> AdaptiveResidualPlanner:
        """A residual adaptive planner for this env, set up as ``AdaptivePlanner.for_env`` sets one up."""
        base = AdaptivePlanner.for_env(env, turn_map, config, online, carry_over, adaptive)
        s = env.unwrapped.obs_model.slices()
        return cls(turn_map, base.layout, base.control_dt, base.reach_radius_m, base.action_of,
                   s["end_to_end_ratio"], s["time_left"], config, limits, policy, base.online_config,
                   base.carry_over, base.reference, base.adaptive)

    def _turn_features(self, ep, plan: dict, obs: np.ndarray) -> np.ndarray:
        return np.concatenate([super()._turn_features(ep, plan, obs), map_features(ep.online)])

    def _corrected(self, ep, plan: dict, action: np.ndarray) -> dict:
        return corrected_adaptive_plan(plan, action, ep.online, self.turn_map, self.limits)


#: The planners a residual policy may correct, by name (``n_features``: the length of the feature vector it sees).
BASE_PLANNERS: dict[str, type[ResidualDecisions]] = {"rule": ResidualPlanner, "adaptive": AdaptiveResidualPlanner}


def base_planner(spec: str) -> tuple[str, type[ResidualDecisions], PlannerConfig | None]:
    """(kind, class, config) of the planner a residual policy corrects: ``rule`` or ``adaptive``, either optionally
    with ``@line=W`` and ``@cap=DEG`` (``PlannerConfig.from_options``, as in the controller specs,
    ``agents.controller_spec``); ValueError naming anything else."""
    allowed = f"{list(BASE_PLANNERS)}, either optionally with '@line=W' (W >= 0) and/or '@cap=DEG' (DEG > 0)"
    try:
        kind = controller_kind(spec)
        options = controller_options(spec)
    except ValueError:
        raise ValueError(f"planner={spec!r} is not allowed; choose one of {allowed}") from None
    if kind not in BASE_PLANNERS or ":" in spec:
        raise ValueError(f"planner={spec!r} is not allowed; choose one of {allowed}")
    return kind, BASE_PLANNERS[kind], PlannerConfig.from_options(options)
