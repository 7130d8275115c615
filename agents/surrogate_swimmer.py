"""The turn-level swimmer: what one burst does, read from the calibrated turn map, with no rod.

A burst of t_c seconds at omega_h flown when the flagellum's reference direction (the map's phase node) lies at
azimuth beta about the heading d turns the heading by theta towards azimuth beta + psi and moves the head by the
map's displacement over the burst and its relaxation (``agents.turn_map``: Huang & Jawed 2020, Sec. 3 and
Fig. 5d; the geometry of ``agents.turn_planner.turn_ends`` and ``RulePlanner.rule_plan``, docs/planner.md):

    d'   = cos(theta) d + sin(theta) (cos(beta + psi) e1 + sin(beta + psi) e2),    (e1, e2) = perpendicular_basis(d)
    head' = head + off_0 d + off_1 e_ref + off_2 (d x e_ref),                      e_ref = cos(beta) e1 + sin(beta) e2

theta, psi, the displacement ``off`` (m), the relaxation time and L'/L at the burst's end are interpolated
bilinearly in (t_c, beta) between the map's measurements (t_c linear; beta periodic-linear between the measured
phases; psi through its unit vector, so its wrap does not matter). Below the shortest measured burst theta falls
linearly to 0 at t_c = 0; beyond the longest the map says nothing (``SurrogateTurn.in_range`` False, the longest
burst's values are used).

Another swimmer (E, mu, the head radius b, the helix pitch and radius randomised like ``FlagellumSteer-v0``,
``flagellum_env.config.draw_randomization``): a parameter error moves when the flagellum buckles, so to first order
the swimmer's burst of t_c turns it as the map's burst of another length (agents/online_turn_map.py). Measured on
the default preset one parameter at a time at +-5 % (``scripts/calibrate_surrogate_shift.py``, a burst of 3.3 s
read back on the map's rising branch) and written as a power law per factor f_k (swimmer's value / map's),

    t_map = t_c prod_k f_k^e_k,     e = E -1.24, mu +1.25, b +0.29, pitch -2.14, helix radius +2.15     (``map_time``)

(``SurrogateCalibration.burst_time_exponents``). E and mu enter as the viscous time tau = mu L^4 / EI does, and
their exponent agrees with the paper's nondimensionalisation (Sec. 2: time in units of tau, motor speed as
omega tau): a swimmer of tau at omega_h is the nominal one at omega_h tau / tau_0 with times scaled by tau / tau_0,
and the faithful maps at 90 and 150 rpm give t_c(theta) ~ omega_h^-alpha with alpha = 2.28-2.37 on the rising branch
(``burst_speed_exponent``), hence an exponent alpha - 1 = 1.31 for tau. The helix geometry weighs more: 4 % less
pitch turns the swimmer 1.4-2.2 times as far as the map says (scripts/compare_surrogate.py, randomised pairs). The
relaxation lasts tau / tau_0 times the map's; the cruise speed and the wobble period stay nominal; motor energies
scale with mu (Stokes drag is linear in mu at a given motor speed). Each factor must lie within
``FACTOR_RANGE`` (measured at +-5 %, the physics envs randomise +-10 % and +-5 %).

A burst ended by L'/L (``burst_end`` "ratio", ``agents.burst_flight``) stops when the swimmer's L'/L reaches the
map's after t_c, so it turns nearly as the map's burst of t_c whatever the swimmer's buckling time: measured on the
rod (``scripts/measure_ratio_clock.py``, docs/ratio_clock.json: swimmers within +-10 %, bursts of 2.8-3.6 s) it turns
as the map's burst of

    t_map = t_c + k (t_c - t_on) ln F,      F = prod_k f_k^e_k (above),   k = ``RATIO_CLOCK_COEFFICIENT``

(t_on: the shortest burst the clock reads, ``RatioClock.start_s``), against t_c F - t_c ~ t_c ln F flown by time:
the clock removes ~70 % of a swimmer's timing error (the map time turned as: 0.08-0.17 s rms from t_c against
0.38-0.47 s by time); near the map's peak (t_c = 3.6 s) the early bucklers' turns (ln F > ~0.18) flip past it, and
with this k the surrogate's do too (t_map beyond the map's peak). It flies t_map / F seconds. Shorter bursts are
flown by time.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
from numba import njit

from agents.online_turn_map import RatioClock
from agents.surrogate_calibration import SurrogateCalibration
from agents.turn_geometry import norm3, unit_basis, wrap_angle
from agents.turn_map import TurnMap
from physics.params import SwimmerParams

#: Each randomised factor (swimmer / map) the surrogate accepts: the burst time law was measured at +-5 %; the
#: physics envs randomise E, mu and b by +-10 % and the helix by +-5 %.
FACTOR_RANGE = (0.85, 1.15)
#: k of a burst ended by L'/L (module docstring): the least-squares fit of the map time the rod turned as, minus t_c,
#: on (t_c - t_on) ln F over the 91 of 96 bursts that stayed on the map's rising branch
#: (``scripts/measure_ratio_clock.py``, docs/ratio_clock.json: 24 swimmers within +-10 %, t_c = 2.8-3.6 s; the 5
#: that flipped past the peak left out; residual 0.05 s rms, against 0.32 s for bursts flown by time).
RATIO_CLOCK_COEFFICIENT = 0.89
#: factor name -> the ``SwimmerParams`` field it is read from (E scales G alike: ``draw_randomization``)
FACTOR_FIELDS = {"youngs_modulus": "youngs_modulus", "viscosity": "viscosity", "head_radius": "head_radius",
                 "pitch": "pitch", "helix_radius": "helix_radius"}


def burst_speed_exponent(slow: TurnMap, fast: TurnMap, thetas_deg=(10.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0)
                         ) -> np.ndarray:
    """alpha of t_c(theta) ~ omega_h^-alpha between two maps of one swimmer at two burst speeds, one per theta
    (deg) on both rising branches, (len(thetas_deg),)."""
    ratio = math.log(fast.omega_h_rpm / slow.omega_h_rpm)
    return np.array([math.log(slow.t_c_for(th) / fast.t_c_for(th)) / ratio for th in thetas_deg])


class SurrogateTurn(NamedTuple):
    """One burst's outcome: ``heading`` (3,) unit, ``displacement`` (3,) m over the burst and ``relax_s``,
    ``theta_rad``, ``psi_rad``, ``relax_s`` (s, for this swimmer), ``end_ratio`` (L'/L at the burst's end),
    ``map_time_s`` (the map's burst length it was read at), ``in_range`` (within the map's burst lengths)."""

    heading: np.ndarray
    displacement: np.ndarray
    theta_rad: float
    psi_rad: float
    relax_s: float
    end_ratio: float
    map_time_s: float
    in_range: bool


class TurnMapTable:
    """The map's measurements on a (t_c, phase) grid for bilinear reads. ``t_c`` (K,) s, ``phases`` (P,) rad
    increasing in [0, 2 pi); ``theta`` (K, P) rad, ``psi_cos``/``psi_sin`` (K, P), ``offset`` (K, P, 3) m,
    ``relax`` (K, P) s, ``end_ratio`` (K, P). ValueError if the map is not a full grid."""

    def __init__(self, turn_map: TurnMap) -> None:
        tcs = turn_map.t_c_values()
        phases = np.array(sorted({p.phase_deg % 360.0 for p in turn_map.points}))
        k_of = {float(t): k for k, t in enumerate(tcs)}
        j_of = {float(ph): j for j, ph in enumerate(phases)}
        shape = (len(tcs), len(phases))
        filled = np.zeros(shape, bool)
        theta, psi, relax, ratio = (np.empty(shape) for _ in range(4))
        offset = np.empty(shape + (3,))
        for p in turn_map.points:
            k, j = k_of[float(p.t_c)], j_of[float(p.phase_deg % 360.0)]
            filled[k, j] = True
            theta[k, j], psi[k, j] = math.radians(p.theta_deg), math.radians(p.psi_deg)
            relax[k, j], ratio[k, j], offset[k, j] = p.relax_s, p.burst_end_ratio, p.offset_m
        if not filled.all():
            raise ValueError(f"the turn map is not a full grid of burst lengths x phases ({int(filled.sum())} of "
                             f"{filled.size} measured); the surrogate interpolates on a grid")
        self.t_c, self.phases = tcs, np.radians(phases)
        self.theta, self.psi_cos, self.psi_sin = theta, np.cos(psi), np.sin(psi)
        self.offset, self.relax, self.end_ratio = offset, relax, ratio
        #: every channel stacked, (K, P, 8): theta, cos psi, sin psi, offset (3), relax, L'/L, read at once
        self.channels = np.concatenate([np.stack([theta, np.cos(psi), np.sin(psi)], axis=-1), offset,
                                        np.stack([relax, ratio], axis=-1)], axis=-1)
        #: the map's L'/L against burst length (bursts ended by L'/L)
        self.clock = RatioClock(turn_map)


@njit(cache=True)
def read_map(t: np.ndarray, ph: np.ndarray, channels: np.ndarray, t_map: float, beta: float
             ) -> tuple[float, float, float, float, float, float, float, float, float, bool]:
    """``channels`` (K, P, 8) read bilinearly at the map time ``t_map`` (s) between the burst lengths ``t`` (K,) s and
    periodically at ``beta`` (rad) between the phases ``ph`` (P,) rad increasing in [0, 2 pi); then theta_scale (< 1
    below the shortest burst: theta -> 0 at t_c = 0; the shortest burst's values) and in_range (within the burst
    lengths; beyond them the longest burst's values)."""
    n_t, n = t.shape[0], ph.shape[0]
    in_range = 0.0 <= t_map <= t[n_t - 1] + 1e-9
    scale = 1.0
    if t_map <= t[0]:
        k0 = k1 = 0
        w_t = 0.0
        scale = max(t_map, 0.0) / t[0]
    elif t_map >= t[n_t - 1]:
        k0 = k1 = n_t - 1
        w_t = 0.0
    else:
        k1 = np.searchsorted(t, t_map, side="right")
        k0 = k1 - 1
        w_t = (t_map - t[k0]) / (t[k1] - t[k0])
    two_pi = 2.0 * math.pi
    b = beta % two_pi
    j1 = np.searchsorted(ph, b, side="right") % n
    j0 = (j1 - 1) % n
    span = (ph[j1] - ph[j0]) % two_pi
    if span == 0.0:
        span = two_pi
    w_b = ((b - ph[j0]) % two_pi) / span
    v = np.empty(8)
    for c in range(8):
        v[c] = ((1.0 - w_t) * ((1.0 - w_b) * channels[k0, j0, c] + w_b * channels[k0, j1, c])
                + w_t * ((1.0 - w_b) * channels[k1, j0, c] + w_b * channels[k1, j1, c]))
    return v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], scale, in_range


