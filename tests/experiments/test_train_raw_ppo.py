"""scripts/train_raw_ppo.py (library: experiments/raw_ppo.py): a tiny PPO run on the raw FlagellumSteer-v0 (faithful
preset) writes SB3's progress.csv, VecMonitor's monitor.csv, a checkpoint per update and meta; a SIGTERM stops it
cleanly after the finished updates; --resume goes on without losing or repeating rows; the learning curve is
drawn; bad options are one-line errors with status 2."""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import signal
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "train_raw_ppo.py"
# faithful preset, 1 s steps, 10-40 rpm (never buckles), a 6 s steady start, a 3-6 mm path and a 4 s time limit:
# every env step is a fraction of a second and an episode ends every few steps
TINY_ENV = {"settle_time_s": 6.0, "omega_range_rpm": [10.0, 40.0], "reach_radius_m": 0.001, "max_sim_time_s": 4.0,
            "n_shape_nodes": 4}
TINY_PATH = {"n_waypoints": 1, "segment_length_m": [0.003, 0.006], "max_turn_deg": 20.0}
TINY = ["--preset", "faithful", "--control-dt", "1.0", "--n-envs", "1", "--n-steps", "8", "--batch-size", "8",
        "--random-path", json.dumps(TINY_PATH), "--env-kwargs", json.dumps(TINY_ENV),
        "--ppo-kwargs", json.dumps({"n_epochs": 2, "policy_kwargs": {"net_arch": [8]}})]


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("train_raw_ppo", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _rows(file: Path) -> list[dict[str, str]]:
    with open(file, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _progress(out: Path) -> list[dict[str, str]]:
    return _rows(out / "progress.csv")


def _monitor(out: Path) -> list[dict[str, str]]:
    lines = (out / "monitor.csv").read_text().splitlines()
    assert lines[0].startswith("#{")  # VecMonitor's header line
    return list(csv.DictReader(lines[1:]))


def test_run_stop_resume_and_plot(script, tmp_path, monkeypatch):
    """SB3's logger writes progress.csv, VecMonitor monitor.csv, CheckpointCallback a checkpoint per update; a
    SIGTERM keeps the finished updates; --resume goes on without counting a step or an episode twice."""
    from flagellum_env.steer_env import FlagellumSteerEnv

    out = tmp_path / "run"
    # a real SIGTERM during the 12th env step (in the second update's rollout)
    step, calls = FlagellumSteerEnv.step, []

    def step_then_sigterm(self, action):
        calls.append(1)
        if len(calls) == 12:
            os.kill(os.getpid(), signal.SIGTERM)
        return step(self, action)

    monkeypatch.setattr(FlagellumSteerEnv, "step", step_then_sigterm)
    handler = signal.getsignal(signal.SIGTERM)
    assert script.main(["--out", str(out), "--timesteps", "16", *TINY], progress=False) == 128 + signal.SIGTERM
    assert signal.getsignal(signal.SIGTERM) is handler  # restored
    monkeypatch.setattr(FlagellumSteerEnv, "step", step)
    rows = _progress(out)
    assert [int(r["time/total_timesteps"]) for r in rows] == [8]  # the finished update only
    assert float(rows[0]["rollout/env_steps_per_s"]) > 0 and float(rows[0]["run/wall_s"]) > 0
    assert float(rows[0]["run/cpu_s"]) > 0 and rows[0]["run/update"] == "1"
    ckpt = out / "checkpoints"
    assert (ckpt / "rl_model_8_steps.zip").is_file() and (ckpt / "rl_model_vecnormalize_8_steps.pkl").is_file()
    assert not (ckpt / "rl_model_16_steps.zip").exists()
    assert (out / "model.zip").is_file() and (out / "vecnormalize.pkl").is_file()  # the last finished update's
    meta = json.loads((out / "meta.json").read_text())
    assert meta["sessions"][0]["status"] == "stopped: SIGTERM" and meta["total"]["env_steps"] == 8
    assert meta["config"]["preset"] == "faithful" and meta["config"]["seed"] == 0
    assert len(meta["sessions"][0]["loadavg_start"]) == 3 and meta["sessions"][0]["loadavg_end"]
    kept = json.loads((ckpt / "rl_model_state_8_steps.json").read_text())["episodes_total"]
    assert len(_monitor(out)) > kept  # episodes that ended after the checkpoint: --resume drops them

    assert script.main(["--out", str(out), "--resume", "--timesteps", "16"], progress=False) == 0
    assert script.main(["--out", str(out), "--resume", "--timesteps", "32"], progress=False) == 0
    rows = _progress(out)
    assert [int(r["time/total_timesteps"]) for r in rows] == [8, 16, 24, 32]
    assert [int(r["run/update"]) for r in rows] == [1, 2, 3, 4]
    assert [float(r["run/wall_s"]) for r in rows] == sorted(float(r["run/wall_s"]) for r in rows)
    episodes = _monitor(out)
    state = json.loads((ckpt / "rl_model_state_32_steps.json").read_text())
    assert state["env_steps"] == 32 and state["updates"] == 4
    # every episode once: one env, so the lengths of the episodes add up to the steps at which each ended
    assert len(episodes) == state["episodes_total"] == int(rows[-1]["run/episodes_total"]) > 0
    assert sum(int(e["l"]) for e in episodes) <= 32
    assert {"is_success", "buckling_events", "waypoint_index", "sim_time_s"} <= set(episodes[0])
    assert sum(e["is_success"] == "True" for e in episodes) == state["successes_total"]
    assert (out / "model.zip").is_file() and (out / "vecnormalize.pkl").is_file()
    assert (out / "learning_curve.png").stat().st_size > 1000
    meta = json.loads((out / "meta.json").read_text())
    assert [s["status"] for s in meta["sessions"]] == ["stopped: SIGTERM", "finished", "finished"]
    assert meta["total"]["env_steps"] == 32 and meta["timesteps"] == 32 and meta["commit"]

    (out / "learning_curve.png").unlink()
    assert script.main(["--out", str(out), "--plot"]) == 0
    assert (out / "learning_curve.png").is_file()


def test_a_run_logged_before_sb3s_logger_still_plots(script, tmp_path):
    """results/agents/raw_ppo_faithful was written by the earlier script (its own column names)."""
    out = tmp_path / "old"
    out.mkdir()
    (out / "progress.csv").write_text("update,env_steps,wall_s,ep_return_mean,success_rate\n1,64,300.0,-3.5,0.0\n"
                                      "2,128,610.0,,\n")
    assert script.main(["--out", str(out), "--plot"]) == 0
    assert (out / "learning_curve.png").stat().st_size > 1000


def test_help_describes_the_outputs(script, capsys):
    with pytest.raises(SystemExit) as info:
        script.main(["--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for word in ("progress.csv", "monitor.csv", "CheckpointCallback", "--resume", "--quiet", "--max-wall-min"):
        assert word in text


def _usage_error(script, capsys, argv: list[str]) -> str:
    with pytest.raises(SystemExit) as info:
        script.main(argv, progress=False)
    assert info.value.code == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("train_raw_ppo.py: error: ") and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize(("argv", "expected"), [
    (["--preset", "nope"], "--preset 'nope' is not allowed; choose one of"),
    (["--seed", "999"], "seed + n_envs - 1 < 1000"),
    (["--n-steps", "4", "--n-envs", "1", "--batch-size", "8"], "--batch-size 8 must be from 2 to n_steps x n_envs = 4"),
    (["--control-dt", "0.15"], "control_dt=0.15 s must be a whole multiple"),
    (["--random-path", "{\"n_waypoints\": 0}"], "random_path.n_waypoints=0"),
    (["--env-kwargs", "[1]"], "--env-kwargs '[1]' must be a JSON object"),
    (["--ppo-kwargs", "{\"gamma\": 2}"], "gamma=2 must be a number in (0, 1]"),
    (["--ppo-kwargs", "{\"n_steps\": 2}"], "unknown or not allowed key(s) ['n_steps']"),
    (["--resume"], "--resume: no checkpoint in"),
    (["--plot"], "does not exist; train first"),
])
def test_bad_options_are_one_line_errors(script, capsys, tmp_path, argv, expected):
    assert expected in _usage_error(script, capsys, ["--out", str(tmp_path / "run"), *argv])
    assert not (tmp_path / "run" / "checkpoints").exists()


def test_resume_keeps_the_runs_settings_and_a_run_is_not_overwritten(script, capsys, tmp_path):
    out = tmp_path / "run"
    (out / "checkpoints").mkdir(parents=True)
    for name in ("rl_model_8_steps.zip", "rl_model_vecnormalize_8_steps.pkl"):
        (out / "checkpoints" / name).write_bytes(b"")
    config = {**script.CONFIG_DEFAULTS, "preset": "faithful", "control_dt": 1.0}
    (out / "meta.json").write_text(json.dumps({"config": config}))
    msg = _usage_error(script, capsys, ["--out", str(out), "--resume", "--n-envs", "4"])
    assert "--n-envs 4 differs from this run's 2" in msg
    assert "already holds a run (8 env steps); pass --resume" in _usage_error(script, capsys, ["--out", str(out)])
