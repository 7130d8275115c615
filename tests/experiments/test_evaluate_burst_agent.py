"""scripts/evaluate_burst_agent.py flies an agent with the action design it was trained with (its BurstLimits)."""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import gymnasium
import pytest

from agents.burst_pilot import SCRATCH_AGENT_DIR
from flagellum_env.paths import path_from_waypoints, save_path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "evaluate_burst_agent.py"


def _script():
    spec = importlib.util.spec_from_file_location("evaluate_burst_agent", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture()
def agents_and_path(tmp_path):
    """Two copies of the shipped agent, whose metas say their bursts end by time and by L'/L."""
    copies = []
    for end in ("time", "ratio"):
        agent = tmp_path / f"{end}_agent"
        shutil.copytree(SCRATCH_AGENT_DIR, agent)
        meta = json.loads((agent / "meta.json").read_text(encoding="utf-8"))
        meta.setdefault("make_kwargs", {})["limits"] = {**meta["make_kwargs"].get("limits", {}), "burst_end": end}
        (agent / "meta.json").write_text(json.dumps(meta), encoding="utf-8")
        copies.append(agent)
    path = tmp_path / "one_turn.json"
    save_path(path_from_waypoints([[0.12, 0.0, 0.0], [0.12, 0.15, 0.0]], name="one_turn", reach_radius_m=0.015), path)
    return copies[0], copies[1], path


def test_the_agents_own_burst_end_is_flown(agents_and_path, monkeypatch):
    timed, ratio, path = agents_and_path
    script = _script()
    made = []
    real_make = gymnasium.make

    def make(env_id, **kwargs):
        env = real_make(env_id, **kwargs)
        made.append(env.unwrapped.limits.burst_end)
        return env

    monkeypatch.setattr(gymnasium, "make", make)  # the script imports gymnasium in fly()
    task = {"path": str(path), "env": "FlagellumBurst-surrogate-v0", "preset": "faithful", "randomize": 0.1,
            "seed": 3}
    for agent in (timed, ratio):
        row = script.fly({**task, "agent": str(agent)})
        assert row["error"] is None and row["decisions"] >= 1
    assert made == ["time", "ratio"]
