"""The rule planner that calibrates its turn map on the swimmer as it swims.

``AdaptivePlanner`` is ``agents.turn_planner.RulePlanner`` with an ``OnlineTurnMap``
(``agents.online_turn_map``): after every turn, once the heading is steady, it measures the
angle turned and the direction of the new heading, updates its estimate of the swimmer's
buckling-time shift and direction offset, and plans the next turn from the corrected map,
keeping bursts away from the map's peak while the estimate is uncertain. Everything else
(hover to the phase, burst, relax, re-plan from the measured heading) is the rule planner's.
With a swimmer equal to the map's the readings stay near zero and it flies like the rule
planner, except that the first turns are capped (the prior's caution) until turns confirm the
corrected map (``OnlineMapConfig.lift_after_turns``).

The correction is per episode by default (``carry_over=False``): each episode may be a
different swimmer (domain randomisation draws one per episode). ``carry_over=True`` keeps
what was learnt across episodes (one physical robot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap
from agents.turn_map import TurnMap
from agents.turn_planner import PlannerConfig, RulePlanner, _Episode, graded_line_miss
from flagellum_env.turn_geometry import angle_between, azimuth, wrap_angle
from flagellum_env.turn_measurement import CruiseObservables, cruise_observables, summarise_cruise
from physics.validation import require_finite


@dataclass
class _AdaptiveEpisode(_Episode):
    online: OnlineTurnMap | None = None
    observed: int = 0                             # turns of ``turns`` already learnt from
    strains: list[float] = field(default_factory=list)   # L'/L - 1 while cruising before the first turn
    azimuths: list[float] = field(default_factory=list)  # of the phase node about the first X_b, rad
    axis: np.ndarray | None = None
    cruise_used: bool = False


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
    ``swim_on_m`` (m): swim on, then turn -- a turn that is not predicted to reach the target is put
    off while the same choice made up to this far on (and this near the target) is (0: never; default 8 cm,
    see ``OnlineMapConfig.lift_after_turns`` for what was measured)."""

    def __init__(self, turn_map: TurnMap, layout, control_dt: float, reach_radius_m: float, action_of,
                 config: PlannerConfig | None = None, online: OnlineMapConfig | None = None,
                 carry_over: bool = False, end_slice: slice | None = None,
                 reference: CruiseObservables | None = None, swim_on_m: float = 0.08) -> None:
        super().__init__(turn_map, layout, control_dt, reach_radius_m, action_of, config)
        self.swim_on_m = require_finite("swim_on_m", swim_on_m, 0.0)
        self.end_slice, self.reference = end_slice, reference
        self.online_config = online or OnlineMapConfig()
        self.carry_over = bool(carry_over)
        self._shared: OnlineTurnMap | None = None

    @classmethod
    def for_env(cls, env, turn_map: TurnMap, config: PlannerConfig | None = None,  # type: ignore[override]
                online: OnlineMapConfig | None = None, carry_over: bool = False,
                swim_on_m: float = 0.08) -> AdaptivePlanner:
        """An adaptive planner for this env (the rule planner's checks apply)."""
        base = RulePlanner.for_env(env, turn_map, config)
        e = env.unwrapped
        reference = cruise_reference(e.params, e.numerics, e.low_speed_rpm, turn_map.phase_node,
                                     (base.period_steps + 1) * base.control_dt, base.control_dt, e.settle_time_s)
        return cls(turn_map, base.layout, base.control_dt, base.reach_radius_m, base.action_of, config, online,
                   carry_over, e.obs_model.slices()["end_to_end_ratio"], reference, swim_on_m)

    @property
    def online_map(self) -> OnlineTurnMap | None:
        """The first env's current correction (for reports), or None before an episode."""
        return self._episodes[0].online if self._episodes else None  # type: ignore[attr-defined]

    def _new_episode(self) -> _AdaptiveEpisode:
        if self.carry_over:
            if self._shared is None:
                self._shared = OnlineTurnMap(self.turn_map, self.online_config)
            return _AdaptiveEpisode(online=self._shared)
        return _AdaptiveEpisode(online=OnlineTurnMap(self.turn_map, self.online_config))

    def _decide(self, ep: _AdaptiveEpisode, obs: np.ndarray) -> float:
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
        # capped turns: a target behind needs several bursts, each must count as progress
        return graded_line_miss(starts, directions, target)

    def _candidate_turns(self, ep):
        return ep.online.candidates(self.control_dt)

    def _continue_burst(self, ep: _AdaptiveEpisode, obs: np.ndarray) -> bool:
        turn = ep.turns[-1]
        target = turn.get("target_ratio")
        if target is None or self.end_slice is None:
            going = super()._continue_burst(ep, obs)
            if not going:
                turn.update(burst_s=(ep.step - turn["burst_step"]) * self.control_dt, stopped_by="time")
            return going
        elapsed = (ep.step - turn["burst_step"]) * self.control_dt  # s at omega_h so far
        ratio = float(obs[self.end_slice][0])
        prev = turn.get("ratio_seen", ratio)
        turn["ratio_seen"] = ratio
        drop = prev - ratio  # per control step
        stop, why = False, None
        if elapsed >= 0.5 * turn["t_c"] - 1e-9 and (ratio <= target or (drop > 0.0 and 2.0 * (ratio - target) <= drop)):
            stop, why = True, "ratio"  # at or nearest to the crossing (the next step would pass it by more)
        elif elapsed >= turn["max_burst_s"] - 1e-9:
            stop, why = True, "time"
        if stop:
            turn.update(burst_s=elapsed, ratio_end=ratio, stopped_by=why)
        return not stop

    def _plan_turn(self, head, d, target, node, ep=None):
        if not ep.cruise_used and self.reference is not None and not ep.turns and len(ep.strains) >= 3:
            seen = summarise_cruise(np.array(ep.strains), np.array(ep.azimuths), self.control_dt)
            ep.online.observe_cruise(seen, self.reference)
            ep.cruise_used = True
        plan = super()._plan_turn(head, d, target, node, ep)
        if plan is not None and self._swim_on_first(head, d, target, node, ep, plan):
            return None
        if plan is not None:
            plan.update(shift_s=ep.online.shift_s, shift_std_s=ep.online.shift_std_s, bias_s=ep.online.bias_s,
                        psi_offset_deg=math.degrees(ep.online.psi_offset_rad), **ep.online.burst_plan(plan["t_c"]))
        return plan

    def _swim_on_first(self, head, d, target, node, ep, plan: dict) -> bool:
        """Swim on, then turn: True if ``plan`` is not predicted to reach the target but the same choice
        made after cruising on (up to ``swim_on_m``, staying within ``swim_on_m`` of the target) is."""
        hit = self.config.hit_fraction * self.reach_radius_m
        if self.swim_on_m <= 0.0 or plan["predicted_miss_m"] <= hit:
            return False
        for c in np.arange(0.005, self.swim_on_m + 1e-9, 0.005):
            ahead = head + c * d
            if np.linalg.norm(target - ahead) > self.swim_on_m:
                break
            later = super()._plan_turn(ahead, d, target, node, ep)
            if later is not None and later["predicted_miss_m"] <= hit:
                plan.update(swim_on_m=float(c))
                return True
        return False

    def _turn_settled(self, ep: _AdaptiveEpisode) -> None:
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
                                turn["theta_deg"])
        turn.update(observed_theta_deg=theta_obs, azimuth_error_deg=math.degrees(az_err),
                    shift_after_s=rec["shift_s"], shift_std_after_s=rec["shift_std_s"])
