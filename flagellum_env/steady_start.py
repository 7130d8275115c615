"""Steady straight swimming at a fixed motor speed, computed once per configuration and cached.

An episode starts from the state a swimmer reaches after ``settle_time_s`` at the low motor
speed, starting from rest. That state depends only on (params, numerics, omega, settle time)
and on the physics code, so it is cached in memory and on disk, keyed by a SHA-256 of all of
them (the physics package's source included, so editing the physics invalidates the cache).
A cached state is bit-identical to a freshly computed one (float64 arrays; scalars through
JSON, which round-trips floats exactly), so results never depend on the cache's state.

Disk cache: ``$FLAGELLUM_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/flagellum_swimmer`` (by
default ``~/.cache/flagellum_swimmer``), subfolder ``steady_start/``; one ``<key>.npz`` file
per configuration, written atomically (parallel environments may share it).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import tempfile
import warnings
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

import physics
from physics.params import NumericsConfig, SwimmerParams
from physics.run import advance
from physics.simulator import Simulator

#: Bump when the meaning of a cached steady state changes.
STEADY_START_VERSION = 1
#: Environment variable that overrides the cache folder.
CACHE_ENV_VAR = "FLAGELLUM_CACHE_DIR"
#: Configurations kept in memory per process.
MEMORY_ENTRIES = 32

_memory: OrderedDict[str, SteadyStart] = OrderedDict()


@dataclass(frozen=True)
class SteadyStart:
    """A steady swimming state and how it was made.

    state: ``Simulator.get_state()`` after ``settle_time_s`` s at ``omega_rad_s`` rad/s from rest.
    speed_m_s: mean head speed over the last motor turn (or the whole settle if shorter), m/s.
    """

    params: SwimmerParams
    numerics: NumericsConfig
    omega_rad_s: float
    settle_time_s: float
    state: dict[str, Any]
    speed_m_s: float
    key: str

    def new_simulator(self) -> Simulator:
        """A fresh ``Simulator`` in this state (fresh, so its history is the same every time)."""
        sim = Simulator(self.params, self.numerics)
        sim.set_state(_copy_state(self.state))
        sim.set_motor_speed(self.omega_rad_s)
        return sim


def default_cache_dir() -> Path:
    """``$FLAGELLUM_CACHE_DIR``, else ``$XDG_CACHE_HOME/flagellum_swimmer`` (``~/.cache/...``)."""
    env = os.environ.get(CACHE_ENV_VAR)
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "flagellum_swimmer"


@lru_cache(maxsize=1)
def physics_fingerprint() -> str:
    """SHA-256 of the physics package's Python sources (names and contents)."""
    root = Path(physics.__file__).resolve().parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def cache_key(params: SwimmerParams, numerics: NumericsConfig, omega_rad_s: float, settle_time_s: float) -> str:
    """Hex key of one configuration (params, numerics, omega rad/s, settle time s, physics code)."""
    payload = {"version": STEADY_START_VERSION, "physics": physics_fingerprint(),
               "params": dataclasses.asdict(params), "numerics": dataclasses.asdict(numerics),
               "omega_rad_s": repr(float(omega_rad_s)), "settle_time_s": repr(float(settle_time_s))}
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:40]


def compute_steady_start(params: SwimmerParams, numerics: NumericsConfig, omega_rad_s: float,
                         settle_time_s: float) -> SteadyStart:
    """Swim from rest for ``settle_time_s`` s at ``omega_rad_s`` rad/s (no cache)."""
    _check_args(omega_rad_s, settle_time_s)
    sim = Simulator(params, numerics)
    sim.set_motor_speed(omega_rad_s)
    n_steps = max(1, round(settle_time_s / numerics.dt))
    turn_steps = min(n_steps, max(1, round(2.0 * math.pi / abs(omega_rad_s) / numerics.dt)))
    x_mark = sim.head_position
    mark_after = n_steps - turn_steps  # steps after which the last turn starts

    def mark(sim: Simulator, k: int) -> None:
        nonlocal x_mark
        if k == mark_after:
            x_mark = sim.head_position

    advance(sim, steps=n_steps, on_step=mark)
    speed = float(np.linalg.norm(sim.head_position - x_mark) / (turn_steps * numerics.dt))
    return SteadyStart(params=params, numerics=numerics, omega_rad_s=float(omega_rad_s),
                       settle_time_s=float(settle_time_s), state=sim.get_state(), speed_m_s=speed,
                       key=cache_key(params, numerics, omega_rad_s, settle_time_s))


