"""scripts/success_by_burst_factor.py: successes binned by the swimmer's burst time factor (folders made up here)."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import gymnasium as gym
import pytest

import agents  # noqa: F401  (registers the ids)

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "success_by_burst_factor.py"
RANDOMIZE = {"youngs_modulus": 0.1, "viscosity": 0.1, "head_radius": 0.1, "geometry": 0.04, "obs_noise_std": 0.0}


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("success_by_burst_factor", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _folder(tmp_path: Path, name: str, randomize, successes: dict[str, list[bool]]) -> Path:
    paths = [f"p{k}" for k in range(len(next(iter(successes.values()))))]
    per_path = [{"path": p, "controller": c, "success": s} for c, ss in successes.items() for p, s in zip(paths, ss)]
    folder = tmp_path / name
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps({
        "per_path": per_path, "aggregate": {}, "preset": "faithful", "missing": [],
        "env_overrides": None if randomize is None else {"randomize": randomize},
        "seeds": {p: 500 + k for k, p in enumerate(paths)}}))
    return folder


def test_each_swimmer_is_binned_by_the_ln_f_its_seed_draws(script, tmp_path, capsys):
    folder = _folder(tmp_path, "a", RANDOMIZE, {"adaptive": [True, False, True, True], "rule": [False] * 4})
    twin = gym.make("FlagellumBurst-surrogate-v0", env_kwargs={"randomize": RANDOMIZE}).unwrapped
    expected = {}
    for s in range(500, 504):
        twin.reset(seed=s)
        expected[s] = math.log(twin.swimmer.time_factor)
    assert script.burst_factor_logs(RANDOMIZE, list(range(500, 504))) == expected
    assert len(set(expected.values())) == 4   # four different swimmers
    assert script.main(["--eval", str(folder), "--edges", "-1", "1", "--json", str(tmp_path / "t.json")]) == 0
    doc = json.loads((tmp_path / "t.json").read_text())
    assert doc["bins"] == [{"ln_F": [-1.0, 1.0], "swimmers": 4, "successes": {"adaptive": 3, "rule": 0}}]
    assert sorted(e["ln_F"] for e in doc["episodes"] if e["controller"] == "rule") == sorted(expected.values())
    cut = sorted(expected.values())[1]   # one swimmer below the edge, three at or above it
    rows = script.binned(doc["episodes"], [-1.0, cut, 1.0])
    assert [r["swimmers"] for r in rows] == [1, 3]
    assert "| ln F | swimmers | `adaptive` | `rule` |" in capsys.readouterr().out


def test_bad_edges_and_a_nominal_folder_are_refused_in_one_line(script, tmp_path, capsys):
    nominal = _folder(tmp_path, "n", None, {"adaptive": [True]})
    assert script.main(["--eval", str(nominal), "--edges", "0", "0"]) == 2
    assert script.main(["--eval", str(nominal)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--edges [0.0, 0.0]" in err[0] and "without --randomize" in err[1]
