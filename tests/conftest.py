"""Fixtures of the whole suite: one steady-start disk cache and one (empty) user turn-map folder per
session (also seen by subprocesses), so tests never read or write the user's; and ``usage_error``."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator

import pytest


def _session_folder(tmp_path_factory: pytest.TempPathFactory, variable: str, name: str) -> Iterator[str]:
    """A fresh folder named by the environment variable ``variable`` for the session, then the old value back."""
    folder = str(tmp_path_factory.mktemp(name))
    old = os.environ.get(variable)
    os.environ[variable] = folder
    yield folder
    if old is None:
        os.environ.pop(variable, None)
    else:
        os.environ[variable] = old


@pytest.fixture(scope="session", autouse=True)
def steady_start_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """One steady-start disk cache for the whole session (also seen by subprocesses)."""
    yield from _session_folder(tmp_path_factory, "FLAGELLUM_CACHE_DIR", "flagellum_cache")


@pytest.fixture(scope="session", autouse=True)
def user_turn_maps(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """An empty user turn-map folder (``agents.assets.user_turn_map_dir``) for the whole session, so tests use
    the shipped maps and never read or write the user's."""
    yield from _session_folder(tmp_path_factory, "FLAGELLUM_TURN_MAPS", "turn_maps")


@pytest.fixture
def usage_error(capsys) -> Callable[[list[str]], str]:
    """``usage_error(argv)`` runs ``flagellum argv`` in-process expecting exit status 2 and one line
    ``flagellum: error: ...`` on stderr (no traceback); returns that line."""
    from flagellum.cli import main

    def run(argv: list[str]) -> str:
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 2
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith("flagellum: error: ") and "Traceback" not in err
        return lines[0]

    return run


@pytest.fixture(scope="session")
def load_script() -> Callable[[str], object]:
    """Import scripts/NAME.py as a module (scripts/ is not a package): ``load_script("stress_tiers")``."""
    import importlib.util
    from pathlib import Path

    scripts = Path(__file__).resolve().parents[1] / "scripts"

    def load(name: str):
        spec = importlib.util.spec_from_file_location(name, scripts / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    return load