def get_steady_start(params: SwimmerParams, numerics: NumericsConfig, omega_rad_s: float, settle_time_s: float,
                     cache_dir: str | os.PathLike | None = None, disk: bool = True) -> SteadyStart:
    """The steady start of this configuration: from memory, else disk, else computed and stored.

    cache_dir: folder of the disk cache (None: ``default_cache_dir()``); disk=False keeps it in
    memory only (e.g. for randomised parameters, which rarely repeat).
    """
    _check_args(omega_rad_s, settle_time_s)
    key = cache_key(params, numerics, omega_rad_s, settle_time_s)
    hit = _memory.get(key)
    if hit is not None:
        _memory.move_to_end(key)
        return hit
    folder = (Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()) / "steady_start"
    result = _load(folder / f"{key}.npz", params, numerics, omega_rad_s, settle_time_s, key) if disk else None
    if result is None:
        result = compute_steady_start(params, numerics, omega_rad_s, settle_time_s)
        if disk:
            _save(folder, result)
    _memory[key] = result
    while len(_memory) > MEMORY_ENTRIES:
        _memory.popitem(last=False)
    return result


def clear_memory_cache() -> None:
    """Forget the steady starts held in this process (the disk cache stays)."""
    _memory.clear()


# --- disk format ---------------------------------------------------------------------------
def _save(folder: Path, s: SteadyStart) -> None:
    arrays = {f"state__{k}": v for k, v in s.state.items() if isinstance(v, np.ndarray)}
    scalars = {k: [type(v).__name__, v] for k, v in s.state.items() if not isinstance(v, np.ndarray)}
    meta = {"key": s.key, "version": STEADY_START_VERSION, "speed_m_s": s.speed_m_s, "scalars": scalars,
            "omega_rad_s": s.omega_rad_s, "settle_time_s": s.settle_time_s,
            "params": dataclasses.asdict(s.params), "numerics": dataclasses.asdict(s.numerics)}
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, suffix=".tmp", delete=False) as f:
            np.savez(f, meta=np.array(json.dumps(meta)), **arrays)
            tmp = f.name
        os.replace(tmp, folder / f"{s.key}.npz")
    except OSError as exc:
        warnings.warn(f"could not write the steady-start cache in {folder}: {exc}", RuntimeWarning, stacklevel=3)


def _load(file: Path, params: SwimmerParams, numerics: NumericsConfig, omega_rad_s: float,
          settle_time_s: float, key: str) -> SteadyStart | None:
    if not file.is_file():
        return None
    try:
        with np.load(file, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            state: dict[str, Any] = {k[len("state__"):]: np.array(data[k]) for k in data.files
                                     if k.startswith("state__")}
        if meta.get("key") != key:
            return None
        for name, (tname, value) in meta["scalars"].items():
            state[name] = {"int": int, "float": float, "bool": bool}[tname](value)
        return SteadyStart(params=params, numerics=numerics, omega_rad_s=float(omega_rad_s),
                           settle_time_s=float(settle_time_s), state=state, speed_m_s=float(meta["speed_m_s"]),
                           key=key)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        warnings.warn(f"ignoring unreadable steady-start cache file {file}: {exc}", RuntimeWarning, stacklevel=3)
        return None


def _copy_state(state: dict[str, Any]) -> dict[str, Any]:
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in state.items()}


def _check_args(omega_rad_s: float, settle_time_s: float) -> None:
    if not (math.isfinite(omega_rad_s) and omega_rad_s != 0.0):
        raise ValueError(f"omega_rad_s={omega_rad_s!r} must be a finite, non-zero motor speed (rad/s)")
    if not (math.isfinite(settle_time_s) and settle_time_s > 0.0):
        raise ValueError(f"settle_time_s={settle_time_s!r} must be > 0 (seconds)")
