"""Waypoint paths for the steering task: the path model, JSON files, the paper's square, random paths.

Every path lives in the *start frame* of an episode: origin at the head centre when the
episode starts, +x the initial swimming direction (the head's body axis X_b), +z the head's
Z_b at that instant and y = z x x. Units are metres. The swimmer starts at the origin, so the
first segment runs from the origin to the first waypoint.

Path file (JSON)::

    {"name": "zigzag", "waypoints": [[0.04, 0.0, 0.0], [0.08, 0.03, 0.0]], "reach_radius_m": 0.015}

``name`` and ``reach_radius_m`` are optional; ``waypoints`` holds at least one ``[x, y, z]``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from physics.linalg.vec3 import dot3s, rownorm3
from physics.validation import require_finite

#: Side of the paper's square path, m.
PAPER_SQUARE_SIDE_M = 0.25
#: Largest |coordinate| of a waypoint, m: the swimmer makes ~0.3 mm per motor turn, so 100 m is already days of
#: simulated swimming (a longer path is a typo, and 1e308 overflowed the path's length).
MAX_COORDINATE_M = 100.0
#: Segments shorter than this count as zero-length, m.
MIN_SEGMENT_M = 1e-6

_FILE_KEYS = ("name", "waypoints", "reach_radius_m")


@dataclass(frozen=True)
class WaypointPath:
    """A polyline of waypoints to visit in order, starting from the origin of the start frame.

    waypoints: (k, 3) float64, metres, start frame (read-only). reach_radius_m: the radius
    the path asks for (None: the environment's default).
    """

    name: str
    waypoints: np.ndarray
    reach_radius_m: float | None = None

    def __post_init__(self) -> None:
        pts, vertices, lengths = _validated_waypoints(self.waypoints, source=f"path {self.name!r}")
        for name, value in (("waypoints", pts), ("_vertices", vertices), ("_segment_lengths", lengths)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_length_m", float(lengths.sum()))
        if self.reach_radius_m is not None:
            r = require_finite(f"path {self.name!r}: reach_radius_m", self.reach_radius_m, 0.0, lo_open=True, unit="m")
            object.__setattr__(self, "reach_radius_m", r)

    # The summaries below are computed once per path, by the validation (a frozen path never changes; read-only
    # arrays).
    @property
    def n_waypoints(self) -> int:
        return self.waypoints.shape[0]

    @property
    def vertices(self) -> np.ndarray:
        """The origin followed by the waypoints, (k + 1, 3), m (read-only)."""
        return self._vertices

    @property
    def segment_lengths(self) -> np.ndarray:
        """Length of each segment (origin -> w0, w0 -> w1, ...), (k,), m (read-only)."""
        return self._segment_lengths

    @property
    def length_m(self) -> float:
        """Total length of the polyline from the origin, m."""
        return self._length_m

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (see the module docstring)."""
        d: dict[str, Any] = {"name": self.name, "waypoints": self.waypoints.tolist()}
        if self.reach_radius_m is not None:
            d["reach_radius_m"] = self.reach_radius_m
        return d

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, WaypointPath):
            return NotImplemented
        return (self.name == other.name and self.reach_radius_m == other.reach_radius_m
                and np.array_equal(self.waypoints, other.waypoints))

    def __hash__(self) -> int:
        return hash((self.name, self.reach_radius_m, self.waypoints.tobytes()))


