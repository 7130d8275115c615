"""Fixtures of the whole suite: one steady-start disk cache per session (also seen by subprocesses),
so tests never read or write the user's cache."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest


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


@pytest.fixture(scope="session", autouse=True)
def user_turn_maps(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """An empty user turn-map folder (``agents.assets.user_turn_map_dir``) for the whole session, so tests use
    the shipped maps and never read or write the user's."""
    folder = str(tmp_path_factory.mktemp("turn_maps"))
    old = os.environ.get("FLAGELLUM_TURN_MAPS")
    os.environ["FLAGELLUM_TURN_MAPS"] = folder
    yield folder
    if old is None:
        os.environ.pop("FLAGELLUM_TURN_MAPS", None)
    else:
        os.environ["FLAGELLUM_TURN_MAPS"] = old
