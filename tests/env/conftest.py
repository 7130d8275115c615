"""Shared fixtures of the environment tests: small envs (the steady-start cache is in tests/conftest.py).

The small configuration (faithful preset, 0.2 s steps, a 6 mm path, 10-40 rpm so the flagellum
never buckles, a 6 s settle) keeps every episode to a fraction of a second of wall time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from flagellum_env.steer_env import FlagellumSteerEnv

SMALL: dict[str, Any] = {
    "path": [[0.003, 0.0, 0.0], [0.006, 0.001, 0.0]],
    "preset": "faithful",
    "control_dt": 0.2,
    "omega_range_rpm": (10.0, 40.0),
    "discrete_speeds_rpm": (10.0, 25.0, 40.0),
    "settle_time_s": 6.0,
    "reach_radius_m": 0.001,
    "max_sim_time_s": 4.0,
    "n_shape_nodes": 4,
}


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
