"""The benchmark helpers behind scripts/bench_env.py run and report what they promise."""

from __future__ import annotations

import pytest

from flagellum_env.bench import bench_env, format_table


def test_bench_reports_steps_per_second(small_kwargs):
    rows = bench_env({"low": 3, "random": 3}, env_kwargs=small_kwargs)
    assert [r["policy"] for r in rows] == ["low", "random"]
    for r in rows:
        assert r["n_steps"] == 3 and r["steps_per_s"] > 0 and r["preset"] == "faithful"
        assert r["steps_per_s"] == pytest.approx(1.0 / r["median_step_s"])
    table = format_table(rows)
    assert "steps/s" in table and table.count("\n") == 3


def test_bench_rejects_unknown_policy(small_kwargs):
    with pytest.raises(ValueError, match="policy='spin'"):
        bench_env({"spin": 3}, env_kwargs=small_kwargs)
