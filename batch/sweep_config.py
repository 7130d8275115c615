"""Sweep configuration: which parameters vary, over which values, and the points that makes.

The runner is ``batch.sweep.run_sweep``. A sweep file (YAML or TOML) names the parameters
to vary and their values::

    sweep:                      # parameter -> list of values
      omega_rpm: [10, 20]       # motor speed, rpm
      head_radius: [0.0, 0.012] # any SwimmerParams / NumericsConfig field (`flagellum params`)
    mode: grid                  # grid: every combination (default); zip: i-th values together
    duration_s: 0.5             # simulated time of every point, s
    fixed: {n_nodes: 30, dt: 0.02}   # applied to every point (optional)
    preset: fast                # optional; applied first, `fixed` and the point's values on top
    record_interval_s: 0.01     # optional head sampling interval, s
    node_record_interval_s: 0.1 # optional shape snapshot interval, s
    save_trajectories: true     # write points/<id>.npz (default true)

Each point is one ``run_simulation`` at a constant motor speed. A point's id is a hash of
everything that determines its numbers (speed, duration, record intervals and every physical
and numerical parameter), so a resumed sweep skips exactly the points already computed. A resume
with another configuration (values added or changed) is refused (``run_sweep``): choose another
output folder.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

from physics.params import (REMOVED_PARAMETERS, NumericsConfig, SwimmerParams, apply_overrides, parameter_table,
                            removed_message)
from physics.presets import apply_preset, check_preset
from physics.run import DEFAULT_NODE_RECORD_INTERVAL_S, DEFAULT_RECORD_INTERVAL_S, validate_run_arguments
from physics.schedule import MAX_RPM, MotorSchedule

Value = Union[int, float, str]
"""A parameter value: a number, or a name for choice parameters (e.g. hydro_model)."""

MODES = ("grid", "zip")
CONFIG_KEYS = ("sweep", "mode", "duration_s", "fixed", "preset", "record_interval_s", "node_record_interval_s",
               "save_trajectories")
REQUIRED_KEYS = ("sweep", "duration_s")
SPEED = "omega_rpm"
_ID_VERSION = 1  # bump when the meaning of a point's settings changes

_FIELDS = {f.name: f for cls in (SwimmerParams, NumericsConfig) for f in dataclasses.fields(cls)}
_ALLOWED = {row["name"]: f"{row['allowed']} {row['unit']}".rstrip(" -") for row in parameter_table()}
_ALLOWED[SPEED] = f">= 0 and <= {MAX_RPM:g} rpm"


class SweepConfigError(ValueError):
    """A bad sweep configuration; the message names the key, the value and what is allowed."""


def parameter_names() -> list[str]:
    """Names a sweep may vary or fix: ``omega_rpm`` and every SwimmerParams/NumericsConfig field."""
    return [SPEED, *_FIELDS]


@dataclass(frozen=True)
class SweepPoint:
    """One run of a sweep: its position, id, the swept values and the resolved settings."""

    index: int
    point_id: str
    values: dict[str, Value]
    omega_rpm: float
    params: SwimmerParams
    numerics: NumericsConfig

    def label(self) -> str:
        """``"omega_rpm=10, head_radius=0"`` for messages and progress bars."""
        return format_values(self.values)


def format_values(values: Mapping[str, Value]) -> str:
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in values.items())


@dataclass(frozen=True)
class SweepConfig:
    """A validated sweep (see the module docstring). Construction raises SweepConfigError.

    ``sweep``: parameter -> values (non-empty, numbers or allowed names); ``mode``: "grid" or
    "zip"; ``duration_s``: simulated time per point, s; ``fixed``: parameter -> value for every
    point; ``preset``: a ``physics.presets`` name or None; ``record_interval_s`` and
    ``node_record_interval_s``: sampling intervals, s; ``save_trajectories``: write npz files.
    ``omega_rpm`` must appear in ``sweep`` or ``fixed``.
    """

    sweep: Mapping[str, Sequence[Value]]
    duration_s: float
    mode: str = "grid"
    fixed: Mapping[str, Value] = field(default_factory=dict)
    preset: str | None = None
    record_interval_s: float = DEFAULT_RECORD_INTERVAL_S
    node_record_interval_s: float = DEFAULT_NODE_RECORD_INTERVAL_S
    save_trajectories: bool = True

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise SweepConfigError(f"mode={self.mode!r} is not allowed; choose one of {list(MODES)}")
        if self.preset is not None:
            try:
                check_preset(self.preset)
            except ValueError as exc:
                raise SweepConfigError(str(exc)) from None
        if not isinstance(self.save_trajectories, bool):
            raise SweepConfigError(f"save_trajectories={self.save_trajectories!r} is not allowed; "
                                   "allowed: true or false")
        for key in ("duration_s", "record_interval_s", "node_record_interval_s"):
            object.__setattr__(self, key, _positive_time(key, getattr(self, key)))
        object.__setattr__(self, "sweep", _check_sweep(self.sweep))
        object.__setattr__(self, "fixed", _check_fixed(self.fixed, self.sweep))
        if SPEED not in self.sweep and SPEED not in self.fixed:
            raise SweepConfigError(f"{SPEED} is missing; give the motor speed (rpm) under 'sweep' or 'fixed'")
        if self.mode == "zip":
            lengths = {k: len(v) for k, v in self.sweep.items()}
            if len(set(lengths.values())) > 1:
                raise SweepConfigError(f"mode='zip' needs lists of equal length under 'sweep', got {lengths}; "
                                       "use mode='grid' for every combination")
        self._check_each_value()
        self.points()  # every point must build; raises naming the point

    # --- construction -----------------------------------------------------------------
    @classmethod
    def from_mapping(cls, data: Any, source: str = "sweep config") -> SweepConfig:
        """Build from the parsed file contents; errors start with ``source`` (the file name)."""
        try:
            if not isinstance(data, Mapping):
                raise SweepConfigError(f"the top level must be a mapping with keys {list(CONFIG_KEYS)}, "
                                       f"got {type(data).__name__}")
            unknown = [str(k) for k in data if k not in CONFIG_KEYS]
            if unknown:
                raise SweepConfigError(f"unknown key {unknown[0]!r}; allowed keys: {', '.join(CONFIG_KEYS)}")
            missing = [k for k in REQUIRED_KEYS if k not in data]
            if missing:
                raise SweepConfigError(f"{missing[0]} is missing; it is required "
                                       f"(required keys: {', '.join(REQUIRED_KEYS)})")
            # an empty optional key (``record_interval_s:`` in YAML) means its default
            return cls(**{k: v for k, v in data.items() if v is not None or k in REQUIRED_KEYS})
        except SweepConfigError as exc:
            raise SweepConfigError(f"{source}: {exc}") from None

    def with_fixed(self, overrides: Mapping[str, Value]) -> SweepConfig:
        """A copy with ``overrides`` added to ``fixed`` (e.g. from ``--set``)."""
        return dataclasses.replace(self, fixed={**self.fixed, **overrides})

    def to_dict(self) -> dict[str, Any]:
        """JSON/YAML-ready form; ``SweepConfig.from_mapping(c.to_dict()) == c``."""
        return {"sweep": {k: list(v) for k, v in self.sweep.items()}, "mode": self.mode,
                "duration_s": self.duration_s, "fixed": dict(self.fixed), "preset": self.preset,
                "record_interval_s": self.record_interval_s,
                "node_record_interval_s": self.node_record_interval_s,
                "save_trajectories": self.save_trajectories}

    # --- expansion --------------------------------------------------------------------
    def combinations(self) -> list[dict[str, Value]]:
        """The swept values of every point, in point order (grid: the last key varies fastest)."""
        names = list(self.sweep)
        columns = [self.sweep[n] for n in names]
        rows: Iterable[tuple[Value, ...]] = itertools.product(*columns) if self.mode == "grid" else zip(*columns)
        return [dict(zip(names, row)) for row in rows]

    def __len__(self) -> int:
        sizes = [len(v) for v in self.sweep.values()]
        return math.prod(sizes) if self.mode == "grid" else sizes[0]

    def points(self) -> list[SweepPoint]:
        """Every point with its resolved parameters and id. SweepConfigError names a bad point."""
        points: list[SweepPoint] = []
        seen: dict[str, int] = {}
        base = self._base()
        for index, values in enumerate(self.combinations()):
            settings = {**self.fixed, **values}
            try:
                params, numerics = _resolve(base, settings)
                omega = float(settings[SPEED])
                validate_run_arguments(numerics, self.duration_s, self.record_interval_s,
                                       self.node_record_interval_s, n_nodes=params.n_nodes)
            except ValueError as exc:
                raise SweepConfigError(f"point {index} ({format_values(values)}): {exc}") from None
            pid = point_id(omega, params, numerics, self.duration_s, self.record_interval_s,
                           self.node_record_interval_s)
            if pid in seen:
                raise SweepConfigError(f"points {seen[pid]} and {index} are the same run "
                                       f"({format_values(values)}); remove the repeated value under 'sweep'")
            seen[pid] = index
            points.append(SweepPoint(index, pid, values, omega, params, numerics))
        return points

    # --- helpers ----------------------------------------------------------------------
    def _base(self) -> tuple[SwimmerParams, NumericsConfig]:
        if self.preset is None:
            return SwimmerParams(), NumericsConfig()
        return apply_preset(self.preset)

    def _check_each_value(self) -> None:
        """Each value alone on top of the preset, so a range error names its key."""
        base = self._base()
        entries = [(f"fixed.{k}", k, v) for k, v in self.fixed.items()]
        entries += [(f"sweep.{k}[{i}]", k, v) for k, vs in self.sweep.items() for i, v in enumerate(vs)]
        for where, name, value in entries:
            try:
                _resolve(base, {name: value})
            except ValueError as exc:
                raise SweepConfigError(f"{where}: {exc}") from None


def point_id(omega_rpm: float, params: SwimmerParams, numerics: NumericsConfig, duration_s: float,
             record_interval_s: float, node_record_interval_s: float) -> str:
    """16 hex digits of a SHA-256 over everything that determines a point's results."""
    payload = {"version": _ID_VERSION, "omega_rpm": float(omega_rpm), "duration_s": float(duration_s),
               "record_interval_s": float(record_interval_s),
               "node_record_interval_s": float(node_record_interval_s),
               "params": dataclasses.asdict(params), "numerics": dataclasses.asdict(numerics)}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def load_sweep_config(path: str | os.PathLike[str]) -> SweepConfig:
    """Read a ``.yaml``/``.yml`` or ``.toml`` sweep file; SweepConfigError names file, key and value."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".yaml", ".yml", ".toml"):
        raise SweepConfigError(f"{path}: unknown file type {suffix or '(none)'!r}; allowed: .yaml, .yml, .toml")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SweepConfigError(f"{path}: cannot read the sweep file ({exc.strerror})") from None
    if suffix == ".toml":
        data = _parse_toml(text, path)
    else:
        import yaml

        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise SweepConfigError(f"{path}: not valid YAML: {' '.join(str(exc).split())}") from None
    return SweepConfig.from_mapping(data, source=str(path))


def _parse_toml(text: str, path: Path) -> Any:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        try:
            import tomli as tomllib
        except ModuleNotFoundError:
            raise SweepConfigError(f"{path}: reading TOML needs Python >= 3.11 or 'pip install tomli'; "
                                   "or write the sweep in YAML") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SweepConfigError(f"{path}: not valid TOML: {exc}") from None


# --- validation helpers ---------------------------------------------------------------
def _positive_time(key: str, value: Any) -> float:
    number = _as_number(key, value, "a finite time > 0 s")
    if number <= 0.0:
        raise SweepConfigError(f"{key}={value!r} is not allowed; allowed: a finite time > 0 s")
    return float(number)


def _as_number(where: str, value: Any, allowed: str) -> int | float:
    """A finite int/float; numeric strings are accepted (YAML reads ``1e-3`` as a string)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise SweepConfigError(f"{where}={value!r} is not a number; allowed: {allowed}")
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise SweepConfigError(f"{where}={value!r} is not a number; allowed: {allowed}") from None
    if not math.isfinite(value):
        raise SweepConfigError(f"{where}={value!r} is not allowed; allowed: {allowed}")
    return value


