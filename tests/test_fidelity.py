"""The fidelity ladder's machinery: tasks, resumable results file, errors against paper, report files."""

from __future__ import annotations

import json

import pytest

from flagellum_bench.fidelity import (FidelityConfig, load_done, missing_tasks, rows_from, run_fidelity,
                                run_metric)
from flagellum_bench.report import markdown, write_report

# cheap stand-ins (N = 30, 50 ms steps): the machinery, not the physics, is under test here
CHEAP = {"n_nodes": 30}
REF = FidelityConfig("paper", "paper", params=CHEAP, numerics={"dt": 0.05})
RFT = FidelityConfig("rft", "paper", params=CHEAP, numerics={"dt": 0.05, "hydro_model": "rft"})
BROKEN = FidelityConfig("broken", "paper", params=CHEAP, numerics={"dt": 0.05, "newton_max_iter": 2, "newton_tol": 1e-12,
                                                                     "max_substeps": 0})
METRICS = ("swim_per_turn_10rpm",)


def test_tasks_are_appended_resumed_and_compared_against_paper(tmp_path):
    results = tmp_path / "fidelity.results.jsonl"
    done = run_fidelity(results, (REF, RFT), METRICS, workers=1, progress=False)
    assert len(results.read_text().splitlines()) == 2
    rec = done[("rft", "swim_per_turn_10rpm")]
    assert rec["error"] is None and rec["measured"] and rec["result"]["rtf"] > 0
    # resume: nothing is run again
    again = run_fidelity(results, (REF, RFT), METRICS, workers=1, progress=False)
    assert len(results.read_text().splitlines()) == 2 and again.keys() == done.keys()
    rows = {r["config"]: r for r in rows_from(load_done(results), (REF, RFT))}
    ref = rows["paper"]["values"]["swim_per_turn_10rpm"]
    rft = rows["rft"]["values"]["swim_per_turn_10rpm"]
    assert rows["paper"]["errors"]["swim_per_turn_10rpm"] == 0.0
    assert rows["rft"]["errors"]["swim_per_turn_10rpm"] == pytest.approx(abs(rft - ref) / ref)
    assert rows["rft"]["errors"]["swim_per_turn_10rpm"] > 0.1  # local RFT is not LSBT (docs/fidelity.md)
    assert missing_tasks(done, (REF, RFT), METRICS + ("omega_b",)) == ["paper: omega_b", "rft: omega_b"]

    out = tmp_path / "fidelity.json"
    write_report(list(rows.values()), out, tmp_path / "fidelity.md", tmp_path / "pareto.png", "test", 1.0,
                 missing=["paper: omega_b"])
    table = json.loads(out.read_text())
    assert isinstance(table, list)
    assert {"config", "preset", "real_time_factor", "errors"} <= set(table[0])
    assert "omega_b for `paper`" in (tmp_path / "fidelity.md").read_text()
    assert (tmp_path / "pareto.png").stat().st_size > 0


def test_a_failing_configuration_is_recorded_not_raised(tmp_path):
    done = run_fidelity(tmp_path / "r.jsonl", (BROKEN,), METRICS, workers=1, progress=False)
    rec = done[("broken", "swim_per_turn_10rpm")]
    assert rec["result"] is None and "SimulationError" in rec["error"]
    assert rows_from(done, (BROKEN,))[0]["failures"]


def test_unknown_metric_names_the_known_ones():
    with pytest.raises(ValueError, match="unknown metric 'speed'.*swim_per_turn_10rpm"):
        run_metric(REF, "speed")


TINY = FidelityConfig("tiny", params={"n_nodes": 20}, numerics={"dt": 0.05, "hydro_refresh_tol": 0.3})


def test_swim_metric_reports_a_forward_distance_and_a_cost():
    out = run_metric(TINY, "swim_per_turn_10rpm")
    assert 0.001 < out["swim_per_turn_10rpm"] < 0.01  # m per motor turn
    assert out["rtf"] > 0


def test_errors_are_relative_to_paper_with_an_angle_floor():
    done = {
        ("paper", "m"): {"config": "paper", "metric": "m", "error": None,
                         "result": {"swim_per_turn_10rpm": 0.004, "theta_tc10": 2.0, "rtf": 1.0}},
        ("tiny", "m"): {"config": "tiny", "metric": "m", "error": None,
                        "result": {"swim_per_turn_10rpm": 0.005, "theta_tc10": 5.0, "rtf": 10.0}},
    }
    rows = rows_from(done, (FidelityConfig("paper", "paper"), TINY))
    tiny = rows[1]
    assert tiny["errors"]["swim_per_turn_10rpm"] == pytest.approx(0.25)
    assert tiny["errors"]["theta_tc10"] == pytest.approx(3.0 / 10.0)  # floor of 10 degrees
    assert rows[0]["errors"]["swim_per_turn_10rpm"] == 0.0
    assert "tiny" in markdown(rows, "# t")
    json.dumps(rows)


