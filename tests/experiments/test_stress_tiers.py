"""scripts/stress_tiers.py classifies each corner: a finite bounded run is ok, a clear error is an error, and its
summary section replaces itself in the page."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def stress(load_script):
    return load_script("stress_tiers")


def test_every_tier_has_every_corner(stress):
    runs = stress.physics_corners()
    for tier in stress.PHYSICS_TIERS:
        corners = [r["corner"] for r in runs if r["tier"] == tier]
        assert any(c.startswith("0 rpm") for c in corners) and any(c.startswith("300 rpm") for c in corners)
        assert any("largest step" in c for c in corners) and any("long burst" in c for c in corners)
        assert sum("randomised +-20 %" in c for c in corners) == len(stress.RANDOM_SEEDS)
    keys = [stress.key(r) for r in runs + stress.surrogate_corners()]
    assert len(keys) == len(set(keys))


def test_physics_corner_ok_and_error(stress):
    ok = stress.run_physics({"tier": "faithful", "corner": "t", "rpm": 10.0, "duration": 0.2, "numerics": {}})
    assert ok["outcome"] == "ok", ok
    assert 0.5 <= ok["edge_ratio"][0] <= ok["edge_ratio"][1] <= 2.0
    bad = stress.run_physics({"tier": "faithful", "corner": "t", "rpm": 10.0, "duration": 0.2,
                              "numerics": {"dt": -1.0}})
    assert bad["outcome"] == "error" and "dt" in bad["message"]


def test_surrogate_corners(stress, monkeypatch):
    monkeypatch.setattr(stress, "SURROGATE_EPISODES", 3)
    ok = stress.run_surrogate({"tier": "FlagellumTurn-surrogate-v0", "corner": "t", "policy": "high",
                               "fraction": 0.15})
    assert ok["outcome"] == "ok" and ok["episodes"] == 3 and ok["decisions"] >= 3
    out = stress.run_surrogate({"tier": "FlagellumBurst-surrogate-v0", "corner": "t", "policy": "random",
                                "fraction": 0.2})
    assert out["outcome"] == "error" and "0.2" in out["message"]


def test_section_replaced_in_place(stress, tmp_path):
    md = tmp_path / "page.md"
    md.write_text("# Page\n\nbefore\n")
    rec = {"tier": "faithful", "corner": "0 rpm", "outcome": "ok", "sim_time_s": 1.0, "halvings": 0,
           "end_to_end": 1.0, "edge_ratio": [0.99, 1.01], "cpu_s": 1.0}
    stress.write_section(md, [rec], "cmd")
    stress.write_section(md, [{**rec, "outcome": "error", "message": "m"}], "cmd")
    text = md.read_text()
    assert text.count(stress.MARKERS[0]) == 1 and "before" in text
    assert "| faithful | 0 rpm | error |" in text and "| faithful | 0 rpm | ok |" not in text


def test_numerics_table_keeps_the_tier_section(stress, load_script, tmp_path):
    """scripts/stress.py rewrites its own table and keeps the "Every tier" section below it."""
    numerics = load_script("stress")
    md = tmp_path / "stability.md"
    rec = {"tier": "faithful", "corner": "0 rpm", "outcome": "ok", "sim_time_s": 1.0, "halvings": 0,
           "end_to_end": 1.0, "edge_ratio": [0.99, 1.01], "cpu_s": 1.0}
    stress.write_section(md, [rec], "cmd")
    numerics.write_md([{"corner": "omega 150 rpm", "outcome": "ok", "sim_time_s": 2.0, "halvings": 0,
                        "newton_per_step": 3.0, "end_to_end": 1.0, "min_gaps_mm": [1.0, 2.0], "wall_s": 1.0}],
                      md, "python scripts/stress.py")
    text = md.read_text()
    assert text.startswith("# Stability at the extremes") and "| omega 150 rpm | ok |" in text
    assert text.count(stress.MARKERS[0]) == 1 and "| faithful | 0 rpm | ok |" in text
