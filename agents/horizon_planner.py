"""A receding-horizon planner over the online-corrected turn map (controller ``horizon``).

The rule planner (``agents.turn_planner``) and the adaptive planner (``agents.adaptive_planner``)
look one turn ahead: the best *next* burst, judged by where its straight line passes the next
waypoint. Issue #23 measured what that misses: circling a waypoint 5-6 cm away (every turn
displaces the head about as far as the target is), paths that start with the target behind
(capped turns push the head forwards against the 10 cm corridor), and out-of-plane drift on
planar paths. This planner searches short sequences of the moves the swimmer can make instead.

A *move* is: cruise on at omega_l for a distance d (``HorizonConfig.cruise_m``, including 0),
then a burst planned for map time m at flagellum phase beta (hover, burst, relax: the head moves
by the map's offset and the heading turns by the map's theta in the direction beta + psi).
Two moves deep, the predicted head path (polyline of the cruises and the turns' offsets, then
the straight line of the last heading) is scored against the remaining waypoints
(``sequence_cost``):

- the closest approach to the next waypoint A (a target behind the last heading counts its
  distance plus a penalty graded by how far behind it is, as in ``graded_line_miss``),
- once A is passed within the reach radius, the closest approach of the rest of the path to the
  waypoint after it, B (weight ``weight_next``),
- the largest predicted distance from the path (``track_weight``), and the 10 cm corridor: predicted
  points farther than ``corridor_soft_m`` from the segment being
  followed cost ``corridor_weight`` per metre beyond it (and 1 m past ``corridor_hard_m``),
- on planar segments (previous waypoint, A and B at z = 0 in the start frame) the largest
  predicted |z| and the last heading's out-of-plane slope (``planar_weight``),
- time: cruise distance and bursts (``cruise_cost``, ``burst_cost_m``).

**Uncertainty is used, not only estimated** (``TurnModel``): a burst planned for map time m
comes out at map time m + e, e ~ N(0, sigma_m) with sigma_m the online map's bias spread when
the burst is flown by L'/L (else its shift spread), and its direction off by N(0, sigma_psi)
(``psi_prior_std_deg``, shrinking with every direction reading). Each first move is predicted for
five sigma points of (e, direction error); the map is read at the sampled time over its
*whole* measured range, so a sample past the rising branch's peak predicts the tumble the
swimmer would make there. For every sample the best second move is chosen for the state that
sample reaches (closed loop: the second move is re-planned after the first is observed), and the
first move's score is the weighted mean over samples plus ``risk`` x their standard deviation.
While the correction is uncertain, a large turn near the branch's peak has widely spread
outcomes and loses to smaller ones (the adaptive planner's 80 deg cap comes out of the search);
once the map fits (or on the nominal swimmer, whose turns read as such), the full turn wins.

The first move is executed: if it starts with a cruise, the planner keeps cruising and searches
again ``replan_s`` later (so "swim on, then turn" is a decision re-made as the head moves); if it
is a burst now, it is flown exactly like the adaptive planner's (hover to the phase, burst ended
by L'/L, relax, observe the turn, update the correction: ``OnlineTurnMap``). Cost: every first
move (cruise x map time x phase, ~1000) against samples at depth one, then the best
``beam`` per cruise distance in closed loop against every second move, all in NumPy: a few ms
per search, a few searches per turn (``tests/agents/test_horizon_planner.py`` times it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from agents.adaptive_planner import AdaptivePlanner, AdaptiveEpisode, segment_distance
from agents.online_turn_map import OnlineMapConfig, OnlineTurnMap
from agents.turn_map import TurnMap
from agents.turn_geometry import perpendicular_basis, wrap_angle
from agents.turn_measurement import summarise_cruise
from physics.validation import require_finite

#: Sigma points of a standard 2-D normal (map-time error, direction error), in standard deviations,
#: and their weights: the mean and +-sqrt(3) along each axis (exact to the 4th moment along the axes).
_SIGMA_POINTS = np.array([[0.0, 0.0], [-math.sqrt(3.0), 0.0], [math.sqrt(3.0), 0.0], [0.0, -math.sqrt(3.0)],
                          [0.0, math.sqrt(3.0)]])
_SIGMA_WEIGHTS = np.array([1.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0])


@dataclass(frozen=True)
class HorizonConfig:
    """Search grid and score weights (lengths in m, times in s, angles in degrees).

    cruise_m: cruise distances before the first burst (0 = burst now). second_cruise_m: before
    the second. map_time_step_s: spacing of the first burst's planned map times (the rising branch
    from ``min_turn_deg`` to its peak); second_map_times: how many map times the second burst
    chooses from (evenly over the same range). phase_step_deg / second_phase_step_deg: burst
    phases searched. beam: first moves per cruise distance kept for the closed-loop stage.
    psi_prior_std_deg: spread of a turn's direction before any reading; then the rms of the azimuth
    errors seen (turns of ``psi_min_theta_deg`` or more), the prior counting as ``psi_prior_weight``
    readings. time_floor_s: the least spread of a burst's map time. risk: weight of the samples' standard deviation in a first move's score.
    second_spread: the second burst's map-time spread as a fraction of the first's (it is flown
    after the first has been observed); its predicted spread costs ``spread_length_m`` x the
    angle's standard deviation (rad). weight_next: weight of the waypoint after the next.
    hit_fraction: a waypoint passed within this x the reach radius counts as reached.
    track_weight: per metre of the largest predicted distance from the path (the segment being followed,
    the next one once its waypoint is passed): keeps corners tight (cross-track is what is measured).
    corridor_soft_m / corridor_weight / corridor_hard_m: the corridor's soft and hard limits.
    planar_weight: per metre of predicted |z| on planar segments (the heading's slope counts over
    ``planar_look_m``). cruise_cost: per metre of cruise; burst_cost_m: per burst.
    improvement_m: a burst is flown only if it beats swimming straight by this much.
    replan_s: search again after this long while cruising (s of simulated time).
    """

    cruise_m: tuple[float, ...] = (0.0, 0.005, 0.015, 0.03, 0.05)
    second_cruise_m: tuple[float, ...] = (0.0, 0.02)
    map_time_step_s: float = 0.2
    second_map_times: int = 6
    phase_step_deg: float = 10.0
    second_phase_step_deg: float = 30.0
    min_turn_deg: float = 5.0
    beam: int = 10
    psi_prior_std_deg: float = 20.0
    psi_prior_weight: float = 2.0
    psi_min_theta_deg: float = 20.0
    time_floor_s: float = 0.15
    risk: float = 1.0
    second_spread: float = 0.5
    spread_length_m: float = 0.05
    weight_next: float = 0.3
    hit_fraction: float = 0.6
    track_weight: float = 0.5
    corridor_soft_m: float = 0.07
    corridor_weight: float = 10.0
    corridor_hard_m: float = 0.095
    planar_weight: float = 2.0
    planar_look_m: float = 0.05
    cruise_cost: float = 0.1
    burst_cost_m: float = 0.015
    improvement_m: float = 0.005
    replan_s: float = 5.0

    def __post_init__(self) -> None:
        for name in ("cruise_m", "second_cruise_m"):
            vals = getattr(self, name)
            if not vals or any(not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0.0) for v in vals):
                raise ValueError(f"HorizonConfig.{name}={vals!r} is not allowed; allowed: distances >= 0 m")
            if 0.0 not in vals:
                raise ValueError(f"HorizonConfig.{name}={vals!r} must include 0 (turn without cruising first)")
        for name in ("map_time_step_s", "phase_step_deg", "second_phase_step_deg", "psi_prior_std_deg",
                     "spread_length_m", "hit_fraction", "corridor_soft_m", "corridor_hard_m", "replan_s"):
            require_finite(f"HorizonConfig.{name}", getattr(self, name), 0.0, lo_open=True)
        for name in ("psi_prior_weight", "psi_min_theta_deg", "time_floor_s", "track_weight", "min_turn_deg", "risk",
                     "second_spread", "weight_next", "corridor_weight", "planar_weight",
                     "planar_look_m", "cruise_cost", "burst_cost_m", "improvement_m"):
            require_finite(f"HorizonConfig.{name}", getattr(self, name), 0.0)
        for name in ("second_map_times", "beam"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"HorizonConfig.{name}={v!r} is not allowed; allowed: an integer >= 1")


# --- what a burst does, with its spread ---------------------------------------------------------
@dataclass(frozen=True)
class TurnModel:
    """The (corrected) map as the search reads it: turn angle theta (rad), direction psi (rad,
    unwrapped, direction offset included) and head offset (m, along heading, phase-node direction,
    heading x that) against map time (s) on ``grid`` (the map's whole measured range); the map
    times a plan may choose (``candidates``, s) with the spread of the map time they come out at
    (``time_std``, s) and the direction's spread (``psi_std``, rad). ``shift_s``: flown time =
    map time - shift_s."""

    grid: np.ndarray
    theta: np.ndarray
    psi: np.ndarray
    offset: np.ndarray
    candidates: np.ndarray
    time_std: np.ndarray
    psi_std: float
    shift_s: float = 0.0

    def at(self, m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(theta rad, psi rad, offset (..., 3) m) at map times ``m`` (clipped to the grid)."""
        m = np.clip(m, self.grid[0], self.grid[-1])
        off = np.stack([np.interp(m, self.grid, self.offset[:, k]) for k in range(3)], axis=-1)
        return np.interp(m, self.grid, self.theta), np.interp(m, self.grid, self.psi), off

    @classmethod
    def from_online(cls, online: OnlineTurnMap, step_s: float, min_turn_deg: float, psi_prior_std_deg: float,
                    min_flown_s: float, time_floor_s: float = 0.0, azimuth_errors_deg: list[float] | None = None,
                    psi_prior_weight: float = 2.0) -> TurnModel:
        """From the adaptive planner's online map: its shift, bias and direction offset and their spreads.

        The map-time spread is the online map's, at least ``time_floor_s`` (a burst ends on a control
        step; the ratio-turn relation scatters from turn to turn). The direction's spread is learnt
        from the azimuth errors of the turns seen (``azimuth_errors_deg``: observed minus predicted),
        with the prior ``psi_prior_std_deg`` counting as ``psi_prior_weight`` readings; it does not
        shrink below what the turns show."""
        table = _map_table(online.turn_map)
        grid, theta, psi, off = table
        t_branch, theta_branch = online.turn_map.rising_branch()
        lo = float(np.interp(min_turn_deg, theta_branch, t_branch))
        lo = max(lo, min_flown_s + online.shift_s)
        hi = float(t_branch[-1])
        cand = np.arange(lo, max(hi, lo) + 1e-9, step_s)
        if cand[-1] < hi - 1e-9:
            cand = np.append(cand, hi)
        cfg = online.config
        by_ratio = np.array([cfg.fly_by_ratio and online.ratio_for(m - online.bias_s) is not None for m in cand])
        std = np.maximum(np.where(by_ratio, online.bias_std_s, online.shift_std_s), time_floor_s)
        errs = np.asarray(azimuth_errors_deg or [], dtype=float)
        psi_var = (psi_prior_weight * psi_prior_std_deg ** 2 + float(np.sum(errs ** 2))) / (psi_prior_weight + len(errs))
        psi_std = math.radians(math.sqrt(psi_var))
        return cls(grid, theta, psi + online.psi_offset_rad, off, cand, std, psi_std, online.shift_s)


_TABLES: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}