def test_a_record_measured_with_another_setup_is_stale(tmp_path):
    """Redefining a configuration (e.g. a preset) must not reuse the numbers measured before."""
    results = tmp_path / "r.jsonl"
    run_fidelity(results, (TINY,), METRICS, workers=1, progress=False)
    assert ("tiny", METRICS[0]) in load_done(results, (TINY,))
    redefined = FidelityConfig("tiny", params={"n_nodes": 21}, numerics=TINY.numerics)
    assert ("tiny", METRICS[0]) not in load_done(results, (redefined,))
    assert ("tiny", METRICS[0]) in load_done(results)  # without configs nothing is filtered
    # a legacy record without a stored setup is kept
    rec = json.loads(results.read_text().splitlines()[0])
    del rec["setup"]
    results.write_text(json.dumps(rec) + "\n")
    assert ("tiny", METRICS[0]) in load_done(results, (redefined,))


def test_node_convergence_rows_table_and_plot(tmp_path):
    from flagellum_bench.node_convergence import METRIC, markdown as nc_markdown, plot, sweep_configs, sweep_rows

    configs = sweep_configs()
    assert len({c.name for c in configs}) == len(configs)  # no duplicate grid points
    first, second = configs[0], configs[1]
    done = {(first.name, METRIC): {"config": first.name, "metric": METRIC, "error": None, "measured": "x",
                                   "result": {"theta_tc40": 30.0, "phi_tc40": 20.0, "rtf": 5.0}},
            (second.name, METRIC): {"config": second.name, "metric": METRIC, "result": None, "measured": "x",
                                    "error": "SimulationError: step 3"}}
    ref = {"theta_tc40": 40.0, "phi_tc40": 35.0, "rtf": 0.5}
    rows = sweep_rows(done, ref)
    assert rows[0]["theta_error"] == pytest.approx(0.25)
    assert rows[1]["theta_tc40"] is None and rows[1]["error"].startswith("SimulationError")
    assert all(r["theta_tc40"] is None for r in rows[2:])
    table = nc_markdown(rows, ref, "# t")
    assert "| 45 | 10 | 0.1 | 30.0 | 20.0 | 25 % | 5.00 |" in table and "SimulationError: step 3" in table
    plot(rows, ref, tmp_path / "nc.png")
    assert (tmp_path / "nc.png").stat().st_size > 0


def test_relative_error_floors_angles_only():
    from flagellum_bench.fidelity import ANGLE_FLOOR_DEG, relative_error

    assert relative_error("swim_per_turn_10rpm", 1.1, 1.0) == pytest.approx(0.1)
    # an angle near 0 is compared against the floor, not against itself
    assert relative_error("phi_tc40", 3.0, 1.0) == pytest.approx(2.0 / ANGLE_FLOOR_DEG)
    assert relative_error("theta_tc40", 49.0, 47.5) == pytest.approx(1.5 / 47.5)
    assert relative_error("lratio_100s", 0.0, 0.0) == 0.0


