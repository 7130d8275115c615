"""Package data (agents/assets.py): the shipped turn maps, evaluation paths and agent, and the user's turn maps."""

from __future__ import annotations

import fnmatch
from pathlib import Path

import pytest

from agents.assets import (default_turn_map, eval_paths_dir, packaged_turn_map, pretrained_dir,
                           user_turn_map_dir)
from agents.burst_pilot import SCRATCH_AGENT_DIR
from agents.evaluation import resolve_paths
from agents.turn_map import TurnMap
from physics.presets import preset_names

ROOT = Path(__file__).resolve().parents[2]


def test_every_preset_has_a_shipped_turn_map_that_loads():
    for preset in preset_names():
        if preset == "reference":  # the converged yardstick of the benchmarks, not a swimmer to steer
            continue
        tmap = TurnMap.load(packaged_turn_map(preset))
        assert tmap.max_theta_deg > 0


def test_a_users_turn_map_is_preferred_to_the_shipped_one(tmp_path, monkeypatch):
    monkeypatch.setenv("FLAGELLUM_TURN_MAPS", str(tmp_path))
    assert user_turn_map_dir() == tmp_path
    assert default_turn_map("faithful") == packaged_turn_map("faithful")
    (tmp_path / "faithful.json").write_text(packaged_turn_map("faithful").read_text())
    assert default_turn_map("faithful") == tmp_path / "faithful.json"
    assert default_turn_map("paper") == packaged_turn_map("paper")


@pytest.mark.parametrize("preset", ["coarse"])
def test_a_retired_presets_turn_map_is_refused_naming_the_replacement(preset, tmp_path, monkeypatch):
    from agents.turn_decision_env import load_turn_map

    monkeypatch.setenv("FLAGELLUM_TURN_MAPS", str(tmp_path))
    (tmp_path / f"{preset}.json").write_text(packaged_turn_map("faithful").read_text())  # even a user's own
    assert not (ROOT / "agents" / "turn_maps" / f"{preset}.json").exists()
    for lookup in (default_turn_map, packaged_turn_map, lambda p: load_turn_map(None, p)):
        with pytest.raises(ValueError, match=f"^preset {preset!r} was retired .*; use 'faithful' \\(the default\\)"):
            lookup(preset)


def test_the_user_folder_defaults_to_xdg_data_home(tmp_path, monkeypatch):
    monkeypatch.delenv("FLAGELLUM_TURN_MAPS", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    assert user_turn_map_dir() == tmp_path / "flagellum" / "turn_maps"


def test_paths_eval_is_the_twenty_shipped_evaluation_paths():
    paths = resolve_paths(["eval"])
    assert len(paths) == 20 and len(list(eval_paths_dir().glob("*.json"))) == 20
    assert {p.name for p in paths} >= {"planar_1000", "3d_1009"}


def test_the_wheel_ships_every_asset_file():
    """Each file under agents/turn_maps, agents/eval_paths and the shipped agents (``ppo``, ``ppo-scratch``) matches a
    package-data glob of pyproject.toml, and nothing else is left in agents/pretrained (validation, checkpoints and
    earlier agents are not shipped)."""
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["agents"]
    agents = ROOT / "agents"
    files = [f for d in (agents / "turn_maps", agents / "eval_paths", agents / "pretrained") for f in d.rglob("*")
             if f.is_file() and "__pycache__" not in f.parts]
    unshipped = [str(f) for f in files if not any(fnmatch.fnmatch(f.relative_to(agents).as_posix(), g) for g in globs)]
    assert not unshipped, unshipped
    assert sorted(f.name for f in pretrained_dir().iterdir()) == ["config.yml", "episodes.csv", "meta.json", "model.zip",
                                                                  "training_curve.png", "vecnormalize.pkl"]
    assert sorted(f.name for f in SCRATCH_AGENT_DIR.iterdir()) == ["config.yml", "meta.json", "model.zip",
                                                                   "training_curve.png", "vecnormalize.pkl"]
    assert sorted(d.name for d in (agents / "pretrained").iterdir()) == sorted([pretrained_dir().name,
                                                                                SCRATCH_AGENT_DIR.name])