def _map_table(tm: TurnMap, step_s: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(grid s, theta rad, psi rad unwrapped, offset (G, 3) m) over the map's whole range (mean over
    phases; theta = 0 and no offset but the cruise at map time 0)."""
    key = id(tm)
    if key not in _TABLES:
        tcs, th, _ = tm.theta_curve()
        grid = np.arange(0.0, float(tcs[-1]) + 1e-9, step_s)
        theta = np.radians(np.interp(grid, np.concatenate([[0.0], tcs]), np.concatenate([[0.0], th])))
        psi = np.unwrap(np.radians([tm.psi_for(t) for t in grid]))
        off = np.array([tm.offset_for(t) for t in grid]).reshape(-1, 3)
        _TABLES[key] = (grid, theta, psi, off)
    return _TABLES[key]


# --- the search ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Situation:
    """What a plan is made against (start frame, m): head, unit heading, the next waypoint
    ``target``, the one after (``after``, None at the last), the start of the segment being
    followed, the reach radius, whether the path is planar here."""

    head: np.ndarray
    heading: np.ndarray
    target: np.ndarray
    after: np.ndarray | None
    segment_start: np.ndarray
    reach_m: float
    planar: bool


@dataclass
class MoveChoice:
    """The best first move: cruise (m) then a burst planned for map time ``map_t`` (s) at
    ``phase`` (rad, about ``perpendicular_basis(heading)``); ``burst`` False: keep swimming straight.
    ``cost`` its score, ``straight_cost`` swimming straight's, ``second``: the second move chosen
    for the mean outcome (cruise m, map time s, phase rad) or None."""

    cruise_m: float
    map_t: float
    phase: float
    burst: bool
    cost: float
    straight_cost: float
    theta: float = 0.0
    azimuth: float = 0.0
    second: tuple[float, float, float] | None = None
    details: dict = field(default_factory=dict)


def _basis_rows(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Right-handed unit vectors (e1, e2) across each row of h (n, 3)."""
    helper = np.zeros_like(h)
    helper[:, 2] = 1.0
    flip = np.abs(h[:, 2]) >= 0.9
    helper[flip] = (1.0, 0.0, 0.0)
    e1 = helper - np.einsum("ij,ij->i", helper, h)[:, None] * h
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(h, e1)