def test_bench_runs_its_tasks_on_a_dask_cluster_with_scheduler(tmp_path, monkeypatch):
    """``flagellum bench --quick --scheduler ADDR`` on a Dask LocalCluster. Every task but the cheapest
    (faithful: steady swimming) is already in ``--results`` (resume), so one real task runs, on the cluster."""
    distributed = pytest.importorskip("distributed")
    import batch.backends as backends
    from flagellum.cli import main
    from flagellum_bench.fidelity import quick_configs, quick_tasks

    def no_local_processes(workers):
        raise AssertionError("bench --scheduler started local worker processes")

    monkeypatch.setattr(backends, "LocalBackend", no_local_processes)
    configs = quick_configs()
    tasks = quick_tasks(configs)
    cheap = next((c, m) for c, m in tasks if c.name == "faithful" and m == "swim_per_turn_10rpm")
    stubs = {"swim_per_turn_10rpm": {"swim_per_turn_10rpm": 0.0028, "rtf": 1.0, "rtf_cpu": 1.0, "wall_s": 1.0},
             "burst": {"theta_tc8": 80.0, "phi_tc8": 80.0, "lratio_burst": 0.5, "straight": True, "rtf": 1.0,
                       "rtf_cpu": 1.0, "wall_s": 1.0},
             "turns": {"theta_tc4": 60.0, "phi_tc4": 5.0, "theta_tc6": 120.0, "phi_tc6": 30.0, "wall_s": 1.0},
             "surrogate_episode": {"episode_success": True, "episode_mean_cross_track_m": 0.012,
                                   "episode_time_s": 290.0, "episode_cpu_s": 0.002, "episode_decisions": 5,
                                   "rtf_cpu": 145000.0, "decisions_per_cpu_s": 8000.0, "wall_s": 0.1},
             "surrogate_map": {"map_loo_rising_rms_deg": 3.5, "map_loo_rising_max_deg": 7.2,
                               "map_loo_peak_rms_deg": 36.7, "map_loo_beyond_rms_deg": 20.7,
                               "map_loo_rising_relative_max": 0.09, "wall_s": 0.1},
             "episode": {"episode_wall_s": 9.0, "episode_cpu_s": 9.0, "episode_success": True,
                         "episode_mean_cross_track_m": 0.01, "episode_time_s": 300.0, "rtf": 30.0, "wall_s": 9.0,
                         "env_steps_per_s_rule": 16.7},
             "env_random": {"env_steps_per_s_random": 4.0, "env_random_buckled_steps": 10, "rtf_cpu": 8.0,
                            "wall_s": 10.0}}
    results = tmp_path / "quick.results.jsonl"
    results.write_text("".join(
        json.dumps({"config": c.name, "metric": m, "result": stubs[m], "error": None,
                    "measured": "2026-01-01T00:00:00Z", "commit": None, "setup": c.setup()}) + "\n"
        for c, m in tasks if (c, m) != cheap))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        assert main(["bench", "--quick", "--json", str(tmp_path / "quick.json"), "--results", str(results),
                     "--scheduler", cluster.scheduler_address, "--no-progress"]) == 0
    lines = results.read_text().splitlines()
    assert len(lines) == len(tasks)
    rec = json.loads(lines[-1])
    assert rec["config"] == "faithful" and rec["metric"] == "swim_per_turn_10rpm" and rec["error"] is None
    assert 0.001 < rec["result"]["swim_per_turn_10rpm"] < 0.01  # m per motor turn
    rows = json.loads((tmp_path / "quick.json").read_text())
    assert [r["config"] for r in rows] == [c.name for c in configs]
    row = next(r for r in rows if r["config"] == "faithful")
    assert set(row) >= {"config", "preset", "real_time_factor", "burst_real_time_factor", "episode_wall_s", "errors",
                        "relax_real_time_factor_cpu", "env_steps_per_s_rule", "env_steps_per_s_random"}
    assert row["errors"]["theta_tc8"] == 0.0 and row["episode_wall_s"] == 9.0  # the stubs equal reference's
    assert row["errors"]["theta_tc4"] == 0.0 and row["episode_real_time_factor_cpu"] == pytest.approx(300.0 / 9.0)
    assert row["env_steps_per_s_random"] == 4.0
    assert next(r for r in rows if r["config"] == "reference")["episode_wall_s"] is None  # not run for reference
    sur = next(r for r in rows if r["config"] == "surrogate")  # the cheapest tier, in the same run
    assert sur["decisions_per_cpu_s"] == 8000.0 and sur["errors"] == {"theta_between_samples": 0.09}
    assert sur["episode_real_time_factor_cpu"] == pytest.approx(145000.0) and sur["real_time_factor"] is None
    md = (tmp_path / "quick.md").read_text()
    assert "faithful" in md and "](quick.png)" in md  # the Pareto figure, written beside it
    assert "| surrogate |" in md and "rising branch RMS 3.5" in md
    assert (tmp_path / "quick.png").stat().st_size > 10_000


def test_the_surrogate_tier_measures_its_episode_speed_and_map_error():
    """The surrogate row's two tasks on the quick protocol's path: the rule planner's episode in the surrogate
    (success, cross-track, simulated s per CPU s, decisions per CPU s) and its map's leave-one-out error."""
    from agents.assets import eval_paths_dir
    from flagellum_bench.fidelity import ANGLE_FLOOR_DEG, EPISODE_PATH
    from flagellum_bench.surrogate_tier import run_surrogate_metric

    ep = run_surrogate_metric("surrogate_episode", str(eval_paths_dir() / EPISODE_PATH), ANGLE_FLOOR_DEG)
    assert ep["episode_success"] and 0.0 < ep["episode_mean_cross_track_m"] < 0.05
    assert ep["episode_decisions"] >= 3 and ep["episode_time_s"] > 100.0  # three waypoints, minutes of swimming
    assert ep["rtf_cpu"] > 1000.0 and ep["decisions_per_cpu_s"] > 100.0  # no rod: far faster than real time
    m = run_surrogate_metric("surrogate_map", "", ANGLE_FLOOR_DEG)
    assert 0.0 < m["map_loo_rising_rms_deg"] <= m["map_loo_rising_max_deg"] < m["map_loo_peak_rms_deg"]
    assert 0.0 < m["map_loo_rising_relative_max"] < 1.0
    with pytest.raises(ValueError, match="unknown surrogate metric 'surrogate_x'"):
        run_surrogate_metric("surrogate_x", "", ANGLE_FLOOR_DEG)
