"""Configuration of ``FlagellumSteer-v0``: every argument, its default and its validation.

``SteerConfig(**kwargs)`` raises ``ValueError`` naming the bad argument and the allowed values;
the environment builds one from the keyword arguments of ``gymnasium.make``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from flagellum_env.paths import RandomPathConfig, WaypointPath, load_path, path_from_waypoints, square_path
from flagellum_env.rewards import RewardConfig
from physics.params import NumericsConfig, SwimmerParams
from physics.presets import DEFAULT_PRESET, apply_preset, check_preset
from physics.validation import is_real, require_finite

PATH_NAMES = ("square", "random")
ACTION_TYPES = ("continuous", "discrete")
OBSERVATION_TYPES = ("flat", "dict")
#: Reach radius when neither the argument nor the path file gives one, m.
DEFAULT_REACH_RADIUS_M = 0.015
#: Longest env step, simulated s (a burst of the turn map lasts at most 600 s; a larger value is a typo that
#: would run for days inside one step).
MAX_CONTROL_DT_S = 600.0
#: Highest motor speed accepted, rpm.
MAX_RPM = 2000.0


@dataclass(frozen=True)
class RandomizationConfig:
    """Per-episode domain randomisation, drawn from the env's ``np_random`` at ``reset``.

    Each physical factor is drawn uniformly from [1 - f, 1 + f] for its fraction f:
    ``youngs_modulus`` scales E and G together (G/E is kept), ``viscosity`` scales mu,
    ``head_radius`` scales b, ``geometry`` scales the helix pitch and the helix radius
    (one draw each). ``obs_noise_std`` is the standard deviation of Gaussian noise added to
    the measured observation entries (waypoints, orientation, velocity, shape, L'/L), in the
    observation's own units; it is drawn afresh every step.
    """

    youngs_modulus: float = 0.1
    viscosity: float = 0.1
    head_radius: float = 0.1
    geometry: float = 0.05
    obs_noise_std: float = 0.01

    def __post_init__(self) -> None:
        for f in fields(self):
            hi = 1.0 if f.name == "obs_noise_std" else 0.5
            object.__setattr__(self, f.name, require_finite(f"randomize.{f.name}", getattr(self, f.name), 0.0, hi))

    @property
    def changes_physics(self) -> bool:
        return any(getattr(self, n) > 0.0 for n in ("youngs_modulus", "viscosity", "head_radius", "geometry"))


def draw_randomization(params: SwimmerParams, r: RandomizationConfig | None, rng: np.random.Generator
                       ) -> tuple[SwimmerParams, float]:
    """One episode's swimmer and observation-noise std under ``r`` (None: ``params`` and 0): E and G scaled by one
    factor, mu, b, the helix pitch and radius by one each, drawn uniformly from [1 - f, 1 + f]. Always five draws
    from ``rng``, in this order, so the stream does not depend on the fractions (``FlagellumSteer-v0`` and the
    turn-level surrogate ``FlagellumTurn-surrogate-v0`` draw the same swimmer from the same seed)."""
    if r is None:
        return params, 0.0
    f_e, f_mu, f_b, f_pitch, f_radius = (float(rng.uniform(1.0 - f, 1.0 + f)) for f in (
        r.youngs_modulus, r.viscosity, r.head_radius, r.geometry, r.geometry))
    if not r.changes_physics:
        return params, r.obs_noise_std
    p = params
    drawn = p.replace(youngs_modulus=p.youngs_modulus * f_e, shear_modulus=p.shear_modulus * f_e,
                      viscosity=p.viscosity * f_mu, head_radius=p.head_radius * f_b,
                      pitch=p.pitch * f_pitch, helix_radius=p.helix_radius * f_radius)
    return drawn, r.obs_noise_std


@dataclass(frozen=True)
class SteerConfig:
    """All arguments of ``FlagellumSteer-v0`` except ``render_mode`` (see the env's docstring)."""

    path: Any = "random"
    random_path: RandomPathConfig | Mapping[str, Any] | None = None
    preset: str = DEFAULT_PRESET
    params: Mapping[str, Any] | None = None
    numerics: Mapping[str, Any] | None = None
    control_dt: float = 2.0
    omega_range_rpm: tuple[float, float] = (10.0, 150.0)
    action_type: str = "continuous"
    discrete_speeds_rpm: tuple[float, ...] = (10.0, 60.0, 150.0)
    observation_type: str = "flat"
    n_lookahead: int = 2
    n_shape_nodes: int = 8
    reach_radius_m: float | None = None
    max_sim_time_s: float | None = None
    time_factor: float = 1.5
    off_path_m: float = 0.1
    randomize: bool | RandomizationConfig | Mapping[str, Any] | None = False
    reward: RewardConfig | Mapping[str, Any] | None = None
    settle_time_s: float | None = None
    buckling_threshold: float = 0.9
    buckling_release: float = 0.95
    cache_dir: str | os.PathLike | None = None
    disk_cache: bool = True
    render_size: tuple[int, int] = (640, 480)
    fixed_path: WaypointPath | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        s = self._set
        s("fixed_path", resolve_path(self.path))
        s("random_path", _sub_config(self.random_path, RandomPathConfig, "random_path"))
        check_preset(self.preset)
        s("params", _overrides(self.params, SwimmerParams, "params"))
        s("numerics", _overrides(self.numerics, NumericsConfig, "numerics"))
        s("control_dt", require_finite("control_dt", self.control_dt, 0.0, MAX_CONTROL_DT_S, lo_open=True, unit="s"))
        lo, hi = _number_pair(self.omega_range_rpm, "omega_range_rpm")
        if not 0.0 < lo < hi <= MAX_RPM:
            raise ValueError(f"omega_range_rpm={self.omega_range_rpm!r} must be (lo, hi) rpm with "
                             f"0 < lo < hi <= {MAX_RPM:g}")
        s("omega_range_rpm", (lo, hi))
        _choice(self.action_type, ACTION_TYPES, "action_type")
        speeds = _number_tuple(self.discrete_speeds_rpm, "discrete_speeds_rpm")
        if len(speeds) < 2 or speeds[0] <= 0.0 or speeds[-1] > MAX_RPM or any(
                b <= a for a, b in itertools.pairwise(speeds)):
            raise ValueError(f"discrete_speeds_rpm={self.discrete_speeds_rpm!r} must hold at least two "
                             f"increasing speeds in (0, {MAX_RPM:g}] rpm")
        s("discrete_speeds_rpm", speeds)
        _choice(self.observation_type, OBSERVATION_TYPES, "observation_type")
        s("n_lookahead", _integer(self.n_lookahead, "n_lookahead", 1, 2))
        s("n_shape_nodes", _integer(self.n_shape_nodes, "n_shape_nodes", 2, 1000))
        if self.reach_radius_m is not None:
            s("reach_radius_m", _positive(self.reach_radius_m, "reach_radius_m", "m"))
        if self.max_sim_time_s is not None:
            s("max_sim_time_s", _positive(self.max_sim_time_s, "max_sim_time_s", "s"))
        s("time_factor", _positive(self.time_factor, "time_factor", ""))
        s("off_path_m", _positive(self.off_path_m, "off_path_m", "m"))
        s("randomize", _randomization(self.randomize))
        s("reward", _sub_config(self.reward, RewardConfig, "reward"))
        if self.settle_time_s is not None:
            s("settle_time_s", _positive(self.settle_time_s, "settle_time_s", "s"))
        th = _positive(self.buckling_threshold, "buckling_threshold", "")
        rel = _positive(self.buckling_release, "buckling_release", "")
        if not th < rel:
            raise ValueError(f"buckling_threshold={th!r} must be below buckling_release={rel!r} (both L'/L)")
        s("buckling_threshold", th)
        s("buckling_release", rel)
        if self.cache_dir is not None and not isinstance(self.cache_dir, (str, os.PathLike)):
            raise ValueError(f"cache_dir={self.cache_dir!r} must be a folder path or None")
        if not isinstance(self.disk_cache, (bool, np.bool_)):
            raise ValueError(f"disk_cache={self.disk_cache!r} must be True or False")
        w, h = _number_pair(self.render_size, "render_size")
        if not (w.is_integer() and h.is_integer() and 64 <= w <= 4096 and 64 <= h <= 4096):
            raise ValueError(f"render_size={self.render_size!r} must be (width, height) pixels, "
                             f"integers from 64 to 4096")
        s("render_size", (int(w), int(h)))

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    # --- derived ---------------------------------------------------------------------------
    @property
    def low_speed_rpm(self) -> float:
        """Motor speed of the steady start (the lowest one the action can ask for), rpm."""
        return self.omega_range_rpm[0] if self.action_type == "continuous" else self.discrete_speeds_rpm[0]

    @property
    def high_speed_rpm(self) -> float:
        """Highest motor speed the action can ask for, rpm."""
        return self.omega_range_rpm[1] if self.action_type == "continuous" else self.discrete_speeds_rpm[-1]

    def physics(self) -> tuple[SwimmerParams, NumericsConfig]:
        """(params, numerics): the preset, then the ``params`` / ``numerics`` overrides."""
        p, n = apply_preset(self.preset)
        try:
            p = p.replace(**(self.params or {}))
        except ValueError as exc:
            raise ValueError(f"params: {exc}") from None
        try:
            n = n.replace(**(self.numerics or {}))
        except ValueError as exc:
            raise ValueError(f"numerics: {exc}") from None
        return p, n

    @classmethod
    def argument_names(cls) -> list[str]:
        return [f.name for f in fields(cls) if f.init]


def make_config(**kwargs: Any) -> SteerConfig:
    """``SteerConfig(**kwargs)`` with a ``ValueError`` listing the known names for an unknown one."""
    known = SteerConfig.argument_names()
    unknown = sorted(set(kwargs) - set(known))
    if unknown:
        raise ValueError(f"unknown argument(s) {unknown} for FlagellumSteer-v0; known arguments: "
                         f"{known + ['render_mode']}")
    return SteerConfig(**kwargs)


def resolve_path(spec: Any) -> WaypointPath | None:
    """The fixed path ``spec`` names, in any form the ``path`` argument takes (None for "random");
    ``ValueError`` naming ``spec`` otherwise."""
    if isinstance(spec, WaypointPath):
        return spec
    if isinstance(spec, str) and spec in PATH_NAMES:
        return square_path() if spec == "square" else None
    if isinstance(spec, (str, os.PathLike)):
        if Path(spec).is_file():
            return load_path(spec)
        raise ValueError(f"path={str(spec)!r} is neither one of {list(PATH_NAMES)} nor an existing path file "
                         f"(JSON); a list of [x, y, z] waypoints (m) is also accepted")
    if isinstance(spec, (Sequence, np.ndarray)):
        try:
            return path_from_waypoints(spec, name="custom")
        except ValueError as exc:
            raise ValueError(f"path: {exc}") from None
    raise ValueError(f"path={spec!r} must be one of {list(PATH_NAMES)}, a path-file name, a list of "
                     f"[x, y, z] waypoints (m) or a WaypointPath")


def _sub_config(value: Any, cls: type, name: str) -> Any:
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, Mapping):
        known = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(value) - set(known))
        if unknown:
            raise ValueError(f"{name}: unknown key(s) {unknown}; allowed keys: {known}")
        return cls(**value)
    raise ValueError(f"{name}={value!r} must be a {cls.__name__}, a dict of its fields or None")