@dataclass(frozen=True)
class RandomPathConfig:
    """Settings of the seeded random-path generator.

    Each segment has a length drawn uniformly from ``segment_length_m`` (m) and turns from the
    previous heading (+x for the first segment) by an angle drawn uniformly from
    [-max_turn_deg, max_turn_deg] (with ``min_turn_deg`` > 0: its size from [min_turn_deg,
    max_turn_deg] and its sign at random): about +z when ``planar`` (the path stays in the x-y plane),
    otherwise about a uniformly drawn axis perpendicular to the heading. ``n_waypoints`` is a number or
    a range (lo, hi), the number then drawn uniformly from lo..hi before the segments;
    ``reach_radius_m`` (m) is None (the environment's radius) or a range (lo, hi) drawn uniformly after
    them. A config without ranges draws exactly what it drew before they existed.
    """

    n_waypoints: int | tuple[int, int] = 3
    segment_length_m: tuple[float, float] = (0.03, 0.08)
    max_turn_deg: float = 90.0
    planar: bool = True
    min_turn_deg: float = 0.0
    reach_radius_m: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        n = self.n_waypoints
        if isinstance(n, (list, tuple)):
            ok = (len(n) == 2 and all(not isinstance(k, bool) and isinstance(k, (int, np.integer)) for k in n)
                  and 1 <= n[0] <= n[1] <= 1000)
            if not ok:
                raise ValueError(f"random_path.n_waypoints={n!r} must be an integer or a range (lo, hi) of integers "
                                 f"with 1 <= lo <= hi <= 1000")
            object.__setattr__(self, "n_waypoints", (int(n[0]), int(n[1])))
        elif isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 1000:
            raise ValueError(f"random_path.n_waypoints={n!r} must be an integer from 1 to 1000 or a range (lo, hi)")
        else:
            object.__setattr__(self, "n_waypoints", int(n))
        lo, hi = _pair(self.segment_length_m, "random_path.segment_length_m")
        if not 0.0 < lo <= hi:
            raise ValueError(f"random_path.segment_length_m={self.segment_length_m!r} must be (lo, hi) metres "
                             f"with 0 < lo <= hi")
        object.__setattr__(self, "segment_length_m", (lo, hi))
        turn = require_finite("random_path.max_turn_deg", self.max_turn_deg, 0.0, 180.0, unit="degrees")
        low = require_finite("random_path.min_turn_deg", self.min_turn_deg, 0.0, turn,
                             unit=f"degrees (max_turn_deg={turn!r})")
        object.__setattr__(self, "min_turn_deg", low)
        object.__setattr__(self, "max_turn_deg", turn)
        if not isinstance(self.planar, (bool, np.bool_)):
            raise ValueError(f"random_path.planar={self.planar!r} must be True or False")
        object.__setattr__(self, "planar", bool(self.planar))
        if self.reach_radius_m is not None:
            r_lo, r_hi = _pair(self.reach_radius_m, "random_path.reach_radius_m")
            if not 0.0 < r_lo <= r_hi:
                raise ValueError(f"random_path.reach_radius_m={self.reach_radius_m!r} must be None or (lo, hi) "
                                 f"metres with 0 < lo <= hi")
            object.__setattr__(self, "reach_radius_m", (r_lo, r_hi))


def square_path(side_m: float = PAPER_SQUARE_SIDE_M) -> WaypointPath:
    """The paper's square: ahead along +x, then three left turns back to the start (x-y plane)."""
    s = require_finite("side_m", side_m, 0.0, lo_open=True, unit="m")
    pts = np.array([[s, 0.0, 0.0], [s, s, 0.0], [0.0, s, 0.0], [0.0, 0.0, 0.0]])
    return WaypointPath(name="square", waypoints=pts)


def random_path(rng: np.random.Generator, config: RandomPathConfig | None = None) -> WaypointPath:
    """A random polyline drawn from ``rng`` only (same generator state -> same path)."""
    cfg = config or RandomPathConfig()
    lo, hi = cfg.segment_length_m
    max_turn = math.radians(cfg.max_turn_deg)
    min_turn = math.radians(cfg.min_turn_deg)
    n = cfg.n_waypoints
    if isinstance(n, tuple):
        n = int(rng.integers(n[0], n[1] + 1))
    signed = cfg.min_turn_deg > 0.0
    # each segment's numbers in the order drawn: its length, the turn (and its sign), the axis' angle; all drawn at
    # once (rng.uniform(a, b) is a + (b - a) x rng.random(), one double each)
    per = 2 + signed + (not cfg.planar)
    pts = _random_points(rng.random(n * per), n, per, lo, hi, min_turn, max_turn, signed, cfg.planar)
    reach = None if cfg.reach_radius_m is None else float(rng.uniform(*cfg.reach_radius_m))
    return WaypointPath(name="random", waypoints=pts, reach_radius_m=reach)


def path_from_waypoints(waypoints: Sequence[Sequence[float]] | np.ndarray, name: str = "custom",
                        reach_radius_m: float | None = None) -> WaypointPath:
    """A path from a list of ``[x, y, z]`` waypoints (m, start frame), validated."""
    return WaypointPath(name=name, waypoints=waypoints, reach_radius_m=reach_radius_m)


def path_from_dict(data: Any, source: str = "path", default_name: str = "path") -> WaypointPath:
    """A path from the JSON form ``{"name", "waypoints", "reach_radius_m"}``; errors name ``source``."""
    if not isinstance(data, dict):
        raise ValueError(f"{source}: expected a JSON object with keys {list(_FILE_KEYS)}, got {type(data).__name__}")
    unknown = sorted(set(data) - set(_FILE_KEYS))
    if unknown:
        raise ValueError(f"{source}: unknown key(s) {unknown}; allowed keys: {list(_FILE_KEYS)}")
    if "waypoints" not in data:
        raise ValueError(f"{source}: missing 'waypoints' (a list of [x, y, z] in metres)")
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise ValueError(f"{source}: 'name' must be a non-empty string, got {name!r}")
    pts, _, _ = _validated_waypoints(data["waypoints"], source=source)
    radius = data.get("reach_radius_m")
    if radius is not None:
        radius = require_finite(f"{source}: reach_radius_m", radius, 0.0, lo_open=True, unit="m")
    return WaypointPath(name=name, waypoints=pts, reach_radius_m=radius)


