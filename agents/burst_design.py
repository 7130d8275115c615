"""The burst action design of ``FlagellumBurst-*``: one decision = one turn primitive, for agents with no planner.

Why not ``FlagellumSteer-v0``'s action (the motor speed, held for ``control_dt`` = 2 s)? A turn is a burst at
omega_h of length t_c, and the turn angle rises steeply with t_c (the default's map: 6 deg at 2 s, 85 deg at
3.5 s, 138 deg at 3.75 s, then the chaotic post-buckling branch), so a 2 s hold reaches a handful of turns and a
random policy spends its time in deep post-buckling; the direction of a turn is set by the flagellum's phase at
the burst's start (Huang & Jawed 2020, Fig. 5e), which a 2 s step cannot time. ``scripts/action_resolution.py``
measures the turns each design reaches per decision (docs/rl.md). Here one action sets the primitive the
planners fly:

    a = (a_0, a_1, a_2, a_3) in [-1, 1]^4 (clipped)
    t_c    = max(a_0, 0) x t_c_max, rounded to control steps        burst length at omega_h, s (0: no burst)
    beta   = atan2(a_2, a_1)                                         the phase node's azimuth at the burst's start
    cruise = cruise_min + (a_3 + 1) / 2 x (cruise_max - cruise_min)  swim straight at omega_l afterwards, s

and the env flies it: hover at omega_l until the phase node's azimuth about the heading reaches beta, burst for
t_c, relax at omega_l (at least two wobble periods), then cruise; a cruise ends early at a waypoint, so that the
agent decides again when its target changes. How the burst ends is the design's ``BurstLimits.burst_end``: "time"
(the default) flies t_c seconds; "ratio" flies until the flagellum's L'/L reaches the map swimmer's L'/L after t_c
(``agents.burst_flight``), so that t_c names a turn of the map rather than a time: across swimmers within +-10 %
(E, mu, b; the helix +-4 %) a timed burst of 2.8-3.4 s turns 27-33 deg rms off the map's turn, one ended by L'/L
4-21 deg (``scripts/measure_ratio_clock.py``, docs/ratio_clock.json).

``t_c_max`` (3.7 s) ends one control step before the map's largest turn (3.75 s, 138 deg): past it the turn
scatters (post-buckling), where the surrogate, which interpolates the map, and the rod disagree by 19-39 deg rms per
decision against ~1 deg on the rising branch (``scripts/compare_burst_twins.py``, docs/rl.md), and a policy trained
on the surrogate with 4.5 s learned to lean on the surrogate's smooth 84 deg at 4.5 s. A swimmer that buckles later
makes its largest turns in two bursts. The azimuth is given as a direction (a_1, a_2), not as one number: a turn's
direction lies ~130 deg from beta on the rising branch (the map's psi), and an angle in one action entry would put a
seam where a Gaussian policy cannot cross it.

The observation (``burst_observation``, ``N_BURST_FEATURES`` values) is the task in the heading's frame
(d, e1, e2) = (heading, ``perpendicular_basis(heading)``), the frame beta is measured in: the next two waypoints
(each as a vector, its distance, its unit direction, its angle off the heading and its azimuth about the heading
as (cos, sin): the turn a policy must make, spelled so that the burst's length is a function of one entry and
its phase direction a fixed rotation of two) and the current segment's line relative to the head, the time left,
and what the last ``HISTORY_BURSTS`` bursts did (``BurstHistory``), from which an agent can tell a swimmer that
turns more or less, or elsewhere, than the nominal one: one burst on the steep rising branch is a noisy reading of
a swimmer's timing. (A PPO policy that saw only the last burst reached every waypoint of 4 of 12 held-out paths at
+-10 % in the surrogate, a SAC policy that saw four 9 of 12: two algorithms, so this does not isolate what the
history adds.) The layout, index: what (units):

    0-9     target 1: vector (3, / 0.1 m), distance (/ 0.1 m), unit direction (3), angle off the heading / pi,
            azimuth about the heading (cos, sin)
    10-19   target 2, as target 1
    20-22   the current segment's unit direction;   23-25 the head's offset from its line (/ 0.1 m)
    26      time left (fraction of the budget)
    27-42   the last 4 bursts, newest first, 4 values each (all zeros: no such burst):
              t_c / t_c_max;  the turn seen / pi (the angle between the headings at that decision and the next);
              w cos(delta), w sin(delta): the turn's direction relative to the command, delta = the azimuth of the
              next decision's heading about the decision's heading (``turn_geometry.azimuth``, the
              ``perpendicular_basis`` beta is measured in) minus the command's beta, weighted by
              w = min(1, turn / 10 deg) (``DIRECTION_FULL_TURN_RAD``) because the direction of a turn of ~0 deg is
              noise. On the map's rising branch delta is near the map's psi (~130 deg); a swimmer that turns
              elsewhere shows it here, which the turn's size alone cannot tell.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.turn_geometry import angle_between, azimuth, perpendicular_basis
from physics.validation import require_finite

#: The keyword arguments of every ``FlagellumBurst`` env.
BURST_ENV_ARGUMENTS = ("preset", "turn_map", "env_kwargs", "paths", "random_path", "limits", "render_mode")
#: ``FlagellumBurst-surrogate-v0`` takes these too (the rod twin refuses them): ``map_noise``, the randomised map.
SURROGATE_BURST_ENV_ARGUMENTS = BURST_ENV_ARGUMENTS + ("map_noise",)
#: The keys of ``map_noise``: the largest direction bias (deg, in [0, 180]) and the turn-size spread (in [0, 1)).
MAP_NOISE_KEYS = ("direction_deg", "turn_scale")
#: Length scale of the observation, m (the paths' segments are 5-40 cm).
OBS_SCALE_M = 0.1
#: Action size: burst length, the burst phase's direction (2), cruise time.
N_BURST_ACTIONS = 4
#: How many of the last bursts the observation recalls.
HISTORY_BURSTS = 4
#: Values per burst in the history: length, turn seen, the turn's direction relative to beta (cos, sin).
HISTORY_FEATURES = 4
#: A turn's direction counts in full from this turn on (rad); below it its (cos, sin) shrink linearly to 0.
DIRECTION_FULL_TURN_RAD = math.radians(10.0)
#: Observation size: 2 targets x (vector (3), distance, unit direction (3), angle off the heading, azimuth (cos,
#: sin)), segment direction (3), offset from its line (3), time left, the last bursts (length, turn seen, turn
#: direction (cos, sin)) x 4: 27 + 16 = 43 (the module docstring's layout).
N_BURST_FEATURES = 27 + HISTORY_FEATURES * HISTORY_BURSTS


#: How a burst may end (``BurstLimits.burst_end``): after t_c of flight time, or when L'/L reaches the map's L'/L at
#: the end of a burst of t_c (the ratio clock, ``agents.burst_flight``).
BURST_ENDS = ("time", "ratio")


@dataclass(frozen=True)
class BurstLimits:
    """What one action can ask for: bursts up to ``t_c_max_s`` (s), cruises of ``cruise_min_s`` to
    ``cruise_max_s`` (s), and how a burst ends (``burst_end``, one of ``BURST_ENDS``): "time" flies t_c seconds,
    "ratio" flies until the flagellum's L'/L reaches what the map's swimmer shows after t_c (the module docstring).
    ValueError naming a value that is not finite, not positive, out of order or not allowed."""

    t_c_max_s: float = 3.7
    cruise_min_s: float = 2.0
    cruise_max_s: float = 60.0
    burst_end: str = "time"

    def __post_init__(self) -> None:
        for name in ("t_c_max_s", "cruise_min_s", "cruise_max_s"):
            require_finite(f"BurstLimits.{name}", getattr(self, name), 0.0)
            if not getattr(self, name) > 0.0:
                raise ValueError(f"BurstLimits.{name}={getattr(self, name)!r} must be > 0 (seconds)")
        if not self.cruise_min_s <= self.cruise_max_s:
            raise ValueError(f"BurstLimits.cruise_min_s={self.cruise_min_s!r} must be <= cruise_max_s="
                             f"{self.cruise_max_s!r}")
        if self.burst_end not in BURST_ENDS:
            raise ValueError(f"BurstLimits.burst_end={self.burst_end!r} is not allowed; allowed: {list(BURST_ENDS)}")


def burst_limits(limits: BurstLimits | Mapping[str, Any] | None) -> BurstLimits:
    """``limits`` as ``BurstLimits`` (None: the defaults); ValueError naming an unknown key or a bad value."""
    if limits is None:
        return BurstLimits()
    if isinstance(limits, BurstLimits):
        return limits
    if not isinstance(limits, Mapping):
        raise ValueError(f"limits={limits!r} must be BurstLimits, a dict of its fields or None")
    known = ("t_c_max_s", "cruise_min_s", "cruise_max_s", "burst_end")
    unknown = sorted(set(limits) - set(known))
    if unknown:
        raise ValueError(f"unknown limits key(s) {unknown}; allowed: {list(known)}")
    return BurstLimits(**{k: (v if k == "burst_end" else float(v)) for k, v in limits.items()})


def parse_map_noise(map_noise: Mapping[str, Any] | None) -> tuple[float, float] | None:
    """``FlagellumBurst-surrogate-v0``'s ``map_noise`` as (D deg, S), None when off (None); ValueError (one line)
    naming the bad value unless it is a dict of ``MAP_NOISE_KEYS`` (both required) with finite 0 <= D <= 180 and
    0 <= S < 1."""
    if map_noise is None:
        return None
    allowed = "a dict {'direction_deg': D, 'turn_scale': S} with finite 0 <= D <= 180 (deg) and 0 <= S < 1, or None"
    if not isinstance(map_noise, Mapping):
        raise ValueError(f"map_noise={map_noise!r} is not allowed; give {allowed}")
    keys = set(map_noise)
    if keys != set(MAP_NOISE_KEYS):
        wrong = sorted(map(str, keys - set(MAP_NOISE_KEYS)))
        missing = sorted(set(MAP_NOISE_KEYS) - keys)
        raise ValueError(f"map_noise={dict(map_noise)!r} has unknown key(s) {wrong} and lacks {missing}; give "
                         f"{allowed}")
    out = []
    for key, hi, closed in (("direction_deg", 180.0, True), ("turn_scale", 1.0, False)):
        value = map_noise[key]
        try:
            x = float(value) if not isinstance(value, bool) else math.nan
        except (TypeError, ValueError):
            x = math.nan
        if not (math.isfinite(x) and 0.0 <= x and (x <= hi if closed else x < hi)):
            raise ValueError(f"map_noise['{key}']={value!r} is not allowed; give {allowed}")
        out.append(x)
    return out[0], out[1]


@dataclass(frozen=True)
class BurstCommand:
    """A decoded action: ``t_c_s`` burst length (s, whole control steps, 0: none; with ``burst_end`` "ratio" the map
    swimmer's burst length whose L'/L ends the burst), ``beta_rad`` the phase node's azimuth to burst at (rad,
    [-pi, pi]), ``cruise_s`` (s, whole control steps, >= one), ``burst_end`` (``BURST_ENDS``)."""

    t_c_s: float
    beta_rad: float
    cruise_s: float
    burst_end: str = "time"


def parse_burst_action(action) -> np.ndarray:
    """An action as (N_BURST_ACTIONS,) float64 (not clipped); ValueError unless it is four finite numbers."""
    try:
        raw = np.asarray(action)
        a = np.empty(0) if np.iscomplexobj(raw) else np.asarray(raw, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        a = np.empty(0)
    if a.size != N_BURST_ACTIONS or not np.all(np.isfinite(a)):
        raise ValueError(f"action={action!r} must be four finite numbers in [-1, 1] (burst length, the burst "
                         "phase's direction (2), cruise time)")
    return a


def decode_burst_action(action, limits: BurstLimits, control_dt: float) -> BurstCommand:
    """The command of an action (module docstring), times rounded to whole ``control_dt`` steps (s)."""
    a = np.clip(parse_burst_action(action), -1.0, 1.0)
    steps = round(max(float(a[0]), 0.0) * limits.t_c_max_s / control_dt)
    cruise = limits.cruise_min_s + 0.5 * (float(a[3]) + 1.0) * (limits.cruise_max_s - limits.cruise_min_s)
    return BurstCommand(steps * control_dt, math.atan2(float(a[2]), float(a[1])),
                        max(1, round(cruise / control_dt)) * control_dt, limits.burst_end)


def turn_seen(before: np.ndarray, after: np.ndarray) -> tuple[float, float]:
    """(turn, azimuth) of a heading change, rad: the angle between the unit headings ``before`` and ``after`` (3,)
    ([0, pi]) and the azimuth of ``after`` about ``before`` (``turn_geometry.azimuth``, in
    ``perpendicular_basis(before)``, the basis beta is measured in; (-pi, pi], 0 for no turn)."""
    return angle_between(before, after), azimuth(after, before)


class BurstHistory:
    """The last ``HISTORY_BURSTS`` bursts of an episode, newest first, each as (t_c / t_c_max, turn seen / pi,
    w cos(azimuth - beta), w sin(azimuth - beta)), w = min(1, turn / ``DIRECTION_FULL_TURN_RAD``) (module
    docstring)."""

    def __init__(self) -> None:
        self.entries: list[tuple[float, float, float, float]] = []

    def record(self, t_c_fraction: float, turn_rad: float, azimuth_rad: float, beta_rad: float) -> None:
        """A burst of ``t_c_fraction`` x t_c_max commanded at phase ``beta_rad`` after which the heading turned
        ``turn_rad`` (rad) by the next decision, towards ``azimuth_rad`` about the decision's heading (rad;
        ``turn_seen`` gives both)."""
        turn = float(turn_rad)
        w = min(1.0, max(turn, 0.0) / DIRECTION_FULL_TURN_RAD)
        delta = float(azimuth_rad) - float(beta_rad)
        entry = (float(t_c_fraction), turn / math.pi, w * math.cos(delta), w * math.sin(delta))
        self.entries = [entry] + self.entries[:HISTORY_BURSTS - 1]

    def features(self) -> np.ndarray:
        """(HISTORY_FEATURES x HISTORY_BURSTS,): the entries, zeros where there were fewer bursts."""
        out = np.zeros(HISTORY_FEATURES * HISTORY_BURSTS)
        for k, entry in enumerate(self.entries):
            out[HISTORY_FEATURES * k:HISTORY_FEATURES * (k + 1)] = entry
        return out


def burst_observation(head: np.ndarray, heading: np.ndarray, targets: np.ndarray, segment: tuple[np.ndarray, np.ndarray],
                      time_left: float, history: BurstHistory) -> np.ndarray:
    """The observation (module docstring), (N_BURST_FEATURES,) float32. ``head`` (3,) m, ``heading`` (3,) unit,
    ``targets`` (2, 3) m (the next two waypoints, the last repeated), ``segment`` the current segment's ends
    ((3,), (3,)) m, ``time_left`` in [0, 1], ``history`` the episode's last bursts."""
    e1, e2 = perpendicular_basis(heading)
    frame = np.stack([heading, e1, e2])
    rel = (targets - head) @ frame.T / OBS_SCALE_M
    dist = np.sqrt((rel * rel).sum(axis=1))
    unit = rel / np.maximum(dist, 1e-12)[:, None]
    off_heading = np.arccos(np.clip(unit[:, 0], -1.0, 1.0)) / math.pi
    across = np.hypot(rel[:, 1], rel[:, 2])
    cos_az = np.where(across > 0.0, rel[:, 1] / np.maximum(across, 1e-12), 1.0)
    sin_az = np.where(across > 0.0, rel[:, 2] / np.maximum(across, 1e-12), 0.0)
    per_target = np.column_stack([rel, dist, unit, off_heading, cos_az, sin_az])
    a, b = segment
    u = b - a
    n = math.sqrt(float(u @ u))
    u = u / n if n > 0.0 else heading
    off = (head - a) - float((head - a) @ u) * u
    out = np.concatenate([per_target.reshape(-1), frame @ u, frame @ off / OBS_SCALE_M,
                          [time_left], history.features()])
    return np.clip(out, -10.0, 10.0).astype(np.float32)