def _turn(p, h, e1, e2, beta, theta, psi, off):
    """Head after a burst at phase beta (rad) turning theta in direction beta + psi with offset off;
    shapes broadcast over leading axes, vectors on the last. Returns (p', h')."""
    cb, sb = np.cos(beta)[..., None], np.sin(beta)[..., None]
    e_ref = cb * e1 + sb * e2
    e_perp = np.cross(h, e_ref)
    az = beta + psi
    across = np.cos(az)[..., None] * e1 + np.sin(az)[..., None] * e2
    h2 = np.cos(theta)[..., None] * h + np.sin(theta)[..., None] * across
    h2 = h2 / np.linalg.norm(h2, axis=-1, keepdims=True)
    p2 = p + off[..., 0:1] * h + off[..., 1:2] * e_ref + off[..., 2:3] * e_perp
    return p2, h2


def _seg_closest(a, b, q):
    """For segments a->b (..., 3) and point q (3,): (distance, parameter in [0, 1])."""
    ab = b - a
    den = np.maximum(np.einsum("...k,...k->...", ab, ab), 1e-18)
    t = np.clip(np.einsum("...k,...k->...", q - a, ab) / den, 0.0, 1.0)
    return np.linalg.norm(a + t[..., None] * ab - q, axis=-1), t


