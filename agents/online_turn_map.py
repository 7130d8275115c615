"""A turn map corrected online from the turns the swimmer actually makes.

The turn map (``agents.turn_map``) is a calibration of the nominal swimmer. A real swimmer
differs: Huang & Jawed (2020, Sec. 4) name this imperfection sensitivity as the main obstacle
for a physical robot and recommend calibrating on the robot itself. Measured here (faithful
preset, 150 rpm burst of 6 s from steady 10 rpm, ``results/online_turn_map/sensitivity.jsonl``):
E 5 % lower turns 42.8 deg instead of 26.2 deg, E 5 % higher 16.1 deg, mu 5 % higher 41.7 deg;
the direction psi moves by at most ~2 deg. A parameter error moves *when* the flagellum
buckles (the viscous time mu L^4 / EI), so the turn of a burst of t_c seconds is, to first
order, the map's turn at t_c + s for a swimmer-specific shift s (s > 0: buckles early),

    theta(t_c) = theta_map(t_c + s),        psi(t_c) = psi_map(t_c + s) + dpsi.

Every settled turn gives one reading of s: the map's burst length for the observed angle
(rising branch) minus the burst length flown. Its uncertainty is the angle's noise divided
by the branch's slope there (steep = precise). ``OnlineTurnMap`` combines the readings with a
Gaussian prior (s = 0) by precision weighting (a scalar Kalman filter for a constant), and
the direction offset dpsi by a weighted circular mean of the readings of large turns.

Planning with it (``OnlineTurnMap.outcomes``): the candidate turns are the map's rising branch
up to its peak, flown ``s`` seconds shorter; each is predicted not as one turn but as sigma points
of what the swimmer may do -- the map read at the planned map time plus an error of the spread of
the correction (past the peak the map's own tumbling turns), each with a direction error whose
spread grows with the turn's size until turns confirmed the corrected map. The planner scores a
turn by its expected miss over these points, so a large turn whose direction is unpredictable
loses to a smaller, predictable one unless any direction will do (a target straight behind), and
a turn near the peak loses while the timing is uncertain: the cap of earlier versions is a
consequence of the spread, not a constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from agents.turn_map import TurnMap, leading_within
from agents.turn_geometry import wrap_angle
from agents.turn_measurement import CruiseObservables
from physics.validation import require_finite


@dataclass(frozen=True)
class OnlineMapConfig:
    """Priors and noise of the online correction (times in s, angles in degrees).

    prior_shift_std_s: prior standard deviation of the buckling-time shift s (see below).
    theta_noise_deg +
    theta_noise_fraction * theta: standard deviation of a measured turn angle (phase scatter,
    the unrelaxed flagellum of a turn right after another). min_theta_deg: smaller observed turns
    give no shift reading (the branch is flat there). psi_min_theta_deg: smaller turns give no
    direction reading (their azimuth is ill-defined). max_shift_s: readings are clipped to +-this (the
    ratio clock read -3.8 s on a development swimmer within +-10 %).

    The direction of a turn (``OnlineTurnMap.outcomes``): its azimuth error is normal with the
    standard deviation ``direction_std_deg`` for turns up to ``large_turn_deg``, and with a
    probability rising linearly from 0 to 1 over the next ``large_turn_ramp_deg`` it is anything
    (uniform): across 31 randomised swimmers (``results/online_turn_map/``) the direction of turns up
    to ~80 deg stayed within ~35 deg of the map's (one 72 deg), while every turn of 94 deg or more came
    out 35-180 deg off; on development swimmers turns of 114-136 deg came out 128-170 deg off. Once
    ``lift_after_turns`` turns in a row confirmed the corrected map (a turn of at least
    ``psi_min_theta_deg`` planned that turned within ``confirm_theta_deg`` + ``confirm_theta_fraction``
    x the planned angle, its new heading within ``confirm_azimuth_deg`` of the predicted azimuth),
    every turn up to ``confirmed_margin_deg`` beyond the largest of those turns has the direction spread
    ``confirmed_direction_std_deg``, and the chance that a larger one goes anywhere ramps up from there
    (the map is trusted where turns tested it: on development swimmers at +-5 % a map confirmed by turns of
    92-131 deg let through 177-178 deg turns near the branch's cliff, whose outcome left the corridor); a turn
    that does not confirm restores the wider spread (the count restarts). 0: never confirmed.
    A cruise that matches the map's swimmer (``cruise_match_tol``: the steady strain and the rotation rate
    both within this relative change of the reference's, ``observe_cruise``) says the swimmer is the map's
    (``follows_model``) until a turn of at least ``psi_min_theta_deg`` does not confirm the map (the test
    above): the 31 randomised swimmers (+-10 %) differed from the reference by 3.3-21.6 % in the larger of the
    two changes, so only a swimmer that cruises like the map's is taken for it. 0: never.

    Flying by L'/L (``fly_by_ratio``): the map records L'/L at each burst's end, i.e. L'/L against
    time during a burst; below ``ratio_valid`` it falls as the flagellum buckles, but not steadily:
    it pauses (at faithful 7.0-7.2 s and 7.6-7.8 s, where the turn still grows from 59 to 71 and from
    102 to 128 deg).
    Where it falls by at least ``clock_slope_per_s`` the ratio seen tells the map time the swimmer
    has reached (``OnlineTurnMap.clock_reading``): the *ratio clock*. During a burst every such
    reading gives the swimmer's shift, and the burst ends when the map time so read reaches the
    planned one (on a pause, by the last reading plus the time flown since), so the buckling the
    swimmer actually does sets the burst's end; before any reading it is cut at ``burst_max_sigmas``
    standard deviations of the shift past its expected length. The last reading is the turn's
    shift reading (``ratio_shift_std_s``); the angle turned then reads a bias of the ratio-turn
    relation (prior ``prior_bias_std_s``).

    The reading before any turn (``OnlineTurnMap.observe_cruise``): shift = strain_shift_s x
    (relative change of the steady strain L'/L - 1) + rate_shift_s x (relative change of the
    flagellum's lab rotation rate), both at omega_l; cruise_residual_std_s: what the fit leaves
    unexplained (leave-one-out rms); min_cruise_samples: fewer samples give no reading. Fitted
    across 31 randomised swimmers of the faithful preset (E, mu, b within +-10 %, helix within
    +-4 %) by ``scripts/turn_shift_sensitivity.py --fit`` (``results/online_turn_map/``, the rows without
    ``head_rotation``: the torque-free swimmer, whose rising branch ran to 8.2 s): the shift's rms over them is
    1.1 s (prior_shift_std_s); after the cruise reading 0.49 s (0.55 s leave-one-out). On the default swimmer
    (head held) the same fit gives 0.28 s, 2.06 s, 20.4 s and 0.21 s, and its turns flip to the other lobe
    (docs/planner.md); the planner refitted to those numbers, with a flip in its direction model, lost paths
    on fresh development swimmers at +-10 % (23 against 26 of 32, none gained), so these defaults stay.
    """

    prior_shift_std_s: float = 1.1
    strain_shift_s: float = 7.64
    rate_shift_s: float = 7.27
    cruise_residual_std_s: float = 0.55
    min_cruise_samples: int = 20
    theta_noise_deg: float = 4.0
    theta_noise_fraction: float = 0.1
    direction_std_deg: float = 20.0
    large_turn_deg: float = 80.0
    large_turn_ramp_deg: float = 20.0
    confirmed_direction_std_deg: float = 10.0
    confirmed_margin_deg: float = 20.0
    lift_after_turns: int = 2
    confirm_theta_deg: float = 10.0
    confirm_theta_fraction: float = 0.15
    confirm_azimuth_deg: float = 15.0
    min_theta_deg: float = 6.0
    psi_min_theta_deg: float = 20.0
    max_shift_s: float = 5.0
    fly_by_ratio: bool = True
    ratio_valid: float = 0.98
    clock_slope_per_s: float = 0.05
    ratio_shift_std_s: float = 0.15
    prior_bias_std_s: float = 0.3
    burst_max_sigmas: float = 2.5
    cruise_match_tol: float = 0.01

    def __post_init__(self) -> None:
        if not isinstance(self.fly_by_ratio, bool):
            raise ValueError(f"OnlineMapConfig.fly_by_ratio={self.fly_by_ratio!r} is not allowed; allowed: True or False")
        require_finite("OnlineMapConfig.ratio_valid", self.ratio_valid, 0.0, 1.0, lo_open=True)
        for name in ("prior_shift_std_s", "theta_noise_deg", "max_shift_s", "cruise_residual_std_s",
                     "ratio_shift_std_s", "prior_bias_std_s", "burst_max_sigmas", "direction_std_deg",
                     "large_turn_ramp_deg", "confirmed_direction_std_deg", "clock_slope_per_s"):
            require_finite(f"OnlineMapConfig.{name}", getattr(self, name), 0.0, lo_open=True)
        for name in ("theta_noise_fraction", "large_turn_deg", "min_theta_deg", "psi_min_theta_deg", "min_cruise_samples",
                     "lift_after_turns", "confirm_theta_deg", "confirm_theta_fraction", "confirm_azimuth_deg",
                     "confirmed_margin_deg", "cruise_match_tol"):
            require_finite(f"OnlineMapConfig.{name}", getattr(self, name), 0.0)
        for name in ("strain_shift_s", "rate_shift_s"):
            require_finite(f"OnlineMapConfig.{name}", getattr(self, name))


def shift_reading(t_branch: np.ndarray, theta_branch: np.ndarray, t_c: float, theta_obs_deg: float,
                  config: OnlineMapConfig) -> tuple[float, float] | None:
    """One reading of the buckling-time shift from a flown burst ``t_c`` (s) that turned
    ``theta_obs_deg``: (shift s, its standard deviation s), or None if the turn says nothing
    (too small). ``t_branch``, ``theta_branch``: the map's rising branch (non-decreasing, deg).

    A turn beyond the branch's peak reads as the peak (a lower bound on the shift: the next
    reading pushes further if it was more).
    """
    if theta_obs_deg < config.min_theta_deg:
        return None
    peak = float(theta_branch[-1])
    theta = min(float(theta_obs_deg), peak)
    k = int(np.searchsorted(theta_branch, theta, side="left"))
    k = min(max(k, 1), len(t_branch) - 1)
    y0, y1 = float(theta_branch[k - 1]), float(theta_branch[k])
    t0, t1 = float(t_branch[k - 1]), float(t_branch[k])
    slope = (y1 - y0) / (t1 - t0) if t1 > t0 else 0.0          # deg/s
    t_equiv = t1 if y1 == y0 else t0 + (theta - y0) / (y1 - y0) * (t1 - t0)
    sigma_theta = config.theta_noise_deg + config.theta_noise_fraction * theta
    std = sigma_theta / max(slope, 1e-6)
    shift = float(np.clip(t_equiv - t_c, -config.max_shift_s, config.max_shift_s))
    return shift, float(min(std, 10.0 * config.max_shift_s))


def ratio_branch(turn_map: TurnMap, t_branch: np.ndarray, ratio_valid: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(map times s, L'/L at the burst's end) on the rising branch where L'/L has fallen below
    ``ratio_valid``, made decreasing; None if the map recorded no ratios there (fewer than 2)."""
    t_out, r_out = [], []
    for t in t_branch:
        r = [p.burst_end_ratio for p in turn_map.points if p.t_c == t and p.burst_end_ratio is not None]
        if t > 0.0 and r:
            t_out.append(float(t))
            r_out.append(float(np.mean(r)))
    if not r_out:
        return None
    r = np.minimum.accumulate(np.array(r_out))
    keep = r < ratio_valid
    if keep.sum() < 2:
        return None
    # the first point below ratio_valid is preceded by the last above it: interpolate the crossing
    k = int(np.argmax(keep))
    t, rr = np.array(t_out), r
    if k > 0:
        t0 = float(np.interp(ratio_valid, [rr[k], rr[k - 1]], [t[k], t[k - 1]]))
        return np.concatenate([[t0], t[keep]]), np.concatenate([[ratio_valid], rr[keep]])
    return t[keep], rr[keep]


def ratio_at(branch: tuple[np.ndarray, np.ndarray] | None, map_t: float) -> float | None:
    """L'/L on a ``ratio_branch`` at map time ``map_t`` (s), linear between its points; None off the branch
    (before L'/L falls below the branch's ``ratio_valid``, past its last point, or no branch)."""
    if branch is None or map_t < branch[0][0] or map_t > branch[0][-1]:
        return None
    return float(np.interp(map_t, *branch))


class RatioClock:
    """The map's L'/L at a burst's end against the burst's length on the rising branch, from where it falls below
    ``ratio_valid`` (``ratio_branch``): the ratio clock of ``OnlineMapConfig``'s "Flying by L'/L", without the
    learning. ``start_s``: the shortest burst it reads (s; inf without a branch)."""

    def __init__(self, turn_map: TurnMap, ratio_valid: float = OnlineMapConfig.ratio_valid) -> None:
        self.branch = ratio_branch(turn_map, turn_map.rising_branch()[0], ratio_valid)
        self.start_s = float(self.branch[0][0]) if self.branch is not None else math.inf

    def ratio_for(self, map_t: float) -> float | None:
        """The map's L'/L at the end of a burst of ``map_t`` s, or None off the branch (``ratio_at``)."""
        return ratio_at(self.branch, map_t)


#: three-point Gauss-Hermite rule for N(0, 1): nodes and weights (exact for polynomials up to degree 5)
GAUSS_HERMITE_3 = (np.array([-math.sqrt(3.0), 0.0, math.sqrt(3.0)]), np.array([1.0, 4.0, 1.0]) / 6.0)


@dataclass(frozen=True)
class TurnOutcomes:
    """Candidate turns (T of them) with K = 3 sigma points each of what the swimmer may do.

    t_fly (T,) s: burst to fly (before the L'/L stop, ``OnlineTurnMap.burst_plan``); map_t (T,) s: the
    planned map time; theta (T, K) rad, psi (T, K) rad (the direction offset applied), offset (T, K, 3) m
    (the map's head displacement: along the heading, the phase node's direction, their cross product)
    at the sigma points of the timing; direction_std (T, K) rad: spread of each point's azimuth (its normal
    part), direction_anything (T, K): the probability that the azimuth is anything instead;
    weights (K,): of the timing's sigma points (the direction's normal part uses the same rule,
    ``GAUSS_HERMITE_3``).
    """

    t_fly: np.ndarray
    map_t: np.ndarray
    theta: np.ndarray
    psi: np.ndarray
    offset: np.ndarray
    direction_std: np.ndarray
    direction_anything: np.ndarray
    weights: np.ndarray


@dataclass
class OnlineTurnMap:
    """The turn map with the swimmer's shift and direction offset, learnt from observed turns.

    ``observe`` after every settled turn; ``outcomes`` for the planner. ``reset`` forgets the
    swimmer (a new episode may be a different swimmer).
    """

    turn_map: TurnMap
    config: OnlineMapConfig = field(default_factory=OnlineMapConfig)

    def __post_init__(self) -> None:
        self._branch = self.turn_map.rising_branch()
        self._ratio = ratio_branch(self.turn_map, self._branch[0], self.config.ratio_valid)
        self._full: tuple[np.ndarray, ...] | None = None
        self.reset()

    def reset(self) -> None:
        self.shift_s = 0.0
        self.shift_var = self.config.prior_shift_std_s ** 2
        self.bias_s = 0.0
        self.bias_var = self.config.prior_bias_std_s ** 2
        self._psi_sum = 0j
        self._psi_weight = 0.0
        self.confirmed = 0  # turns in a row that confirmed the corrected map (``OnlineMapConfig``)
        self.confirmed_upto_deg = 0.0  # the largest of them, deg
        self.follows_model = False  # the cruise matched the map's swimmer and no turn has contradicted the map since
        self.readings: list[dict] = []

    @property
    def map_confirmed(self) -> bool:
        """True once enough turns in a row confirmed the corrected map (``OnlineMapConfig.lift_after_turns``):
        turns up to ``confirmed_margin_deg`` beyond the largest confirming one then have the narrow direction
        spread ``confirmed_direction_std_deg``."""
        return 0 < self.config.lift_after_turns <= self.confirmed

    def _confirm(self, planned_deg: float, theta_obs_deg: float, azimuth_error_rad: float | None) -> None:
        cfg = self.config
        if planned_deg < cfg.psi_min_theta_deg:
            return  # a small turn says nothing about large ones
        ok = (abs(theta_obs_deg - planned_deg) <= cfg.confirm_theta_deg + cfg.confirm_theta_fraction * planned_deg
              and azimuth_error_rad is not None and abs(math.degrees(azimuth_error_rad)) <= cfg.confirm_azimuth_deg)
        self.confirmed = self.confirmed + 1 if ok else 0
        self.follows_model = self.follows_model and ok
        self.confirmed_upto_deg = max(self.confirmed_upto_deg, planned_deg) if ok else 0.0

    @property
    def shift_std_s(self) -> float:
        return math.sqrt(self.shift_var)

    @property
    def bias_std_s(self) -> float:
        return math.sqrt(self.bias_var)

    def ratio_for(self, map_t: float) -> float | None:
        """The map's L'/L at the end of a burst of map time ``map_t`` (s), or None where the map's
        ratio is not yet below ``ratio_valid`` (before buckling, or no ratios recorded)."""
        return ratio_at(self._ratio, map_t)

    def map_time_for_ratio(self, ratio: float) -> float | None:
        """Map time (s) at which the map's L'/L is ``ratio`` (clipped to the branch), or None if
        ``ratio`` is not below ``ratio_valid``."""
        if self._ratio is None or not ratio < self.config.ratio_valid:
            return None
        t, r = self._ratio
        return float(np.interp(ratio, r[::-1], t[::-1]))

    def clock_reading(self, ratio: float) -> float | None:
        """The ratio clock (``OnlineMapConfig``): the map time (s) at which the map's L'/L is ``ratio``, where
        the map's L'/L falls by at least ``clock_slope_per_s``; None before buckling (not below
        ``ratio_valid``), on a pause of L'/L or past the map's recorded ratios."""
        if self._ratio is None or not ratio < self.config.ratio_valid:
            return None
        t, r = self._ratio
        for k in range(1, len(t)):
            if r[k] <= ratio <= r[k - 1]:
                drop, dt = float(r[k - 1] - r[k]), float(t[k] - t[k - 1])
                if drop > 0.0 and drop >= self.config.clock_slope_per_s * dt:
                    return float(t[k - 1] + (r[k - 1] - ratio) / drop * dt)
                return None
        return None

    def burst_plan(self, t_fly: float) -> dict:
        """How to fly a candidate chosen with burst length ``t_fly`` (s, from ``outcomes``): its map time,
        the map time of the ratio clock to stop at (``clock_map_t``; None: fly the time) and the longest
        burst allowed before a clock reading (s)."""
        cfg = self.config
        map_t = t_fly + self.shift_s
        # beyond the map's recorded ratios too: the burst is then timed from the last reading before it; not a
        # burst planned to end before the map's L'/L falls below ratio_valid (no reading would come: it is flown
        # by time)
        clock = map_t - self.bias_s if (cfg.fly_by_ratio and self._ratio is not None) else None
        if clock is not None and clock < float(self._ratio[0][0]):
            clock = None
        longest = t_fly - self.bias_s + cfg.burst_max_sigmas * math.hypot(self.shift_std_s, self.bias_std_s)
        return {"map_t": map_t, "clock_map_t": clock, "max_burst_s": max(longest, t_fly)}

    @property
    def psi_offset_rad(self) -> float:
        """Weighted circular mean of the direction readings (0 without any)."""
        return math.atan2(self._psi_sum.imag, self._psi_sum.real) if self._psi_weight > 0.0 else 0.0

    @property
    def t_peak_s(self) -> float:
        """Map time of the rising branch's peak, s."""
        return float(self._branch[0][-1])

    def _combine(self, reading: float, std: float) -> None:
        w, w0 = 1.0 / (std * std), 1.0 / self.shift_var
        self.shift_s = (w0 * self.shift_s + w * reading) / (w0 + w)
        self.shift_var = 1.0 / (w0 + w)

    def observe_cruise(self, seen: CruiseObservables, reference: CruiseObservables) -> dict | None:
        """Update from what was seen while cruising at omega_l before the first turn (``seen``)
        against the map swimmer's cruise (``reference``): the shift predicted by the relative
        changes of the strain and of the rotation rate (coefficients fitted across swimmers,
        ``OnlineMapConfig``), with the fit's residual and the readings' own noise as its spread.
        Returns the reading, or None (too few samples or a degenerate reference)."""
        cfg = self.config
        if seen.samples < max(cfg.min_cruise_samples, 3) or reference.strain <= 0.0 or reference.rotation_rate == 0.0:
            return None
        d_strain = seen.strain / reference.strain - 1.0
        d_rate = seen.rotation_rate / reference.rotation_rate - 1.0
        if not (math.isfinite(d_strain) and math.isfinite(d_rate)):
            return None
        reading = float(np.clip(cfg.strain_shift_s * d_strain + cfg.rate_shift_s * d_rate,
                                -cfg.max_shift_s, cfg.max_shift_s))
        noise = math.hypot(cfg.strain_shift_s * seen.strain_sem / reference.strain,
                           cfg.rate_shift_s * seen.rotation_rate_std / abs(reference.rotation_rate))
        std = math.hypot(cfg.cruise_residual_std_s, noise)
        self._combine(reading, std)
        matched = 0.0 < cfg.cruise_match_tol and max(abs(d_strain), abs(d_rate)) <= cfg.cruise_match_tol
        self.follows_model = matched  # the swimmer cruises like the map's (OnlineMapConfig)
        rec = {"strain_relative_change": d_strain, "rate_relative_change": d_rate, "shift_reading_s": reading,
               "shift_reading_std_s": std, "shift_s": self.shift_s, "shift_std_s": self.shift_std_s,
               "cruise_matched": matched}
        self.readings.append(rec)
        return rec

    def observe(self, t_c: float, theta_obs_deg: float, azimuth_error_rad: float | None = None,
                ratio_end: float | None = None, planned_theta_deg: float | None = None,
                clock_shift_s: float | None = None) -> dict:
        """Update from one settled turn: burst ``t_c`` (s) flown, angle ``theta_obs_deg`` turned;
        ``azimuth_error_rad``: observed minus predicted azimuth of the new heading about the old
        one (the prediction used ``psi_offset_rad`` as it was), or None; ``ratio_end``: L'/L seen
        at the burst's end, or None; ``planned_theta_deg``: the angle the planner expected (confirms the
        map or restores the wide direction spread, ``OnlineMapConfig.lift_after_turns``), or None;
        ``clock_shift_s``: the last reading of the ratio clock during the burst (its map time minus the
        time flown then), or None. Returns the reading.

        With a clock reading (``clock_shift_s``, else the clock at ``ratio_end``), it is the shift reading
        and the angle reads the bias (map time of the angle minus the map time reached, ``t_c`` + shift);
        otherwise the angle reads the shift."""
        cfg = self.config
        rec: dict = {"t_c": float(t_c), "theta_obs_deg": float(theta_obs_deg), "shift_before_s": self.shift_s,
                     "ratio_end": ratio_end}
        if planned_theta_deg is not None:
            self._confirm(float(planned_theta_deg), float(theta_obs_deg), azimuth_error_rad)
        if clock_shift_s is None and ratio_end is not None:
            m = self.clock_reading(ratio_end)
            clock_shift_s = None if m is None else m - t_c
        if clock_shift_s is not None:
            s = float(np.clip(clock_shift_s, -cfg.max_shift_s, cfg.max_shift_s))
            map_end = t_c + s
            self._combine(s, cfg.ratio_shift_std_s)
            rec.update(shift_reading_s=s, shift_reading_std_s=cfg.ratio_shift_std_s)
            reading = shift_reading(*self._branch, map_end, theta_obs_deg, cfg)
            if reading is not None:
                b, std = reading
                w, w0 = 1.0 / (std * std), 1.0 / self.bias_var
                self.bias_s = (w0 * self.bias_s + w * b) / (w0 + w)
                self.bias_var = 1.0 / (w0 + w)
                rec.update(bias_reading_s=b, bias_reading_std_s=std)
        else:
            reading = shift_reading(*self._branch, t_c, theta_obs_deg, cfg)
            if reading is not None:
                s, std = reading
                self._combine(s, std)
                rec.update(shift_reading_s=s, shift_reading_std_s=std)
        if azimuth_error_rad is not None and theta_obs_deg >= self.config.psi_min_theta_deg:
            # the reading is the total offset: the one already applied plus the error seen
            total = wrap_angle(self.psi_offset_rad + float(azimuth_error_rad))
            wt = math.sin(math.radians(min(theta_obs_deg, 90.0)))
            self._psi_sum += wt * complex(math.cos(total), math.sin(total))
            self._psi_weight += wt
            rec["psi_reading_deg"] = math.degrees(total)
        rec.update(shift_s=self.shift_s, shift_std_s=self.shift_std_s, bias_s=self.bias_s, bias_std_s=self.bias_std_s,
                   psi_offset_deg=math.degrees(self.psi_offset_rad), confirmed=self.confirmed)
        self.readings.append(rec)
        return rec

    @property
    def timing_std_s(self) -> float:
        """Spread (s) of the map time a planned burst comes out at: flying by L'/L it is the ratio-turn
        bias's (the ratio already absorbs the shift), else the shift's."""
        return self.bias_std_s if (self.config.fly_by_ratio and self._ratio is not None) else self.shift_std_s

    def direction_spread(self, theta_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How the azimuth of turns of ``theta_rad`` (rad, any shape) may err (``OnlineMapConfig``): (standard
        deviation rad of its normal part, probability that it is anything instead), each of that shape."""
        cfg = self.config
        shape = np.shape(theta_rad)
        std, start = cfg.direction_std_deg, cfg.large_turn_deg
        if self.map_confirmed:
            std, start = cfg.confirmed_direction_std_deg, max(start, self.confirmed_upto_deg + cfg.confirmed_margin_deg)
        anything = np.clip((np.degrees(theta_rad) - start) / cfg.large_turn_ramp_deg, 0.0, 1.0)
        return np.full(shape, math.radians(std)), anything

    def outcomes(self, control_dt: float, max_theta_rad: float = math.inf) -> TurnOutcomes:
        """The turns the planner may choose now and, for each, sigma points of their outcome
        (``TurnOutcomes``): map times every ``control_dt`` from one step up to the rising branch's
        peak (or, below it, the last whose expected turn is at most ``max_theta_rad``), flown ``t_map - shift``
        (at least one control step); each read at t_map + e for the three-point Gauss-Hermite nodes e of
        N(0, ``timing_std_s``) over the whole map (past the peak: the map's tumbling turns)."""
        t_full, th_full, t_psi, psi_full, off_full = self._curves()
        t_lo = max(control_dt, control_dt + self.shift_s)
        t_map = np.arange(t_lo, max(self.t_peak_s, t_lo) + 1e-9, control_dt)
        if math.isfinite(max_theta_rad):
            t_map = t_map[:leading_within(np.interp(t_map, t_full, th_full), max_theta_rad)]
        nodes, weights = GAUSS_HERMITE_3
        at = t_map[:, None] + nodes[None, :] * self.timing_std_s                          # (T, K)
        theta = np.interp(at, t_full, th_full)
        psi = np.interp(at, t_psi, psi_full) + self.psi_offset_rad
        offset = np.stack([np.interp(at, t_psi, off_full[:, k]) for k in range(3)], axis=-1)
        std, anything = self.direction_spread(theta)
        return TurnOutcomes(t_fly=t_map - self.shift_s, map_t=t_map, theta=theta, psi=psi, offset=offset,
                            direction_std=std, direction_anything=anything, weights=weights)

    def turn_at(self, map_t: float) -> tuple[float, float]:
        """The map's turn at map time ``map_t`` (s): (theta rad, psi rad with the direction offset)."""
        t_full, th_full, t_psi, psi_full, _ = self._curves()
        return (float(np.interp(map_t, t_full, th_full)),
                float(np.interp(map_t, t_psi, psi_full)) + self.psi_offset_rad)

    def _curves(self) -> tuple[np.ndarray, ...]:
        """The whole map (not only its rising branch): (t_c from 0 s, theta rad, t_c, psi rad unwrapped,
        offset (n, 3) m); cached."""
        if self._full is None:
            tm = self.turn_map
            t, th, _ = tm.theta_curve()
            tp, psi, _ = tm.psi_curve()
            off = np.array([tm.offset_for(x) for x in tp]).reshape(-1, 3)
            self._full = (np.concatenate([[0.0], t]), np.radians(np.concatenate([[0.0], th])), tp,
                          np.unwrap(np.radians(psi)), off)
        return self._full

    def predicted_theta_deg(self, t_c: float) -> float:
        """The corrected map's turn for a burst of ``t_c`` s flown."""
        t_branch, theta_branch = self._branch
        return float(np.interp(t_c + self.shift_s, t_branch, theta_branch))