def load_path(file: str | os.PathLike) -> WaypointPath:
    """Read and validate a path file (JSON, see the module docstring)."""
    file = Path(file)
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileNotFoundError(f"path file {str(file)!r} does not exist") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{file}: not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from None
    return path_from_dict(data, source=str(file), default_name=file.stem)


def save_path(path: WaypointPath, file: str | os.PathLike) -> None:
    """Write ``path`` as a path file (JSON)."""
    Path(file).write_text(json.dumps(path.to_dict(), indent=2) + "\n", encoding="utf-8")


# --- helpers ------------------------------------------------------------------------------
def _validated_waypoints(raw: Any, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """((k, 3) float64 copy of ``raw``, the vertices (k + 1, 3) m and the segments' lengths (k,) m of the path
    through them: ``WaypointPath.vertices``, ``segment_lengths``); ValueError naming the bad waypoint."""
    if (type(raw) is np.ndarray and raw.dtype == np.float64 and raw.ndim == 2 and raw.shape[0] > 0
            and raw.shape[1] == 3 and _within_reach(raw)):
        pts = raw.copy()  # numbers, finite and within reach: what _checked_points checks, at once
    else:
        if isinstance(raw, np.ndarray):
            items = list(raw) if raw.ndim >= 1 else [raw]
        elif isinstance(raw, (list, tuple)):
            items = list(raw)
        else:
            raise ValueError(f"{source}: waypoints must be a list of [x, y, z] (metres), got {type(raw).__name__}")
        if not items:
            raise ValueError(f"{source}: waypoints is empty; give at least one [x, y, z] (metres)")
        pts = _checked_points(items, source)
    vertices = np.empty((pts.shape[0] + 1, 3))
    vertices[0], vertices[1:] = 0.0, pts
    lengths = _segment_lengths(vertices)
    if lengths.min() < MIN_SEGMENT_M:
        i = int(np.flatnonzero(lengths < MIN_SEGMENT_M)[0])
        start = "the start (origin)" if i == 0 else f"waypoint {i - 1}"
        raise ValueError(f"{source}: zero-length segment from {start} to waypoint {i} "
                         f"({pts[i].tolist()}); consecutive points must differ by at least {MIN_SEGMENT_M} m")
    return pts, vertices, lengths


@njit(cache=True)
def _within_reach(pts: np.ndarray) -> bool:
    """Whether every coordinate of ``pts`` (k, 3) is finite and within +-``MAX_COORDINATE_M`` m."""
    for v in pts.ravel():
        if not abs(v) <= MAX_COORDINATE_M:
            return False
    return True


@njit(cache=True)
def _segment_lengths(vertices: np.ndarray) -> np.ndarray:
    """|vertices[i + 1] - vertices[i]|, (k,) m, rounded as ``np.linalg.norm(np.diff(vertices, axis=0), axis=1)``."""
    out = np.empty(vertices.shape[0] - 1)
    for i in range(out.shape[0]):
        out[i] = rownorm3(vertices[i + 1, 0] - vertices[i, 0], vertices[i + 1, 1] - vertices[i, 1],
                          vertices[i + 1, 2] - vertices[i, 2])
    return out


def _checked_points(items: list, source: str) -> np.ndarray:
    """(k, 3) float64 of the waypoints ``items``; ValueError naming the first that is not three finite numbers
    within reach."""
    pts = np.empty((len(items), 3))
    for i, w in enumerate(items):
        if isinstance(w, (str, bytes)) or not hasattr(w, "__len__") or len(w) != 3:
            raise ValueError(f"{source}: waypoint {i} = {_short(w)} must be [x, y, z] (three numbers, metres)")
        for k, c in enumerate(w):
            if isinstance(c, (bool, np.bool_)) or not isinstance(c, (int, float, np.integer, np.floating)):
                raise ValueError(f"{source}: waypoint {i} = {_short(w)} has a non-numeric coordinate {c!r}")
            if not math.isfinite(float(c)):
                raise ValueError(f"{source}: waypoint {i} = {_short(w)} has a non-finite coordinate {c!r}")
            if abs(float(c)) > MAX_COORDINATE_M:
                raise ValueError(f"{source}: waypoint {i} = {_short(w)} has a coordinate {c!r} m out of reach; "
                                 f"allowed: coordinates within +-{MAX_COORDINATE_M:g} m of the start")
            pts[i, k] = float(c)
    return pts


def _pair(value: Any, name: str) -> tuple[float, float]:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise ValueError(f"{name}={value!r} must be a pair (lo, hi)")
    return require_finite(name, value[0]), require_finite(name, value[1])


def _short(w: Any) -> str:
    s = repr(w.tolist() if isinstance(w, np.ndarray) else w)
    return s if len(s) <= 60 else s[:57] + "..."


@njit(cache=True)
def _random_points(u: np.ndarray, n: int, per: int, lo: float, hi: float, min_turn: float, max_turn: float,
                   signed: bool, planar: bool) -> np.ndarray:
    """``random_path``'s waypoints, (n, 3) m, from its ``per`` doubles per segment ``u`` (n per,) in [0, 1) in the
    order drawn (length in [lo, hi] m, turn in [min_turn, max_turn] rad with its sign if ``signed``, else in
    [-max_turn, max_turn], the axis' angle unless ``planar``)."""
    pts = np.empty((n, 3))
    h0, h1, h2 = 1.0, 0.0, 0.0  # the heading
    p0, p1, p2 = 0.0, 0.0, 0.0  # the point
    for i in range(n):
        k = i * per
        length = _uniform(lo, hi, u[k])
        if signed:  # |angle| in [min, max], either sign
            angle = _uniform(min_turn, max_turn, u[k + 1]) * (1.0 if u[k + 2] < 0.5 else -1.0)
        else:
            angle = _uniform(-max_turn, max_turn, u[k + 1])
        # about +z, or about an axis perpendicular to the heading at a uniformly drawn angle
        phi = 0.0 if planar else _uniform(0.0, 2.0 * math.pi, u[k + per - 1])
        h0, h1, h2 = _turned_heading(h0, h1, h2, planar, phi, angle)
        p0, p1, p2 = p0 + length * h0, p1 + length * h1, p2 + length * h2
        pts[i, 0], pts[i, 1], pts[i, 2] = p0, p1, p2
    return pts


@njit(cache=True)
def _uniform(low: float, high: float, u: float) -> float:
    """``Generator.uniform(low, high)`` from its double ``u`` in [0, 1) (``Generator.random()``): low + (high - low) u,
    as NumPy computes it."""
    return low + (high - low) * u


@njit(cache=True)
def _turned_heading(h0: float, h1: float, h2: float, planar: bool, phi: float, angle: float
                    ) -> tuple[float, float, float]:
    """The unit heading h turned by ``angle`` (rad, Rodrigues) about +z if ``planar``, else about the unit vector
    perpendicular to h at angle ``phi`` (rad) from e1 = h x helper / |h x helper| towards h x e1 (helper +z, or +y
    with h near +-z); rounded as the NumPy expressions (``physics.linalg.vec3``)."""
    if planar:
        x0, x1, x2 = 0.0, 0.0, 1.0
    else:
        g0, g1, g2 = (0.0, 0.0, 1.0) if abs(h2) < 0.9 else (0.0, 1.0, 0.0)
        a0, a1, a2 = h1 * g2 - h2 * g1, h2 * g0 - h0 * g2, h0 * g1 - h1 * g0  # h x helper
        n = math.sqrt(dot3s(a0, a1, a2, a0, a1, a2))
        a0, a1, a2 = a0 / n, a1 / n, a2 / n
        b0, b1, b2 = h1 * a2 - h2 * a1, h2 * a0 - h0 * a2, h0 * a1 - h1 * a0  # h x e1
        cp, sp = math.cos(phi), math.sin(phi)
        x0, x1, x2 = cp * a0 + sp * b0, cp * a1 + sp * b1, cp * a2 + sp * b2
    c, s = math.cos(angle), math.sin(angle)
    k0, k1, k2 = x1 * h2 - x2 * h1, x2 * h0 - x0 * h2, x0 * h1 - x1 * h0  # axis x h
    p = dot3s(x0, x1, x2, h0, h1, h2)
    r0 = h0 * c + k0 * s + x0 * p * (1.0 - c)
    r1 = h1 * c + k1 * s + x1 * p * (1.0 - c)
    r2 = h2 * c + k2 * s + x2 * p * (1.0 - c)
    n = math.sqrt(dot3s(r0, r1, r2, r0, r1, r2))
    return r0 / n, r1 / n, r2 / n


__all__ = ["PAPER_SQUARE_SIDE_M", "RandomPathConfig", "WaypointPath", "load_path", "path_from_dict",
           "path_from_waypoints", "random_path", "save_path", "square_path"]