def _ray_miss(p, h, q, behind_penalty: float = 0.2):
    """Graded miss of rays p + s h (s >= 0) to q: lateral distance if q is ahead, else its distance
    plus ``behind_penalty`` x the cosine of how far behind (``graded_line_miss``); and the
    distance along the ray to the closest point (0 if behind)."""
    rel = q - p
    along = np.einsum("...k,...k->...", rel, h)
    dist = np.linalg.norm(rel, axis=-1)
    lateral = np.linalg.norm(rel - along[..., None] * h, axis=-1)
    miss = np.where(along > 0.0, lateral, dist - behind_penalty * along / np.maximum(dist, 1e-12))
    return miss, np.maximum(along, 0.0)


def sequence_cost(sit: Situation, points: list[np.ndarray], h_last: np.ndarray, n_bursts: np.ndarray | int,
                  cruise_total: np.ndarray | float, cfg: HorizonConfig) -> np.ndarray:
    """Score of predicted head paths (module docstring): ``points`` the polyline's vertices from
    the head on (each (..., 3) m, the first may be the head itself), then the ray along
    ``h_last``; lower is better, m-equivalent."""
    A, B = sit.target, sit.after
    hit_r = cfg.hit_fraction * sit.reach_m
    shape = np.broadcast_shapes(*(np.shape(p)[:-1] for p in points), h_last.shape[:-1])
    h_last = np.broadcast_to(h_last, shape + (3,))
    # closest approach to A, piece by piece (first piece reaching A wins)
    best = np.full(shape, np.inf)
    where = np.full(shape, len(points) - 1, dtype=np.int64)     # piece index of the approach (len-1: the ray)
    frac = np.zeros(shape)
    hit = np.zeros(shape, dtype=bool)
    for k in range(len(points) - 1):
        d, t = _seg_closest(points[k], points[k + 1], A)   # at the pieces' own (smaller) shapes
        better = ~hit & (d < best)
        best = np.where(better, d, best)
        where = np.where(better, k, where)
        frac = np.where(better, t, frac)
        hit |= d <= hit_r
    p_end = np.broadcast_to(points[-1], shape + (3,))
    ray_d, ray_s = _ray_miss(p_end, h_last, A)
    better = ~hit & (ray_d < best)
    best = np.where(better, ray_d, best)
    where = np.where(better, len(points) - 1, where)
    hit |= ray_d <= hit_r
    cost = np.maximum(best - 0.5 * hit_r, 0.0)
    # the approach point
    q = np.broadcast_to(p_end, shape + (3,)) + np.where(where == len(points) - 1, ray_s, 0.0)[..., None] * h_last
    for k in range(len(points) - 1):
        a, b = points[k], points[k + 1]
        q = np.where((where == k)[..., None], a + frac[..., None] * (b - a), q)
    # corridor and planar drift at the vertices (segment S->A before the approach, A->B after) and q
    seg2_end = B if B is not None else A
    xt_max = segment_distance(q, sit.segment_start, A)
    z_max = np.abs(q[..., 2])
    for k in range(1, len(points)):
        v = points[k]
        xt = np.where(k <= where, segment_distance(v, sit.segment_start, A), segment_distance(v, A, seg2_end))
        xt_max = np.maximum(xt_max, xt)
        z_max = np.maximum(z_max, np.abs(v[..., 2]))
    cost = cost + cfg.track_weight * xt_max + cfg.corridor_weight * np.maximum(xt_max - cfg.corridor_soft_m, 0.0)
    cost = cost + np.where(xt_max > cfg.corridor_hard_m, 1.0, 0.0)
    if sit.planar:
        cost = cost + cfg.planar_weight * (z_max + cfg.planar_look_m * np.abs(h_last[..., 2]))
    # the waypoint after: closest approach of what follows the approach to A
    if B is not None and float(np.linalg.norm(B - A)) > 1e-9:
        nb = np.full(shape, np.inf)
        start = q
        for k in range(len(points) - 1):
            a = np.where((where == k)[..., None], q, points[k])
            d, _ = _seg_closest(a, points[k + 1], B)
            nb = np.where(where <= k, np.minimum(nb, d), nb)
        rd, _ = _ray_miss(np.where((where == len(points) - 1)[..., None], start, p_end), h_last, B)
        nb = np.minimum(nb, rd)
        nb = np.where(hit, nb, float(np.linalg.norm(B - A)))
        cost = cost + cfg.weight_next * nb
    return cost + cfg.cruise_cost * cruise_total + cfg.burst_cost_m * n_bursts


