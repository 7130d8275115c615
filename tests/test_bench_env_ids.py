"""flagellum_bench.env_ids (scripts/bench_env_ids.py, the table of registered ids in docs/env.md): a short run
gives positive rates from CPU time, and the table names every row."""

from __future__ import annotations

from flagellum_bench.env_ids import bench_steer, format_table


def test_a_short_steer_run_reports_steps_per_cpu_second():
    row = bench_steer("FlagellumSteer-fast-v0", "fixed", n_steps=2)
    assert row["preset"] == "fast" and row["steps"] == 2 and row["control_dt_s"] == 2.0
    assert row["cpu_s"] >= 0 and row["steps_per_cpu_s"] > 0 and row["steps_per_wall_s"] > 0
    assert row["simulation_errors"] == 0
    table = format_table([row])
    assert "`FlagellumSteer-fast-v0` | `fast` | fixed | 2 |" in table