@njit(cache=True)
def turn_outcome(t: np.ndarray, ph: np.ndarray, channels: np.ndarray, t_map: float, beta: float, d: np.ndarray,
                 direction_bias: float, turn_scale: float
                 ) -> tuple[float, float, float, float, float, float, float, float, float, float, bool]:
    """``SurrogateSwimmer.turn``'s outcome, compiled: (the new heading, 3 components; the displacement, 3, m; theta,
    psi rad; the map's relaxation s; L'/L; in_range) of the map (``read_map``'s ``t``, ``ph``, ``channels``) read at
    the map time ``t_map`` (s) and the azimuth ``beta`` (rad) about the unit heading ``d`` (3,), its direction moved
    by ``direction_bias`` (rad) and its size scaled by ``turn_scale`` (``SurrogateSwimmer``)."""
    th, pc, ps, o0, o1, o2, relax, ratio, scale, in_range = read_map(t, ph, channels, t_map, beta)
    theta, psi = scale * th, math.atan2(ps, pc)
    ref = beta   # the azimuth of e_ref, the displacement's lateral frame
    if direction_bias != 0.0 or turn_scale != 1.0:
        theta = min(max(turn_scale * theta, 0.0), math.pi)
        psi = wrap_angle(psi + direction_bias)
        ref = beta + direction_bias
    h0, h1, h2, x0, x1, x2 = turned(d, theta, psi, beta, ref, o0, o1, o2)
    return h0, h1, h2, x0, x1, x2, theta, psi, relax, ratio, in_range