def search(sit: Situation, model: TurnModel, cfg: HorizonConfig) -> MoveChoice:
    """The best first move of two (module docstring); vectorised over every sequence."""
    head, h = np.asarray(sit.head, float), np.asarray(sit.heading, float)
    e1, e2 = perpendicular_basis(h)
    straight = float(sequence_cost(sit, [head], h[None, :], 0, 0.0, cfg)[0])

    # first moves: cruise x map time x phase (F), each for S samples of (map-time error, direction error)
    d1 = np.asarray(cfg.cruise_m, float)
    m1 = model.candidates
    beta = np.radians(np.arange(0.0, 360.0, cfg.phase_step_deg))
    D, T, Bn = len(d1), len(m1), len(beta)
    zt, zp, w = _SIGMA_POINTS[:, 0], _SIGMA_POINTS[:, 1], _SIGMA_WEIGHTS      # (S,)
    S = len(w)
    m_s = m1[:, None] + zt[None, :] * model.time_std[:, None]                   # (T, S)
    th_s, psi_s, off_s = model.at(m_s)
    psi_s = psi_s + zp[None, :] * model.psi_std
    p1 = head[None, :] + d1[:, None] * h[None, :]                               # (D, 3)
    # broadcast to (D, T, B, S)
    P1 = p1[:, None, None, None, :]
    bet = beta[None, None, :, None]
    p2, h2 = _turn(P1, h, e1, e2, bet, th_s[None, :, None, :], psi_s[None, :, None, :],
                   off_s[None, :, None, :, :])
    shape = (D, T, Bn, S)
    h2 = np.broadcast_to(h2, shape + (3,))
    P1b = np.broadcast_to(P1, shape + (3,))
    cruise1 = np.broadcast_to(d1[:, None, None, None], shape)
    one = sequence_cost(sit, [head, P1b, p2], h2, 1, cruise1, cfg)              # (D, T, B, S)
    mean1 = np.einsum("dtbs,s->dtb", one, w)
    std1 = np.sqrt(np.maximum(np.einsum("dtbs,s->dtb", (one - mean1[..., None]) ** 2, w), 0.0))
    score1 = mean1 + cfg.risk * std1

    # closed loop: the best `beam` first moves per cruise distance, against every second move
    flat = score1.reshape(D, -1)
    k = min(cfg.beam, flat.shape[1])
    keep = np.argpartition(flat, k - 1, axis=1)[:, :k]                          # (D, k)
    di = np.repeat(np.arange(D), k)
    ti, bi = np.unravel_index(keep.ravel(), (T, Bn))
    n1 = len(di)
    P1k, p2k, h2k = p1[di], p2[di, ti, bi], h2[di, ti, bi]                      # (n1, [S,] 3)
    d2 = np.asarray(cfg.second_cruise_m, float)
    m2 = np.linspace(m1[0], m1[-1], cfg.second_map_times) if len(m1) > 1 else m1
    beta2 = np.radians(np.arange(0.0, 360.0, cfg.second_phase_step_deg))
    th2, psi2, off2 = model.at(m2)
    std2 = cfg.second_spread * np.interp(m2, m1, model.time_std)
    slope = np.abs(np.gradient(model.theta, model.grid))
    spread2 = np.hypot(np.interp(m2, model.grid, slope) * std2, np.sin(th2) * model.psi_std * cfg.second_spread)
    # second moves: (D2, T2, B2) plus "none"; states: (n1, S)
    hs = h2k.reshape(-1, 3)
    f1, f2 = _basis_rows(hs)
    f1 = f1.reshape(n1, S, 3)
    f2 = f2.reshape(n1, S, 3)
    ex = (slice(None), slice(None), None, None, None)                           # (n1, S) -> (n1, S, D2, T2, B2)
    P3 = p2k[ex] + d2[None, None, :, None, None, None] * h2k[ex]
    p4, h4 = _turn(P3, h2k[ex], f1[ex], f2[ex], beta2[None, None, None, None, :],
                   th2[None, None, None, :, None], psi2[None, None, None, :, None],
                   off2[None, None, None, :, None, :])
    shp = (n1, S, len(d2), len(m2), len(beta2))
    P1e = P1k[:, None, None, None, None, :]
    p2e = p2k[ex]
    P3e = P3
    extra = cfg.spread_length_m * spread2[None, None, None, :, None]
    cruise12 = d1[di][:, None, None, None, None] + d2[None, None, :, None, None]
    two = sequence_cost(sit, [head, P1e, p2e, P3e, p4], h4, 2, cruise12, cfg) + extra
    best2 = two.reshape(n1, S, -1).min(axis=2)
    arg2 = two.reshape(n1, S, -1).argmin(axis=2)
    none = one[di, ti, bi]                                                      # (n1, S): no second burst
    closed = np.minimum(best2, none)
    mean = closed @ w
    std = np.sqrt(np.maximum(((closed - mean[:, None]) ** 2) @ w, 0.0))
    score = mean + cfg.risk * std
    j = int(np.argmin(score))
    d_j, t_j, b_j = int(di[j]), int(ti[j]), int(bi[j])
    mid = 0                                                                     # the mean sample (0, 0)
    second = None
    if best2[j, mid] < none[j, mid]:
        a, b, c = np.unravel_index(int(arg2[j, mid]), shp[2:])
        second = (float(d2[a]), float(m2[b]), float(beta2[c]))
    th_mean, psi_mean, _ = model.at(np.array([m1[t_j]]))
    burst = bool(score[j] < straight - cfg.improvement_m)
    return MoveChoice(cruise_m=float(d1[d_j]), map_t=float(m1[t_j]), phase=float(beta[b_j]), burst=burst,
                      cost=float(score[j]), straight_cost=straight, theta=float(th_mean[0]),
                      azimuth=wrap_angle(float(beta[b_j] + psi_mean[0])), second=second,
                      details={"cost_std": float(std[j]), "time_std_s": float(model.time_std[t_j]),
                               "psi_std_deg": math.degrees(model.psi_std)})