def _check_name(where: str, name: Any) -> str:
    if name == SPEED or name in _FIELDS:
        return name
    if name in REMOVED_PARAMETERS:
        raise SweepConfigError(f"{where}: {removed_message(name)}")
    raise SweepConfigError(f"{where}: unknown parameter {name!r}; allowed: {', '.join(parameter_names())} "
                           "(see 'flagellum params')")


def _check_value(where: str, name: str, value: Any) -> Value:
    """Type check of one value of parameter ``name`` (ranges are checked by the dataclasses)."""
    fld = _FIELDS.get(name)
    choices = fld.metadata.get("choices") if fld is not None else None
    if choices is not None:
        if value not in choices:
            raise SweepConfigError(f"{where}={value!r} is not allowed; choose one of {list(choices)}")
        return value
    return _as_number(where, value, _ALLOWED[name])


def _check_sweep(sweep: Any) -> dict[str, tuple[Value, ...]]:
    if not isinstance(sweep, Mapping) or not sweep:
        raise SweepConfigError(f"sweep={sweep!r} is not allowed; allowed: a non-empty mapping of parameter "
                               "name -> list of values, e.g. {omega_rpm: [10, 20]}")
    out: dict[str, tuple[Value, ...]] = {}
    for name, values in sweep.items():
        _check_name("sweep", name)
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or len(values) == 0:
            raise SweepConfigError(f"sweep.{name}={values!r} is not allowed; allowed: a non-empty list of values")
        checked = tuple(_check_value(f"sweep.{name}[{i}]", name, v) for i, v in enumerate(values))
        out[name] = checked
    return out


def _check_fixed(fixed: Any, sweep: Mapping[str, Any]) -> dict[str, Value]:
    if not isinstance(fixed, Mapping):
        raise SweepConfigError(f"fixed={fixed!r} is not allowed; allowed: a mapping of parameter name -> value")
    out: dict[str, Value] = {}
    for name, value in fixed.items():
        _check_name("fixed", name)
        if name in sweep:
            raise SweepConfigError(f"fixed.{name}: {name} is also under 'sweep'; give each parameter in one place")
        out[name] = _check_value(f"fixed.{name}", name, value)
    return out


def _as_override(value: Value) -> str:
    """String form for ``apply_overrides`` that round-trips exactly."""
    return repr(float(value)) if isinstance(value, float) else str(value)


def _resolve(base: tuple[SwimmerParams, NumericsConfig],
             settings: Mapping[str, Value]) -> tuple[SwimmerParams, NumericsConfig]:
    """``base`` with ``settings`` applied; ValueError (from the dataclasses) on a bad value."""
    if SPEED in settings:
        MotorSchedule.constant(float(settings[SPEED]))
    overrides = {k: _as_override(v) for k, v in settings.items() if k != SPEED}
    return apply_overrides(base[0], base[1], overrides)

