"""Path-following harness: evaluate() results files, resume, metrics, CLI errors, eval paths."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import batch.pool as task_pool
from agents.evaluation import evaluate, resolve_paths, results_markdown, summarise
from agents.path_following import METRICS, EpisodeTrace, episode_metrics
from flagellum.cli import main
from flagellum_env.paths import RandomPathConfig, path_from_waypoints, random_path, save_path

SHORT = path_from_waypoints([[0.004, 0.0, 0.0]], name="short", reach_radius_m=0.002)


def test_controllers_followed_at_once_match_one_after_the_other():
    from agents.path_following import FollowTask, env_settings, follow_controllers, make_controller, run_episode
    from flagellum_env.steer_env import FlagellumSteerEnv

    path, specs = SHORT, ["rule", "adaptive"]
    got, interrupted = follow_controllers([FollowTask(s, path, "faithful") for s in specs], workers=2)
    assert interrupted is False and list(got) == specs
    for spec in specs:
        env = FlagellumSteerEnv(path=path, **env_settings(spec, "faithful"))
        metrics, trace = run_episode(env, make_controller(spec, env, "faithful"), path)
        par_metrics, par_trace = got[spec]
        assert par_metrics["time_s"] > 0.0 and "interrupted" not in par_metrics
        for field in ("t", "head", "omega_rpm", "end_to_end_ratio", "cross_track_m", "waypoint_index"):
            assert np.array_equal(getattr(par_trace, field), getattr(trace, field)), (spec, field)
        assert {k: v for k, v in par_metrics.items() if k not in ("wall_time_s", "turns")} == {
            k: v for k, v in metrics.items() if k != "wall_time_s"}


def test_evaluate_writes_results_and_resumes(tmp_path, monkeypatch):
    out = tmp_path / "eval"
    res = evaluate([SHORT], ["rule"], "faithful", out, workers=1, progress=False)
    doc = json.loads((out / "results.json").read_text())
    assert doc == json.loads(json.dumps(res))
    row = doc["per_path"][0]
    assert row["path"] == "short" and row["controller"] == "rule" and row["status"] == "ok"
    assert set(METRICS) <= set(row)
    assert row["success"] and row["waypoints_reached"] == 1 and row["buckling_events"] == 0
    assert 2.0 < row["time_s"] < 6.0  # (4 - 2) mm at ~0.7 mm/s
    record = json.loads((out / "results.jsonl").read_text().splitlines()[0])
    assert record["turns"] == []  # the planner's turns are kept with the episode (none on a straight path)
    agg = doc["aggregate"]["rule"]
    assert agg["success_rate"] == 1.0 and agg["episodes"] == 1
    assert agg["mean_cross_track_m"] == pytest.approx(row["mean_cross_track_m"])
    assert "| success rate (%) | 100 |" in (out / "results.md").read_text()
    # a resumed run starts no worker and gives the same numbers
    monkeypatch.setattr(task_pool, "make_backend", lambda *a: pytest.fail("resume started workers"))
    again = evaluate([SHORT], ["rule"], "faithful", out, resume=True, progress=False)
    assert again["per_path"][0]["time_s"] == row["time_s"]
    # report-only lists what was never run instead of running it
    other = path_from_waypoints([[0.0, 0.004, 0.0]], name="other")
    partial = evaluate([SHORT, other], ["rule"], "faithful", out, report_only=True, progress=False)
    assert partial["missing"] == ["rule on other"] and len(partial["per_path"]) == 1


def test_seed0_draws_each_paths_swimmer_from_its_own_seed_and_the_report_pairs_them(tmp_path):
    from agents.evaluation_report import folder_report

    out = tmp_path / "eval"
    other = path_from_waypoints([[0.0, 0.004, 0.0]], name="other", reach_radius_m=0.002)
    res = evaluate([SHORT, other], ["rule"], "faithful", out, workers=1, progress=False, seed_per_path=True, seed0=7)
    assert res["seeds"] == {"short": 7, "other": 8}
    with pytest.raises(ValueError, match="seed0"):
        evaluate([SHORT], ["rule"], "faithful", tmp_path / "e2", workers=1, progress=False, seed0=-1)
    lines = folder_report(out, tmp_path / "figures", "short_paths")
    text = "\n".join(lines)
    assert "| other (8) | " in text and "| short (7) | yes (1/1)" in text
    assert "env seeds 7-8" in text
    assert (tmp_path / "figures" / "short_paths.png").is_file()
    # the cross-track budget reads the same traces: its mean is the episodes' mean cross-track
    from experiments.cross_track_budget import budget_table, folder_budgets

    b = folder_budgets(out)["rule"]
    assert b["episodes"] == 2
    assert b["mean_m"] == pytest.approx(res["aggregate"]["rule"]["mean_cross_track_m"], rel=0.05)
    assert "| `rule` | 2 |" in "\n".join(budget_table({"eval": folder_budgets(out)}))


def test_episode_metrics_from_a_trace():
    path = path_from_waypoints([[0.1, 0.0, 0.0], [0.1, 0.1, 0.0]])
    heads = np.array([[0, 0, 0], [0.05, 0.01, 0.002], [0.1, 0.05, -0.004]])
    trace = EpisodeTrace(t=np.array([0.0, 1.0, 2.0]), head=heads,
                         omega_rpm=np.array([10.0, 150, 10]), end_to_end_ratio=np.ones(3),
                         cross_track_m=np.array([0.0, 0.01, 0.0]), waypoint_index=np.array([0, 0, 1]),
                         waypoints=path.waypoints)
    m = episode_metrics(trace, path, {"is_success": False, "waypoint_index": 1, "energy_used_j": 0.5,
                                      "buckling_events": 1})
    assert m["mean_cross_track_m"] == pytest.approx(0.005) and m["max_cross_track_m"] == pytest.approx(0.01)
    assert m["max_out_of_plane_ratio"] == pytest.approx(0.04)  # 4 mm over the 0.1 m second segment
    assert m["time_s"] == 2.0 and not m["success"] and m["energy_J"] == 0.5
    path3d = path_from_waypoints([[0.1, 0.0, 0.01]])
    trace.waypoints = path3d.waypoints
    trace.waypoint_index[:] = 0
    assert episode_metrics(trace, path3d, {"is_success": True, "waypoint_index": 1, "energy_used_j": 0.0,
                                           "buckling_events": 0})["max_out_of_plane_ratio"] is None


def test_summary_and_table_with_two_controllers():
    recs = [{"path": p, "controller": c, "status": "ok", "success": s, "waypoints_reached": 1,
             "mean_cross_track_m": x, "max_cross_track_m": x, "max_out_of_plane_ratio": None, "time_s": 10.0,
             "energy_J": 1e-3, "buckling_events": 1, "wall_time_s": 2.0}
            for p, c, s, x in [("a", "rule", True, 0.01), ("b", "rule", False, 0.03), ("a", "ppo", True, 0.02)]]
    res = summarise(recs, ["rule", "ppo"])
    assert res["aggregate"]["rule"]["success_rate"] == 0.5
    assert math.isclose(res["aggregate"]["rule"]["mean_cross_track_m"], 0.02)
    assert res["aggregate"]["ppo"]["max_out_of_plane_ratio"] is None
    md = results_markdown(res)
    assert "| metric | rule | ppo |" in md and "| success rate (%) | 50 | 100 |" in md


def test_resolve_paths_errors_and_folders(tmp_path):
    with pytest.raises(ValueError, match="allowed: 'square'"):
        resolve_paths([str(tmp_path / "missing.json")])
    with pytest.raises(ValueError, match="no path files"):
        resolve_paths([str(tmp_path)])
    save_path(SHORT, tmp_path / "a.json")
    save_path(path_from_waypoints([[0.01, 0, 0]], name="other"), tmp_path / "b.json")
    assert [p.name for p in resolve_paths([str(tmp_path), "square"])] == ["short", "other", "square"]
    with pytest.raises(ValueError, match="unique"):
        resolve_paths([str(tmp_path / "a.json"), str(tmp_path / "a.json")])


@pytest.mark.parametrize("argv, message", [
    (["evaluate", "--paths", "nowhere.json", "--controller", "rule"], "allowed: 'square', 'eval'"),
    (["evaluate", "--paths", "square", "--controller", "magic"], "controller 'magic' is not allowed"),
    (["evaluate", "--paths", "square", "--controller", "rule", "--seed0", "-1"], "--seed0 '-1' is not allowed"),
    (["follow", "--path", "square", "--controller", "ppo:no_agent_here"], "no trained PPO agent"),
    (["follow", "--path", "square", "--controller", "rule:nomap.json"], "no turn map at 'nomap.json'"),
    (["calibrate-turns", "--preset", "faithful", "--t-c", "-1"], "--t-c '-1' is not allowed"),
])
def test_cli_rejects_bad_input(argv, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main([*argv, "--out", str(tmp_path / "o")] if argv[0] != "calibrate-turns"
             else [*argv, "--out", str(tmp_path / "m.json")])
    assert info.value.code == 2
    assert message in capsys.readouterr().err


def test_random_paths_respect_the_turn_range():
    cfg = RandomPathConfig(n_waypoints=6, segment_length_m=(0.1, 0.2), min_turn_deg=30.0, max_turn_deg=150.0)
    for seed in range(5):
        v = random_path(np.random.default_rng(seed), cfg).vertices
        seg = np.diff(np.vstack([[-1.0, 0, 0], v]), axis=0)  # the heading before the first segment is +x
        for a, b in zip(seg[:-1], seg[1:], strict=True):
            ang = math.degrees(math.acos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))
            assert 30.0 - 1e-9 <= ang <= 150.0 + 1e-9
    with pytest.raises(ValueError, match="min_turn_deg"):
        RandomPathConfig(min_turn_deg=100.0, max_turn_deg=90.0)


def test_follow_randomize_draws_the_swimmer_from_the_seed_and_records_it(tmp_path):
    """``flagellum follow --randomize F --seed S``: the swimmer differs from the nominal one (another episode), the
    same seed draws the same swimmer, and summary.json says what was drawn from."""
    path = tmp_path / "one_turn.json"
    path.write_text(json.dumps({"name": "one_turn", "waypoints": [[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]],
                                "reach_radius_m": 0.015}))
    runs = {}
    for name, extra in (("nominal", []), ("a", ["--randomize", "0.1", "--seed", "3"]),
                        ("b", ["--randomize", "0.1", "--seed", "3"])):
        out = tmp_path / name
        assert main(["follow", "--path", str(path), "--preset", "faithful", "--no-progress", "--out", str(out)]
                    + extra) == 0
        runs[name] = json.loads((out / "summary.json").read_text())
    assert runs["nominal"]["randomize"] is None
    assert runs["a"]["randomize"] == {"youngs_modulus": 0.1, "viscosity": 0.1, "head_radius": 0.1,
                                      "geometry": pytest.approx(0.04), "obs_noise_std": 0.0} and runs["a"]["seed"] == 3
    rule = [r["controllers"]["rule"] for r in (runs["nominal"], runs["a"], runs["b"])]
    assert all(rule[1][k] == rule[2][k] for k in ("time_s", "mean_cross_track_m", "energy_J"))
    assert rule[1]["energy_J"] != rule[0]["energy_J"]


def test_best_planner_is_the_higher_success_then_the_lower_cross_track():
    from agents.evaluation_report import best_planner

    def res(**agg):
        return {"aggregate": {k: {"success_rate": s, "mean_cross_track_m": x} for k, (s, x) in agg.items()}}

    assert best_planner(res(rule=(0.5, 0.01), adaptive=(0.8, 0.02), ppo=(1.0, 0.001))) == "adaptive"
    assert best_planner(res(rule=(1.0, 0.007), adaptive=(1.0, 0.008))) == "rule"
    assert best_planner(res(rule=(1.0, None), adaptive=(1.0, 0.008))) == "adaptive"
    assert best_planner(res(adaptive=(0.2, 0.03))) == "adaptive"
    with pytest.raises(ValueError, match="none of the planners"):
        best_planner(res(ppo=(1.0, 0.001)))