def _randomization(value: Any) -> RandomizationConfig | None:
    if value is None or value is False:
        return None
    if value is True:
        return RandomizationConfig()
    if isinstance(value, (RandomizationConfig, Mapping)):
        return _sub_config(value, RandomizationConfig, "randomize")
    raise ValueError(f"randomize={value!r} must be False, True, a dict of "
                     f"{[f.name for f in fields(RandomizationConfig)]} or a RandomizationConfig")


def _overrides(value: Any, cls: type, name: str) -> dict[str, Any] | None:
    if value is None:
        return None
    if not isinstance(value, Mapping):
        raise ValueError(f"{name}={value!r} must be a dict of {cls.__name__} fields or None")
    known = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(value) - set(known))
    if unknown:
        raise ValueError(f"{name}: unknown field(s) {unknown}; allowed: {known}")
    return dict(value)


def _positive(value: Any, name: str, unit: str) -> float:
    return require_finite(name, value, 0.0, lo_open=True, unit=unit)


def _integer(value: Any, name: str, lo: int, hi: int) -> int:
    if not is_real(value) or not float(value).is_integer() or not lo <= value <= hi:
        raise ValueError(f"{name}={value!r} must be an integer from {lo} to {hi}")
    return int(value)


def _choice(value: Any, allowed: tuple[str, ...], name: str) -> None:
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not allowed; choose one of {list(allowed)}")


def _number_tuple(value: Any, name: str) -> tuple[float, ...]:
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ValueError(f"{name}={value!r} must be a sequence of numbers")
    out = []
    for v in value:
        if not is_real(v) or not math.isfinite(v):
            raise ValueError(f"{name}={value!r} must hold finite numbers only")
        out.append(float(v))
    return tuple(out)


def _number_pair(value: Any, name: str) -> tuple[float, float]:
    t = _number_tuple(value, name)
    if len(t) != 2:
        raise ValueError(f"{name}={value!r} must be a pair of numbers")
    return t[0], t[1]