@njit(cache=True)
def turned(d: np.ndarray, theta: float, psi: float, beta: float, ref: float, o0: float, o1: float, o2: float
           ) -> tuple[float, float, float, float, float, float]:
    """(the new unit heading, the head's displacement m), 3 components each, of a turn by ``theta`` (rad) towards azimuth
    beta + psi (rad) about the unit heading ``d`` (3,) and the map's displacement (o0, o1, o2) m along d, e_ref
    (azimuth ``ref``, rad) and d x e_ref (module docstring; ``perpendicular_basis(d)`` = (e1, e2))."""
    e1, e2 = unit_basis(d / norm3(d))
    d0, d1, d2 = d[0], d[1], d[2]
    a0, a1, a2 = e1[0], e1[1], e1[2]
    b0, b1, b2 = e2[0], e2[1], e2[2]
    ca, sa = math.cos(beta + psi), math.sin(beta + psi)
    ct, st = math.cos(theta), math.sin(theta)
    h0, h1, h2 = ct * d0 + st * (ca * a0 + sa * b0), ct * d1 + st * (ca * a1 + sa * b1), ct * d2 + st * (ca * a2 + sa * b2)
    hn = math.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    cb, sb = math.cos(ref), math.sin(ref)
    r0, r1, r2 = cb * a0 + sb * b0, cb * a1 + sb * b1, cb * a2 + sb * b2   # e_ref
    p0, p1, p2 = d1 * r2 - d2 * r1, d2 * r0 - d0 * r2, d0 * r1 - d1 * r0   # d x e_ref
    return (h0 / hn, h1 / hn, h2 / hn, o0 * d0 + o1 * r0 + o2 * p0, o0 * d1 + o1 * r1 + o2 * p1,
            o0 * d2 + o1 * r2 + o2 * p2)


