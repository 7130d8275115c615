"""Shared fixtures of the environment tests: a session-wide steady-start cache and small envs.

The small configuration (fast preset, 0.2 s steps, a 6 mm path, 10-40 rpm so the flagellum
never buckles, a 6 s settle) keeps every episode to a fraction of a second of wall time.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from flagellum_env.steer_env import FlagellumSteerEnv

SMALL: dict[str, Any] = {
    "path": [[0.003, 0.0, 0.0], [0.006, 0.001, 0.0]],
    "preset": "fast",
    "control_dt": 0.2,
    "omega_range_rpm": (10.0, 40.0),
    "discrete_speeds_rpm": (10.0, 25.0, 40.0),
    "settle_time_s": 6.0,
    "reach_radius_m": 0.001,
    "max_sim_time_s": 4.0,
    "n_shape_nodes": 4,
}


@pytest.fixture(scope="session", autouse=True)
def steady_start_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """One steady-start disk cache for the whole session (also seen by subprocesses)."""
    folder = str(tmp_path_factory.mktemp("flagellum_cache"))
    old = os.environ.get("FLAGELLUM_CACHE_DIR")
    os.environ["FLAGELLUM_CACHE_DIR"] = folder
    yield folder
    if old is None:
        os.environ.pop("FLAGELLUM_CACHE_DIR", None)
    else:
        os.environ["FLAGELLUM_CACHE_DIR"] = old


@pytest.fixture
def small_kwargs() -> dict[str, Any]:
    """A fresh copy of the small configuration."""
    return dict(SMALL)


@pytest.fixture
def make_env() -> Iterator[Callable[..., FlagellumSteerEnv]]:
    """Factory of small envs (``SMALL`` updated with the keyword arguments), closed afterwards."""
    envs: list[FlagellumSteerEnv] = []

    def factory(**overrides: Any) -> FlagellumSteerEnv:
        env = FlagellumSteerEnv(**{**SMALL, **overrides})
        envs.append(env)
        return env

    yield factory
    for env in envs:
        env.close()
