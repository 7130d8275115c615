"""Fixtures of the agent tests: a session-wide steady-start cache (shared with subprocesses)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest


@pytest.fixture(scope="session", autouse=True)
def steady_start_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    folder = str(tmp_path_factory.mktemp("flagellum_cache_agents"))
    old = os.environ.get("FLAGELLUM_CACHE_DIR")
    os.environ["FLAGELLUM_CACHE_DIR"] = folder
    yield folder
    if old is None:
        os.environ.pop("FLAGELLUM_CACHE_DIR", None)
    else:
        os.environ["FLAGELLUM_CACHE_DIR"] = old