class SurrogateSwimmer:
    """The kinematic swimmer of one episode (module docstring). ``turn_map`` and ``calibration`` are the nominal
    swimmer's; ``params`` this episode's swimmer (``draw_randomization``); ValueError naming the value if a factor
    lies outside ``FACTOR_RANGE`` or another parameter differs from the map's."""

    def __init__(self, turn_map: TurnMap, calibration: SurrogateCalibration, table: TurnMapTable,
                 params: SwimmerParams | None = None) -> None:
        self.turn_map, self.calibration, self.table = turn_map, calibration, table
        params = turn_map.params if params is None else params
        lo, hi = FACTOR_RANGE
        self.time_factor = 1.0
        for name, field in FACTOR_FIELDS.items():
            f = getattr(params, field) / getattr(turn_map.params, field)
            if not lo <= f <= hi:
                raise ValueError(f"swimmer with {field} = {getattr(params, field):.4g} ({f:.3g} x the map's) is "
                                 f"outside the surrogate's calibrated range [{lo}, {hi}] x the map's")
            self.time_factor *= f ** calibration.burst_time_exponents[name]
        others = [] if params is turn_map.params else [  # the map's own swimmer differs in nothing
            f.name for f in dataclasses.fields(SwimmerParams) if f.name not in (*FACTOR_FIELDS.values(),
            "shear_modulus") and getattr(params, f.name) != getattr(turn_map.params, f.name)]
        if others:
            raise ValueError(f"swimmer differs from the map's in {others}; the surrogate is calibrated for "
                             f"{sorted(FACTOR_FIELDS)} only")
        self.tau_ratio = params.viscous_time / turn_map.params.viscous_time
        self.mu_ratio = params.viscosity / turn_map.params.viscosity
        self.speed_m_s = calibration.cruise_speed_m_s
        self.period_s = turn_map.period_s
        self.cruise_power_w = calibration.cruise_power_w * self.mu_ratio
        #: a randomised map (``FlagellumBurst-surrogate-v0``'s ``map_noise``; set by the env): every turn's
        #: direction psi is moved by ``direction_bias_rad`` (the displacement's lateral part rotated alike about the
        #: heading) and its size theta scaled by ``turn_scale`` (clipped to [0, pi]); 0 and 1: the map as measured
        self.direction_bias_rad, self.turn_scale = 0.0, 1.0

    def map_time(self, t_c: float) -> float:
        """The map's burst length (s) that turns the nominal swimmer as ``t_c`` s turn this one."""
        return t_c * self.time_factor

    def burst_times(self, t_c: float, burst_end: str = "time") -> tuple[float, float]:
        """(the burst's flight time, the map's burst length it turns as), s, for a command of ``t_c`` s ended by
        ``burst_end`` ("time" or "ratio": the module docstring)."""
        start = self.table.clock.start_s
        if burst_end == "ratio" and self.table.clock.ratio_for(t_c) is not None:
            t_map = t_c + RATIO_CLOCK_COEFFICIENT * (t_c - start) * math.log(self.time_factor)
            return t_map / self.time_factor, t_map
        return t_c, self.map_time(t_c)

    def burst_energy_j(self, t_c: float, burst_end: str = "time") -> float:
        """Motor energy of a burst of ``t_c`` s at omega_h ended by ``burst_end``, J (the calibration's, times
        mu / mu_0)."""
        return self.calibration.burst_energy(self.burst_times(t_c, burst_end)[1]) * self.mu_ratio

    def turn(self, d: np.ndarray, t_c: float, beta: float, burst_end: str = "time") -> SurrogateTurn:
        """The outcome of a burst of ``t_c`` s ended by ``burst_end`` (``burst_times``) at the reference
        direction's azimuth ``beta`` (rad) about the unit heading ``d`` (3,)."""
        t_map = self.burst_times(t_c, burst_end)[1]
        tab = self.table
        h0, h1, h2, x0, x1, x2, theta, psi, relax, ratio, in_range = turn_outcome(
            tab.t_c, tab.phases, tab.channels, t_map, beta, np.asarray(d, dtype=np.float64), self.direction_bias_rad,
            self.turn_scale)
        return SurrogateTurn(np.array([h0, h1, h2]), np.array([x0, x1, x2]), theta, psi, relax * self.tau_ratio, ratio,
                             float(t_map), bool(in_range))
