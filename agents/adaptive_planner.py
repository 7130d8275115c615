"""The rule planner that calibrates its turn map on the swimmer as it swims.

``AdaptivePlanner`` is ``agents.turn_planner.RulePlanner`` with an ``OnlineTurnMap``
(``agents.online_turn_map``): after every turn, once the heading is steady, it measures the
angle turned and the direction of the new heading, updates its estimate of the swimmer's
buckling-time shift and direction offset, and plans the next turn from the corrected map,
and chooses each turn by its expected miss over the outcomes the corrected map allows
(``OnlineTurnMap.outcomes``: timing and direction errors, the direction's spread growing with the
turn's size until turns confirm the map; misses counted up to a scale, ``saturating_miss``), with
the 10 cm corridor around the current path segment as a soft limit. A turn that is not predicted to
do well now may be put off: the swimmer swims on (at most ``AdaptiveConfig.swim_on_m``, staying
near the segment) when the same choice made further on is predicted to miss by less. Bursts are
timed by the ratio clock (L'/L read as the map time the swimmer has reached, where it falls;
``OnlineMapConfig``) and may run past their planned length once the flagellum is seen to buckle
late. Everything else (hover to the phase, burst, relax,
re-plan from the measured heading) is the rule planner's.

A swimmer that cruises like the map's (the steady strain and rotation rate read before the first turn within
``OnlineMapConfig.cruise_match_tol`` of the map swimmer's: ``OnlineTurnMap.follows_model``) is steered by the
rule planner's own choice on the map, each burst flown by time, until a turn of at least
``OnlineMapConfig.psi_min_theta_deg`` comes out off the map (``OnlineTurnMap``'s confirmation test); from then on
by the corrections above. On the nominal swimmer its episodes are the rule planner's.

The correction is per episode by default (``carry_over=False``): each episode may be a
different swimmer (domain randomisation draws one per episode). ``carry_over=True`` keeps
what was learnt across episodes (one physical robot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from agents.online_turn_map import GAUSS_HERMITE_3, OnlineMapConfig, OnlineTurnMap
from agents.turn_map import TurnMap
from agents.turn_planner import (PlannerConfig, RulePlanner, PlannerEpisode, graded_line_miss, line_distance,
                                 paper_line_miss, pick_turn, turn_ends)
from agents.turn_geometry import angle_between, azimuth, perpendicular_basis, wrap_angle
from agents.turn_measurement import CruiseObservables, cruise_observables, summarise_cruise
from physics.validation import require_finite


@dataclass(frozen=True)
class AdaptiveConfig:
    """How the adaptive planner weighs a turn's outcome (lengths in m).

    corridor_m: the env's ``off_path_m`` (the episode ends farther than this from the current segment);
    a predicted head position beyond ``corridor_soft`` x corridor_m costs its excess (m per m), beyond
    ``corridor_hard`` x corridor_m 0.5 m (checked at the turn's end and after its forward travel).
    swim_on_m: how far the swimmer may swim on before a turn (0: never; checked every cm); swim_near_m: it
    stays this near the target, and within corridor_soft x corridor_m of the segment (swimming on to the hard
    limit left no room for the next turn's forward travel: development swimmers at +-5 % then left the corridor
    after a waypoint, 3 of 16 paths against 0 of 16 with the soft limit); swim_cost: cost per m swum
    (m/m); swim_gain_m: swimming on must lower the expected miss by more than this.
    late_onset_factor: a burst may run until the buckling seen (L'/L below ``OnlineMapConfig.ratio_valid``)
    plus this x the map's time from buckling to the planned map time, plus 0.5 s.
    miss_scale_m, miss_scale_fraction: a predicted miss m counts as c (1 - exp(-m / c)) (``saturating_miss``),
    c = max(miss_scale_m, miss_scale_fraction x the straight-line miss at the decision): misses much larger
    than c all cost about c (the swimmer turns again after a bad turn), so a large turn with a spread-out
    outcome is not ruled out by its unlikely worst cases; inf: the miss itself.
    Chosen on development paths (seeds 5200-5203 and 5300-5303, faithful, nominal and +-5/10 % swimmers).
    """

    corridor_m: float = 0.1
    corridor_soft: float = 0.6
    corridor_hard: float = 0.85
    swim_on_m: float = 0.10
    swim_near_m: float = 0.09
    swim_cost: float = 0.1
    swim_gain_m: float = 0.01
    late_onset_factor: float = 1.5
    miss_scale_m: float = 0.03
    miss_scale_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not (isinstance(self.miss_scale_m, (int, float)) and self.miss_scale_m > 0.0):
            raise ValueError(f"AdaptiveConfig.miss_scale_m must be > 0 (inf: no saturation), got {self.miss_scale_m!r}")
        require_finite("AdaptiveConfig.miss_scale_fraction", self.miss_scale_fraction, 0.0)
        for name in ("corridor_m", "corridor_soft", "corridor_hard", "swim_near_m", "late_onset_factor"):
            require_finite(f"AdaptiveConfig.{name}", getattr(self, name), 0.0, lo_open=True)
        for name in ("swim_on_m", "swim_cost", "swim_gain_m"):
            require_finite(f"AdaptiveConfig.{name}", getattr(self, name), 0.0)


def saturating_miss(miss, scale_m: float):
    """c (1 - exp(-miss / c)) for c = ``scale_m`` (m), elementwise: ~miss for misses much below c, -> c above
    it; ``scale_m`` = inf returns ``miss``."""
    if not math.isfinite(scale_m):
        return miss
    return scale_m * -np.expm1(-np.asarray(miss) / scale_m)


def segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of points (..., 3) from the segment a-b, shape (...)."""
    ab = b - a
    t = np.clip(((points - a) @ ab) / max(float(ab @ ab), 1e-18), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[..., None] * ab), axis=-1)


@dataclass
class AdaptiveEpisode(PlannerEpisode):
    online: OnlineTurnMap | None = None
    observed: int = 0                             # turns of ``turns`` already learnt from
    swim_until: np.ndarray | None = None          # swimming on (``AdaptiveConfig.swim_on_m``) until past this point
    swim_heading: np.ndarray | None = None
    strains: list[float] = field(default_factory=list)   # L'/L - 1 while cruising before the first turn
    azimuths: list[float] = field(default_factory=list)  # of the phase node about the first X_b, rad
    axis: np.ndarray | None = None
    cruise_used: bool = False
    cruise_reading: dict | None = None            # OnlineTurnMap.observe_cruise's, before the first turn


def cruise_reference(params, numerics, omega_l_rpm: float, phase_node: int, duration_s: float, sample_s: float,
                     settle_time_s: float | None = None) -> CruiseObservables:
    """What the map swimmer shows while cruising at omega_l from the env's steady start
    (``cruise_observables``, sampled as the planner samples; the start comes from the disk cache
    the env uses). Cached per configuration."""
    from flagellum_env.steady_start import get_steady_start
    from physics.params import RPM_TO_RAD_S

    settle = settle_time_s if settle_time_s is not None else 5 * 60.0 / omega_l_rpm
    key = (params, numerics, float(omega_l_rpm), int(phase_node), round(duration_s, 9), round(sample_s, 9),
           float(settle))
    if key not in _CRUISE_REFERENCE:
        start = get_steady_start(params, numerics, omega_l_rpm * RPM_TO_RAD_S, settle)
        _CRUISE_REFERENCE[key] = cruise_observables(start.new_simulator(), phase_node, duration_s, sample_s)
    return _CRUISE_REFERENCE[key]


_CRUISE_REFERENCE: dict = {}


class AdaptivePlanner(RulePlanner):
    """Rule planner with online map correction (module docstring); same constructor as
    ``RulePlanner`` plus ``online`` (``OnlineMapConfig``), ``carry_over``, for the cruise reading
    before the first turn ``end_slice`` (where L'/L is in the flat observation) and
    ``reference`` (the map swimmer's ``CruiseObservables``; None: no cruise reading), and
    ``adaptive`` (``AdaptiveConfig``: corridor, swim on, late bursts)."""

    def __init__(self, turn_map: TurnMap, layout, control_dt: float, reach_radius_m: float, action_of,
                 config: PlannerConfig | None = None, online: OnlineMapConfig | None = None,
                 carry_over: bool = False, end_slice: slice | None = None,
                 reference: CruiseObservables | None = None, adaptive: AdaptiveConfig | None = None) -> None:
        super().__init__(turn_map, layout, control_dt, reach_radius_m, action_of, config)
        self.adaptive = adaptive or AdaptiveConfig()
        self.end_slice, self.reference = end_slice, reference
        self.online_config = online or OnlineMapConfig()
        self.carry_over = bool(carry_over)
        self._shared: OnlineTurnMap | None = None

    @classmethod
    def for_env(cls, env, turn_map: TurnMap, config: PlannerConfig | None = None,  # type: ignore[override]
                online: OnlineMapConfig | None = None, carry_over: bool = False,
                adaptive: AdaptiveConfig | None = None) -> AdaptivePlanner:
        """An adaptive planner for this env (the rule planner's checks apply); the corridor is the env's
        ``off_path_m`` unless ``adaptive`` is given."""
        base = RulePlanner.for_env(env, turn_map, config)
        e = env.unwrapped
        reference = cruise_reference(e.params, e.numerics, e.low_speed_rpm, turn_map.phase_node,
                                     (base.period_steps + 1) * base.control_dt, base.control_dt, e.settle_time_s)
        adaptive = adaptive or AdaptiveConfig(corridor_m=e.config.off_path_m)
        return cls(turn_map, base.layout, base.control_dt, base.reach_radius_m, base.action_of, config, online,
                   carry_over, e.obs_model.slices()["end_to_end_ratio"], reference, adaptive)

    @property
    def online_map(self) -> OnlineTurnMap | None:
        """The first env's current correction (for reports), or None before an episode."""
        return self._episodes[0].online if self._episodes else None  # type: ignore[attr-defined]

    def _new_episode(self) -> AdaptiveEpisode:
        if self.carry_over:
            if self._shared is None:
                self._shared = OnlineTurnMap(self.turn_map, self.online_config)
            return AdaptiveEpisode(online=self._shared)
        return AdaptiveEpisode(online=OnlineTurnMap(self.turn_map, self.online_config))

    def _decide(self, ep: AdaptiveEpisode, obs: np.ndarray) -> float:
        if self.end_slice is not None and not ep.turns and ep.mode == "cruise" and not ep.cruise_used:
            lay = self.layout
            rot = obs[lay.orientation].reshape(3, 3).T  # columns X_b, Y_b, Z_b in the start frame
            if ep.axis is None:
                ep.axis = rot[:, 0].astype(np.float64)
            node = obs[lay.shape].reshape(-1, 3)[lay.phase_slot].astype(np.float64) @ rot.T
            ep.strains.append(float(obs[self.end_slice][0]) - 1.0)
            ep.azimuths.append(azimuth(node, ep.axis))
        return super()._decide(ep, obs)

    @staticmethod
    def _line_miss(starts, directions, target):
        # a target behind may take several bursts: each must count as progress
        return graded_line_miss(starts, directions, target)

    def _continue_burst(self, ep: AdaptiveEpisode, obs: np.ndarray) -> bool:
        turn = ep.turns[-1]
        clock_t = turn.get("clock_map_t")
        if clock_t is None or self.end_slice is None:
            going = super()._continue_burst(ep, obs)
            if not going:
                turn.update(burst_s=(ep.step - turn["burst_step"]) * self.control_dt, stopped_by="time")
            return going
        elapsed = (ep.step - turn["burst_step"]) * self.control_dt  # s at omega_h so far
        ratio = float(obs[self.end_slice][0])
        on = ep.online
        if "onset_s" not in turn and ratio < on.config.ratio_valid:
            # buckling seen: the burst may last until the map's time from buckling to the planned map time,
            # stretched, after it (a late buckler would otherwise be cut at its planned length)
            turn["onset_s"] = elapsed
            t_on = on.map_time_for_ratio(on.config.ratio_valid - 1e-9)
            if t_on is not None:
                late = elapsed + self.adaptive.late_onset_factor * max(clock_t - t_on, 0.0) + 0.5
                turn["max_burst_s"] = max(turn["max_burst_s"], late)
        if ratio < turn.get("ratio_low", math.inf):
            # the ratio clock, read where L'/L makes a new low (on a pause it would keep reading the pause's start)
            turn["ratio_low"] = ratio
            reading = on.clock_reading(ratio)
            if reading is not None:
                turn["clock_shift_s"] = reading - elapsed  # map time reached minus time flown
        stop, why = False, None
        if ("clock_shift_s" in turn and elapsed >= 0.5 * turn["t_c"] - 1e-9
                and elapsed >= clock_t - turn["clock_shift_s"] - 0.5 * self.control_dt):
            stop, why = True, "ratio"  # the step nearest to the planned map time on the ratio clock
        elif elapsed >= turn["max_burst_s"] - 1e-9:
            stop, why = True, "time"
        if stop:
            turn.update(burst_s=elapsed, ratio_end=ratio, stopped_by=why)
        return not stop

    def _plan_turn(self, head, d, target, node, ep=None):
        """The next turn, or None to swim on: the best expected miss over the outcomes (``expected_misses``),
        if it beats swimming straight by ``PlannerConfig.improvement_m`` and swimming on first would not."""
        if not ep.cruise_used and self.reference is not None and not ep.turns and len(ep.strains) >= 3:
            seen = summarise_cruise(np.array(ep.strains), np.array(ep.azimuths), self.control_dt)
            ep.cruise_reading = ep.online.observe_cruise(seen, self.reference)
            ep.cruise_used = True
        self.track_segment(ep, target)  # (done by _decide already; here for a direct call)
        if ep.swim_until is not None:
            if float((ep.swim_until - head) @ ep.swim_heading) > 0.0:
                return None  # swimming on, as decided
            ep.swim_until = None
        if ep.online.follows_model:
            # the swimmer is the map's as far as the cruise and the turns so far tell: the paper's rule on the map,
            # flown by time (no clock_map_t), until a turn contradicts the map
            plan = self.rule_plan(head, d, target, ep, paper_line_miss)
            if plan is not None:
                plan.update(follows_model=True, shift_s=ep.online.shift_s, shift_std_s=ep.online.shift_std_s)
                self._record_cruise(ep, plan)
            return plan
        miss0 = self._miss_if_off_course(head, d, target)
        if miss0 is None:
            return None
        scale = self._miss_scale(miss0)
        plan = self._best_turn(head, d, target, ep, miss0, scale)
        if plan is None or self._swim_on_first(head, d, target, ep, plan, scale):
            return None
        on = ep.online
        plan.update(shift_s=on.shift_s, shift_std_s=on.shift_std_s, bias_s=on.bias_s,
                    psi_offset_deg=math.degrees(on.psi_offset_rad), **on.burst_plan(plan["t_c"]))
        self._record_cruise(ep, plan)
        return plan

    @staticmethod
    def _record_cruise(ep: AdaptiveEpisode, plan: dict) -> None:
        if not ep.turns and ep.cruise_reading is not None:  # the first turn records what the cruise read
            plan.update(cruise={k: ep.cruise_reading[k] for k in ("strain_relative_change", "rate_relative_change",
                                                                   "shift_reading_s", "cruise_matched")})

    def _miss_scale(self, miss0: float) -> float:
        """The scale c (m) of ``saturating_miss`` for a decision whose straight-line miss is ``miss0`` (m)."""
        a = self.adaptive
        return max(a.miss_scale_m, a.miss_scale_fraction * miss0) if math.isfinite(miss0) else a.miss_scale_m

    def _best_turn(self, head: np.ndarray, d: np.ndarray, target: np.ndarray, ep: AdaptiveEpisode,
                   miss0: float, scale_m: float) -> dict | None:
        """The candidate (burst x phase) of least expected saturated miss (``saturating_miss`` at ``scale_m``),
        or None if it does not beat the straight line's (``miss0``, m) by ``PlannerConfig.improvement_m``."""
        out = ep.online.outcomes(self.control_dt, math.radians(self.config.burst_cap_deg))
        beta = np.radians(np.arange(0.0, 360.0, self.config.phase_step_deg))
        a = self.adaptive

        def line_miss(starts, directions, tgt):
            return saturating_miss(self._line_miss(starts, directions, tgt), scale_m)

        miss = expected_misses(head, d, target, out, beta, line_miss, ep.segment,
                               a.corridor_soft * a.corridor_m, a.corridor_hard * a.corridor_m)
        line = None
        if self.config.line_weight > 0.0 and ep.segment is not None:
            # the rule planner's line term (PlannerConfig.line_weight), in expectation over the timing outcomes
            ends = turn_ends(head, d, out.offset, beta)                                   # (T, K, B, 3)
            line = (np.einsum("k,tkb->tb", out.weights, line_distance(ends, *ep.segment)),
                    float(line_distance(head, *ep.segment)))
        chosen = pick_turn(miss, float(saturating_miss(miss0, scale_m)), self.config, line)
        if chosen is None:
            return None
        i, j, score, _ = chosen
        theta, psi = ep.online.turn_at(float(out.map_t[i]))
        return {"t_c": float(max(out.t_fly[i], self.control_dt)), "theta_deg": math.degrees(theta),
                "burst_phase": wrap_angle(beta[j]), "predicted_azimuth": wrap_angle(beta[j] + psi),
                "predicted_miss_m": score, "miss_straight_m": float(miss0),
                "heading": d.tolist(), "head": head.tolist()}

    def _swim_on_first(self, head, d, target, ep, plan: dict, scale_m: float) -> bool:
        """Swim on, then turn: True (and the point to swim to kept) if the best turn made up to
        ``AdaptiveConfig.swim_on_m`` further on, staying near the target and the segment, is expected
        to miss by less than ``plan``'s, counting ``swim_cost`` per m swum."""
        a = self.adaptive
        best, best_c = plan["predicted_miss_m"] - a.swim_gain_m, None
        for c in np.arange(0.01, a.swim_on_m + 1e-9, 0.01):
            ahead = head + c * d
            if (float(np.linalg.norm(target - ahead)) > a.swim_near_m
                    or float(segment_distance(ahead, *ep.segment)) > a.corridor_soft * a.corridor_m):
                break
            later = self._best_turn(ahead, d, target, ep, self._line_miss(ahead[None, :], d[None, :], target)[0],
                                    scale_m)
            if later is not None and later["predicted_miss_m"] + a.swim_cost * c < best:
                best, best_c = later["predicted_miss_m"] + a.swim_cost * c, float(c)
        if best_c is None:
            return False
        plan.update(swim_on_m=best_c)
        ep.swim_until, ep.swim_heading = head + best_c * d, d.copy()
        return True

    def _turn_settled(self, ep: AdaptiveEpisode) -> None:
        if ep.observed >= len(ep.turns):
            return
        turn = ep.turns[-1]
        ep.observed = len(ep.turns)
        d0 = np.asarray(turn["heading"], dtype=np.float64)
        d1 = self._heading(ep)
        theta_obs = math.degrees(angle_between(d0, d1))
        predicted = turn["predicted_azimuth"] + math.radians(turn.get("phase_error_deg", 0.0))
        az_err = wrap_angle(azimuth(d1, d0) - predicted)
        rec = ep.online.observe(turn.get("burst_s", turn["t_c"]), theta_obs, az_err, turn.get("ratio_end"),
                                turn["theta_deg"], turn.get("clock_shift_s"))
        turn.update(observed_theta_deg=theta_obs, azimuth_error_deg=math.degrees(az_err),
                    shift_after_s=rec["shift_s"], shift_std_after_s=rec["shift_std_s"])


def expected_misses(head: np.ndarray, d: np.ndarray, target: np.ndarray, out, beta: np.ndarray, line_miss,
                    segment: tuple[np.ndarray, np.ndarray] | None, soft_m: float, hard_m: float,
                    uniform_nodes: int = 8) -> np.ndarray:
    """Expected miss (m) of every candidate turn (T,) at every flagellum phase ``beta`` (B,) rad: (T, B).

    Each candidate's outcomes (``OnlineTurnMap.outcomes``: K timing points, each with direction errors
    -- three Gauss-Hermite points of its normal part and ``uniform_nodes`` evenly spread ones for the
    chance that the direction is anything) are predicted as the rule planner predicts one turn -- the
    head moves by the map's displacement, then swims along the new heading -- and scored by
    ``line_miss`` against ``target``; a head position (after the turn, and after its forward travel)
    farther than ``soft_m`` from the current ``segment`` adds its excess, farther than ``hard_m``
    0.5 m (the corridor the episode must stay in)."""
    nodes, w = GAUSS_HERMITE_3
    uniform = 2.0 * np.pi * np.arange(uniform_nodes) / uniform_nodes
    q = out.direction_anything[..., None]                                                   # (T, K, 1)
    dpsi = np.concatenate([nodes * out.direction_std[..., None],
                           np.broadcast_to(uniform, out.direction_std.shape + (uniform_nodes,))], axis=-1)
    wj = np.concatenate([(1.0 - q) * w, np.broadcast_to(q / uniform_nodes, q.shape[:2] + (uniform_nodes,))],
                        axis=-1)                                                            # (T, K, J)
    e1, e2 = perpendicular_basis(d)
    az = beta + (out.psi[..., None] + dpsi)[..., None]                                      # (T, K, J, B)
    across = np.cos(az)[..., None] * e1 + np.sin(az)[..., None] * e2
    theta = out.theta[:, :, None, None, None]
    heading = np.cos(theta) * d + np.sin(theta) * across                                    # (T, K, J, B, 3)
    off = out.offset
    after = turn_ends(head, d, off, beta)                                                   # (T, K, B, 3)
    starts = np.broadcast_to(after[:, :, None], heading.shape)
    miss = line_miss(starts.reshape(-1, 3), heading.reshape(-1, 3), target).reshape(heading.shape[:4])
    if segment is not None:
        travel = head + np.maximum(off[..., 0], 0.0)[..., None] * d                          # (T, K, 3)
        worst = np.maximum(segment_distance(travel, *segment)[..., None],
                           segment_distance(after, *segment))[:, :, None, :]               # (T, K, 1, B)
        miss = miss + np.maximum(worst - soft_m, 0.0) + 0.5 * (worst > hard_m)
    wt = out.weights[None, :, None, None] * wj[..., None]                                  # (T, K, J, 1)
    return np.einsum("tkjb,tkjb->tb", miss, np.broadcast_to(wt, miss.shape))