# --- the controller -----------------------------------------------------------------------------
#: The online correction the horizon planner starts from: the adaptive planner's, with the prior spread of the
#: ratio-turn bias at 0.15 s instead of 0.3 s. Bursts flown by L'/L on the dev swimmers (E, mu, b within 10 %,
#: seeds 5000-5002) ended within 0.05-0.15 s of map time of the planned turn; at 0.3 s (sigma points at
#: +-0.52 s, past the branch's peak) the nominal swimmer split the square's corners into 22 + 78 deg.
HORIZON_ONLINE = OnlineMapConfig(prior_bias_std_s=0.15)

@dataclass
class HorizonEpisode(AdaptiveEpisode):
    next_search: int = 0                          # env step of the next search while cruising
    targets: np.ndarray | None = None             # (2, 3) next waypoints, start frame, m
    segment_start: np.ndarray = field(default_factory=lambda: np.zeros(3))
    searches: int = 0
    search_s: float = 0.0
    rel_pending: np.ndarray | None = None  # (k, 3) the waypoints relative to the head (m) read at this step


class HorizonPlanner(AdaptivePlanner):
    """The adaptive planner's loop (cruise reading, hover, burst by L'/L, relax, observe) with turns
    chosen by the two-move search above; ``horizon`` (``HorizonConfig``) sets the search. Same
    constructor as ``AdaptivePlanner`` otherwise; ``for_env`` builds it for an env."""

    def __init__(self, *args, horizon: HorizonConfig | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.horizon = horizon or HorizonConfig()

    @classmethod
    def for_env(cls, env, turn_map: TurnMap, config=None, online=None, carry_over: bool = False,  # type: ignore[override]
                horizon: HorizonConfig | None = None) -> HorizonPlanner:
        """A horizon planner for this env. ``online`` defaults to ``HORIZON_ONLINE``."""
        online = online or HORIZON_ONLINE
        base = AdaptivePlanner.for_env(env, turn_map, config, online, carry_over)
        return cls(turn_map, base.layout, base.control_dt, base.reach_radius_m, base.action_of, config, online,
                   carry_over, base.end_slice, base.reference, horizon=horizon)

    def _new_episode(self) -> HorizonEpisode:
        ep = super()._new_episode()
        return HorizonEpisode(online=ep.online)

    @property
    def search_stats(self) -> dict:
        """Searches made and their CPU time in the first env's episode."""
        ep = self._episodes[0] if self._episodes else None
        return {"searches": ep.searches, "search_s": ep.search_s} if ep is not None else {}

    def _decide(self, ep: HorizonEpisode, obs: np.ndarray) -> float:
        lay = self.layout
        rot = obs[lay.orientation].reshape(3, 3).T
        rel = (obs[lay.waypoints].reshape(-1, 3) * lay.length_scale_m) @ rot.T
        ep.rel_pending = rel
        return super()._decide(ep, obs)

    def _plan_turn(self, head, d, target, node, ep=None):
        if ep.step < ep.next_search:
            return None
        rel = ep.rel_pending
        targets = ep.head + rel
        if ep.targets is not None and float(np.linalg.norm(targets[0] - ep.targets[0])) > 1e-6:
            ep.segment_start = ep.targets[0].copy()  # the target switched: the old one starts the segment
        ep.targets = targets
        after = targets[1] if targets.shape[0] > 1 and float(np.linalg.norm(targets[1] - targets[0])) > 1e-9 else None
        if not ep.cruise_used and self.reference is not None and not ep.turns and len(ep.strains) >= 3:
            seen = summarise_cruise(np.array(ep.strains), np.array(ep.azimuths), self.control_dt)
            ep.online.observe_cruise(seen, self.reference)
            ep.cruise_used = True
        # on course (the rule planner's test): nothing to search
        miss0 = self._line_miss(head[None, :], d[None, :], target)[0]
        ahead = float((target - head) @ d) > 0.0
        planar = bool(abs(ep.segment_start[2]) < 1e-6 and abs(target[2]) < 1e-6
                      and (after is None or abs(after[2]) < 1e-6))
        if ahead and miss0 < self.config.hit_fraction * self.reach_radius_m and not (planar and abs(d[2]) > 0.05):
            return None
        import time
        t0 = time.process_time()
        hz = self.horizon
        errors = [t["azimuth_error_deg"] for t in ep.turns
                  if "azimuth_error_deg" in t and t.get("observed_theta_deg", 0.0) >= hz.psi_min_theta_deg]
        model = TurnModel.from_online(ep.online, hz.map_time_step_s, hz.min_turn_deg, hz.psi_prior_std_deg,
                                      self.control_dt, hz.time_floor_s, errors, hz.psi_prior_weight)
        sit = Situation(head=head, heading=d, target=target, after=after, segment_start=ep.segment_start,
                        reach_m=self.reach_radius_m, planar=planar)
        choice = search(sit, model, self.horizon)
        ep.searches += 1
        ep.search_s += time.process_time() - t0
        if not choice.burst or choice.cruise_m > 0.0:
            ep.next_search = ep.step + max(1, round(self.horizon.replan_s / self.control_dt))
            return None
        t_fly = max(self.control_dt, choice.map_t - ep.online.shift_s)
        plan = {"t_c": float(t_fly), "theta_deg": math.degrees(choice.theta), "burst_phase": wrap_angle(choice.phase),
                "predicted_azimuth": choice.azimuth, "predicted_cost_m": choice.cost,
                "straight_cost_m": choice.straight_cost, "second_move": choice.second, **choice.details,
                "heading": d.tolist(), "head": head.tolist(),
                "shift_s": ep.online.shift_s, "shift_std_s": ep.online.shift_std_s, "bias_s": ep.online.bias_s,
                "psi_offset_deg": math.degrees(ep.online.psi_offset_rad)}
        plan.update(ep.online.burst_plan(t_fly))
        ep.next_search = 0
        return plan
