"""PPO agent: residual corrections, the config, a short training run (and resume), the pretrained
agent on a short path, determinism of predict, CLI errors."""

from __future__ import annotations

from pathlib import Path

import json
import math

import numpy as np
import pytest

from agents.path_following import env_settings, make_controller, run_episode
from agents.ppo_config import TrainConfig
from agents.ppo_policy import PRETRAINED_DIR, load_agent
from agents.residual_planner import N_FEATURES, ResidualLimits, corrected_plan, turn_features
from agents.turn_geometry import azimuth, wrap_angle
from agents.assets import default_turn_map
from agents.turn_map import TurnMap
from flagellum.cli import main
from flagellum_env.paths import path_from_waypoints
from flagellum_env.steer_env import FlagellumSteerEnv

# 2 cm ahead, then a left turn of 90 degrees and 8 cm: one planned turn
ONE_TURN = path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], name="one_turn", reach_radius_m=0.015)
SHORT_TURN = {"n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}
TINY = {"tiny": {"n_envs": 1, "n_timesteps": 3, "seed": 0, "checkpoint_every": 1, "n_steps": 3, "batch_size": 3,
                 "n_epochs": 1, "policy_kwargs": {"net_arch": [8], "log_std_init": -1.0},
                 "task": {"preset": "faithful", "limits": {"max_dtc_fraction": 0.1},
                          "curriculum": [{"name": "one", "until": 3, "random_path": SHORT_TURN}],
                          "validation": {"seeds": [5], "every": 3, "random_path": SHORT_TURN}}}}


@pytest.fixture(scope="module")
def fast_map() -> TurnMap:
    """A frozen map (rising branch to 178 deg at t_c = 8.1 s): the correction's arithmetic, not a preset's map."""
    return TurnMap.load(Path(__file__).parent / "data" / "turn_map_150rpm.json")


def _plan(theta: float = 60.0) -> dict:
    return {"t_c": 7.0, "theta_deg": theta, "burst_phase": 1.0, "predicted_miss_m": 0.004, "miss_straight_m": 0.05,
            "heading": [1.0, 0.0, 0.0], "head": [0.0, 0.0, 0.0]}


def test_zero_correction_is_the_planners_turn(fast_map):
    out = corrected_plan(_plan(), np.zeros(2), fast_map, ResidualLimits())
    assert out["t_c"] == 7.0 and out["burst_phase"] == pytest.approx(1.0)
    assert out["planned_t_c"] == 7.0 and out["residual"] == [0.0, 0.0]
    t, th = fast_map.rising_branch()
    assert out["predicted_theta_deg"] == pytest.approx(np.interp(7.0, t, th))
    assert out["predicted_azimuth"] == pytest.approx(wrap_angle(1.0 + math.radians(fast_map.psi_for(7.0))))


def test_full_correction_scales_the_burst_and_shifts_the_phase_by_the_limits(fast_map):
    lim = ResidualLimits(max_dtc_fraction=0.2, max_dphase_deg=30.0)
    out = corrected_plan(_plan(), np.array([1.0, -1.0]), fast_map, lim)
    assert out["t_c"] == pytest.approx(7.0 * 1.2)
    assert out["burst_phase"] == pytest.approx(1.0 - math.radians(30.0))
    assert out["predicted_theta_deg"] > corrected_plan(_plan(), np.zeros(2), fast_map, lim)["predicted_theta_deg"]
    # actions are clipped to [-1, 1]; beyond the rising branch the prediction is the map's maximum
    short = corrected_plan(_plan(), np.array([-5.0, 0.0]), fast_map, lim)
    assert short["t_c"] == pytest.approx(7.0 * 0.8)
    long = corrected_plan({**_plan(), "t_c": 11.0}, np.array([1.0, 0.0]), fast_map, lim)
    assert long["predicted_theta_deg"] == pytest.approx(fast_map.max_theta_deg)
    with pytest.raises(ValueError, match="two finite numbers"):
        corrected_plan(_plan(), np.array([np.nan, 0.0]), fast_map, lim)


def test_residual_limits_name_the_bad_value():
    with pytest.raises(ValueError, match="max_dtc_fraction=1.5"):
        ResidualLimits(max_dtc_fraction=1.5)


def test_turn_features_describe_the_turn_the_next_corner_and_the_last_turns_error():
    targets = np.array([[0.0, 0.1, 0.0], [0.1, 0.1, 0.0]])  # 10 cm to the left, then a right turn of 90 deg
    f = turn_features(_plan(), targets, 0.015, 1.0, 0.5, None, 2, max_theta_deg=120.0)
    assert f.shape == (N_FEATURES,) and f.dtype == np.float32
    assert f[0] == pytest.approx(0.5) and f[4] == pytest.approx(1.0)  # theta / max, distance / 0.1 m
    assert f[5] == pytest.approx(1.0) and f[6] == pytest.approx(1.0)  # 90 deg off the heading; 90 deg corner
    assert f[7] == pytest.approx(1.0) and f[10] == pytest.approx(0.4)
    assert list(f[11:]) == [0.0, 1.0, 0.0]  # no previous turn
    one = turn_features(_plan(), targets[:1], 0.015, 1.0, 0.5, None, 0, max_theta_deg=120.0)  # n_lookahead = 1
    assert one[6] == 0.0 and one[7] == 0.0
    # the previous turn was predicted as 60 deg towards azimuth 0 about +y; the heading is now +x:
    # 90 deg turned (ratio 1.5), towards the azimuth of +x about +y
    d0 = np.array([0.0, 1.0, 0.0])
    prev = {"heading": d0.tolist(), "predicted_theta_deg": 60.0, "predicted_azimuth": 0.0}
    g = turn_features(_plan(), targets, 0.015, 1.0, 0.5, prev, 1, max_theta_deg=120.0)
    assert g[11] == 1.0 and g[12] == pytest.approx(1.5)
    assert g[13] == pytest.approx(math.degrees(azimuth(np.array([1.0, 0, 0]), d0)) / 90.0)


def test_shipped_config_loads_and_held_out_seeds_are_refused(tmp_path):
    cfg = TrainConfig.from_yaml("agents/configs/ppo_residual_adaptive.yml")
    assert cfg.preset == "faithful" and cfg.n_envs == 4 and cfg.max_wall_time_s <= 7200
    assert cfg.stage_at(0).name == "single_turns" and cfg.stage_at(10_000_000).name == "broad"
    assert all(s < 1000 for s in cfg.validation.seeds)
    assert [p.name for p in cfg.validation.paths()] == [f"{'planar' if i % 2 == 0 else '3d'}_{s}" for i, s in enumerate(cfg.validation.seeds)]
    bad = json.loads(json.dumps(TINY))
    bad["tiny"]["task"]["validation"]["seeds"] = [1003]
    with pytest.raises(ValueError, match="held out"):
        TrainConfig.from_dict(bad)
    bad = json.loads(json.dumps(TINY))
    bad["tiny"]["n_stepz"] = 3
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['n_stepz'\]"):
        TrainConfig.from_dict(bad)
    bad = json.loads(json.dumps(TINY))
    bad["tiny"]["task"]["curriculum"][0]["random_path"]["max_turn_deg"] = 400
    with pytest.raises(ValueError, match="max_turn_deg=400"):
        TrainConfig.from_dict(bad)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from agents.ppo_training import train

    out = tmp_path_factory.mktemp("ppo") / "run"
    result = train(TrainConfig.from_dict(TINY), out, progress=False)
    return out, result


def test_short_training_run_writes_an_agent_that_loads(tiny_run):
    out, result = tiny_run
    assert result.decisions == 3 and not result.stopped_by_budget
    for name in ("model.zip", "vecnormalize.pkl", "meta.json", "episodes.csv", "eval/evaluations.npz",
                 "training_curve.png"):
        assert (out / name).is_file(), name
    meta = json.loads((out / "meta.json").read_text())
    assert meta["mode"] == "residual" and meta["decisions"] == 3 and meta["finished"]
    assert meta["head_rotation"] == "fixed"  # the default swimmer's reading (faithful)
    assert meta["limits"] == {"max_dtc_fraction": 0.1}
    with np.load(out / "eval" / "evaluations.npz") as d:
        assert list(d["timesteps"]) == [3]
    agent = load_agent(str(out))
    f = np.linspace(-1, 1, N_FEATURES).astype(np.float32)
    a = agent.act(f)
    assert a.shape == (2,) and np.all(np.abs(a) <= 1.0)
    assert np.array_equal(agent.act(f, deterministic=True), a)


def test_training_resumes_from_its_checkpoint_and_refuses_to_overwrite(tiny_run):
    from agents.ppo_training import latest_checkpoint, train

    out, _ = tiny_run
    with pytest.raises(ValueError, match="--resume"):
        train(TrainConfig.from_dict(TINY), out, progress=False)
    rows_before = (out / "episodes.csv").read_text().count("\n")
    more = json.loads(json.dumps(TINY))
    more["tiny"]["n_timesteps"] = 6
    more["tiny"]["task"]["curriculum"][0]["until"] = 6
    more["tiny"]["task"]["validation"]["every"] = 2  # counted in decisions since the start, not since the resume
    result = train(TrainConfig.from_dict(more), out, resume=True, progress=False)
    assert result.decisions == 6 and latest_checkpoint(out)[2] == 6
    assert (out / "episodes.csv").read_text().count("\n") > rows_before  # appended, not rewritten
    with np.load(out / "eval" / "evaluations.npz") as d:
        assert list(d["timesteps"]) == [3, 4, 6]  # the first run's evaluation is kept


def test_fine_tuning_starts_from_a_trained_agent(tiny_run, tmp_path):
    """init_from: the trained policy and statistics, a fresh decision count, the source recorded."""
    import torch
    from stable_baselines3 import PPO

    from agents.ppo_training import train

    src, _ = tiny_run
    cfg = json.loads(json.dumps(TINY))
    cfg["tiny"]["init_from"] = str(src)
    cfg["tiny"]["learning_rate"] = 0.0  # no update: the fine-tuned policy must be the source's
    result = train(TrainConfig.from_dict(cfg), tmp_path / "ft", progress=False)
    assert result.decisions == 3
    meta = json.loads((tmp_path / "ft" / "meta.json").read_text())
    assert meta["init_from"]["path"] == str(src) and meta["init_from"]["decisions"] >= 3
    a, b = (PPO.load(str(d / "model.zip"), device="cpu").policy.state_dict() for d in (src, tmp_path / "ft"))
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    cfg["tiny"]["init_from"] = str(tmp_path / "nowhere")
    with pytest.raises(ValueError, match=r"init_from=.*nowhere.*lacks \['model.zip', 'vecnormalize.pkl'\]"):
        TrainConfig.from_dict(cfg)


def test_pretrained_agent_completes_a_short_path_deterministically():
    assert (PRETRAINED_DIR / "model.zip").is_file(), "the pretrained agent is committed with the package"
    meta = json.loads((PRETRAINED_DIR / "meta.json").read_text())
    assert meta["preset"] == "faithful" and meta["planner"] == "adaptive" and meta["commit"]
    runs = []
    for _ in range(2):
        env = FlagellumSteerEnv(path=ONE_TURN, **env_settings("ppo", "faithful"))
        ctrl = make_controller("ppo", env, "faithful")
        metrics, trace = run_episode(env, ctrl, ONE_TURN)
        runs.append((metrics, trace, ctrl.turns))
    (m, trace, turns), (m2, trace2, turns2) = runs
    assert m["success"] and m["waypoints_reached"] == 2 and len(turns) >= 1
    assert all("residual" in t for t in turns)
    # deterministic=True: the same episode twice, bit for bit
    assert np.array_equal(trace.head, trace2.head) and [t["residual"] for t in turns] == [t["residual"] for t in turns2]


@pytest.mark.parametrize("argv, fragment", [
    (["train", "--config", "no/such.yml"], "cannot read the training config"),
    (["train", "--resume", "--out", "{tmp}/empty"], "no checkpoint"),
    (["train", "--preset", "paper"], "differs from the config's task.preset"),
    (["evaluate", "--paths", "square", "--controller", "rule", "--randomize", "0.9"], "a fraction in (0, 0.5]"),
    (["evaluate", "--paths", "square", "--controller", "rule", "--randomize", "0.1", "--randomize-geometry", "-1"],
     "a fraction in [0, 0.5]"),
    (["evaluate", "--paths", "square", "--controller", "rule", "--randomize-geometry", "0.1"], "needs --randomize"),
    (["evaluate", "--paths", "square", "--controller", "adaptiv"], "'adaptive'"),
])
def test_cli_errors_name_the_problem(capsys, tmp_path, argv, fragment):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1


# --- issue 24: a resume continues the same run, or refuses naming the difference ----------------------------
def test_resume_refuses_another_network_task_or_a_finished_run(tiny_run):
    from agents.ppo_training import latest_checkpoint, train

    out, _ = tiny_run
    done = latest_checkpoint(out)[2]
    meta_before = (out / "meta.json").read_text()
    for change, fragment in [(lambda c: c["tiny"]["policy_kwargs"].update(net_arch=[16]),
                              "policy_kwargs.net_arch is [8] there and [16] in this config"),
                             (lambda c: c["tiny"]["task"].update(preset="fast"), "preset is 'faithful' there and 'fast'"),
                             (lambda c: c["tiny"]["task"].update(action_cost=2.0), "action_cost is 0.0 there and 2.0")]:
        other = json.loads(json.dumps(TINY))
        other["tiny"]["n_timesteps"] = done + 3
        other["tiny"]["task"]["curriculum"][0]["until"] = done + 3
        change(other)
        with pytest.raises(ValueError, match="holds another training run") as info:
            train(TrainConfig.from_dict(other), out, resume=True, progress=False)
        assert fragment in str(info.value), str(info.value)
    finished = json.loads(json.dumps(TINY))
    finished["tiny"]["n_timesteps"] = done
    finished["tiny"]["task"]["curriculum"][0]["until"] = done
    with pytest.raises(ValueError, match=f"has done {done} decisions, n_timesteps={done}: nothing to resume"):
        train(TrainConfig.from_dict(finished), out, resume=True, progress=False)
    assert (out / "meta.json").read_text() == meta_before  # decisions not reset to 0


def test_resume_drops_what_a_killed_run_logged_after_its_checkpoint(tmp_path):
    from agents.ppo_training import EPISODE_FIELDS
    from batch.store import drop_rows_after

    f = tmp_path / "episodes.csv"
    f.write_text(",".join(EPISODE_FIELDS) + "\n" + "".join(f"{d},1.0,one,0.5,1,False,0,0.01,5,0.1,1\n"
                                                          for d in (2, 4, 6, 8)))
    drop_rows_after(f, "decisions", 4, EPISODE_FIELDS)
    assert [line.split(",")[0] for line in f.read_text().splitlines()[1:]] == ["2", "4"]
