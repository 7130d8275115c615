"""``import agents`` registers FlagellumTurn-v0 (``TurnDecisionEnv``) and its surrogate and burst twins
(``agents.registration``; the retired ``-coarse`` id only to refuse it);
``gymnasium.make`` builds each, both env checkers pass on each, bad arguments fail at construction, and the reward, ``info``, the no-turn case and seeding behave as
docs/env.md says.

Cheap on purpose (a one-turn path): with ``off_path_m = 0.02`` every episode leaves the path
during the first burst (~1.5 s of wall time per episode), which is all the checkers need; the test of the
reward uses the same episode, the others paths that need no turn.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import agents
from agents.registration import BURST_ENV_IDS, RETIRED_TURN_ENV_IDS, SURROGATE_TURN_ENV_IDS, TURN_ENV_IDS
from agents.residual_planner import N_FEATURES
from agents.turn_decision_env import TurnDecisionEnv
from flagellum_env.paths import path_from_waypoints

ROOT = Path(__file__).resolve().parents[2]
# 2 cm ahead, then a left turn of 90 degrees and 8 cm: one planned turn
ONE_TURN = path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], name="one_turn", reach_radius_m=0.015)
CHEAP = {"preset": "faithful", "paths": [ONE_TURN], "env_kwargs": {"off_path_m": 0.02}}
INFO = {"path", "is_success", "waypoints_reached", "mean_cross_track_m", "time_s", "energy_J", "buckling_events",
        "turns"}


def test_import_registers_the_turn_env_and_make_passes_arguments():
    assert agents.TURN_ENV_ID == "FlagellumTurn-v0"
    assert agents.TURN_ENV_ID in gym.registry
    env = gym.make("FlagellumTurn-v0", preset="faithful", paths=[ONE_TURN], limits={"max_dtc_fraction": 0.1},
                   action_cost=0.5)
    base = env.unwrapped
    assert isinstance(base, TurnDecisionEnv)
    assert env.spec.id == "FlagellumTurn-v0"
    assert base.observation_space == gym.spaces.Box(-10.0, 10.0, (N_FEATURES,), np.float32)
    assert base.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert base.planner.limits.max_dtc_fraction == 0.1 and base.planner.limits.max_dphase_deg == 15.0
    assert base.action_cost == 0.5 and base.paths == [ONE_TURN]
    env.close()


def test_reimporting_does_not_register_twice():
    spec = gym.registry[agents.TURN_ENV_ID]
    importlib.reload(agents)
    assert gym.registry[agents.TURN_ENV_ID] is spec


def _fresh_python(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300,
                          check=False)


def test_import_agents_is_light():
    # the registration names the entry points only: no env, physics, torch or stable-baselines3 yet
    r = _fresh_python("import sys\n"
                      "import agents\n"
                      "print(sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'stable_baselines3',"
                      " 'numba', 'scipy', 'physics') or m.startswith(('agents.', 'flagellum_env.'))))")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "['agents.registration']"


def test_import_agents_registers_the_turn_ids_with_their_classes():
    r = _fresh_python("import gymnasium as gym, agents\n"
                      "ours = {i: s for i, s in gym.registry.items() if i.startswith('Flagellum')}\n"
                      "print(sorted((i, s.entry_point, s.max_episode_steps) for i, s in ours.items() "
                      "if isinstance(s.entry_point, str)))\n"
                      "print(sorted((i, s.entry_point.args) for i, s in ours.items() if not isinstance(s.entry_point, str)))")
    assert r.returncode == 0, r.stderr
    live, retired = r.stdout.strip().splitlines()
    assert live == str(sorted((i, e, None) for i, e in {**TURN_ENV_IDS, **SURROGATE_TURN_ENV_IDS,
                                                           **BURST_ENV_IDS}.items()))
    assert retired == str(sorted((i, (i, *v)) for i, v in RETIRED_TURN_ENV_IDS.items()))
    assert sorted(TURN_ENV_IDS) == ["FlagellumTurn-fast-v0", "FlagellumTurn-v0"]
    assert sorted(RETIRED_TURN_ENV_IDS) == ["FlagellumTurn-coarse-v0"]
    assert sorted(BURST_ENV_IDS) == ["FlagellumBurst-surrogate-v0", "FlagellumBurst-v0"]


@pytest.mark.parametrize("env_id, preset", [("FlagellumTurn-v0", "faithful"), ("FlagellumTurn-fast-v0", "fast")])
def test_make_gives_the_ids_class_and_preset(env_id, preset):
    env = gym.make(env_id).unwrapped
    assert type(env).env_id == env_id and env.preset == preset
    env.close()


@pytest.mark.parametrize("env_id, preset, why", [
    ("FlagellumTurn-coarse-v0", "coarse", "slower than 'faithful' and wrong: it does not buckle")])
def test_a_retired_id_or_preset_is_refused_on_one_line_naming_the_replacement(env_id, preset, why):
    retired = (f"preset {preset!r} was retired ({why}; docs/presets.md); use 'faithful' (the default), or "
               "FlagellumTurn-surrogate-v0 / FlagellumBurst-surrogate-v0 for a cheap turn-level swimmer")
    for kwargs in ({}, CHEAP):
        with pytest.raises(ValueError) as err:
            gym.make(env_id, **kwargs)
        assert str(err.value) == f"{env_id} was retired with its preset (use FlagellumTurn-v0): {retired}"
    for make in (lambda: gym.make("FlagellumTurn-v0", preset=preset), lambda: TurnDecisionEnv(preset=preset),
                 lambda: gym.make("FlagellumBurst-v0", preset=preset)):
        with pytest.raises(ValueError) as err:
            make()
        assert str(err.value) == retired


@pytest.mark.parametrize("env_id", sorted(TURN_ENV_IDS))
def test_gymnasium_check_env_passes(env_id):
    import warnings

    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, render_mode="rgb_array", disable_env_checker=True, **CHEAP).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the checker's warnings count as failures
        check_env(env, skip_render_check=False)
    env.close()


@pytest.mark.parametrize("env_id", sorted(TURN_ENV_IDS))
def test_stable_baselines3_check_env_passes(env_id):
    import warnings

    sb3_env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, render_mode="rgb_array", **CHEAP)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_env_checker.check_env(env, warn=True)
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3
    env.close()


@pytest.mark.parametrize("module", ["agents"])
def test_without_a_prior_import_the_module_prefixed_id_works(module):
    r = _fresh_python("import gymnasium as gym, sys\n"
                      "assert 'agents' not in sys.modules and 'flagellum_env' not in sys.modules\n"
                      f"env = gym.make('{module}:FlagellumTurn-v0', preset='faithful')\n"
                      "print(type(env.unwrapped).__name__)")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "TurnDecisionEnv"


def test_the_defaults_are_the_first_agents_settings():
    """The task of the first agent (agents/configs/ppo_residual_coarse.yml until its preset was retired; the values
    as they stood there): FlagellumTurn-v0 with no argument is that agent's env at the default preset."""
    from agents.turn_decision_env import DEFAULT_ACTION_COST, DEFAULT_ENV_KWARGS, DEFAULT_RANDOM_PATH

    env = gym.make("FlagellumTurn-v0").unwrapped
    assert env.preset == "faithful"
    assert dataclasses.asdict(env.planner.limits) == {"max_dtc_fraction": 0.05, "max_dphase_deg": 15.0}
    assert env.action_cost == DEFAULT_ACTION_COST == 5.0
    assert DEFAULT_ENV_KWARGS == {"reward": {"cross_track_per_cm_s": 0.05}}
    assert env.base.config.reward.cross_track_per_cm_s == 0.05
    assert DEFAULT_RANDOM_PATH == {"n_waypoints": 3, "segment_length_m": [0.12, 0.2], "min_turn_deg": 30.0,
                                   "max_turn_deg": 150.0, "planar": [True, False]}
    assert env.paths is None and len(env._path_configs) == 2
    assert gym.make("FlagellumTurn-fast-v0").unwrapped.preset == "fast"


BAD = [({"preset": "quick"}, "preset='quick'"), ({"limits": {"max_dtc": 0.1}}, "max_dtc"),
       ({"limits": {"max_dtc_fraction": 2.0}}, "max_dtc_fraction=2.0"), ({"paths": ["random"]}, "paths\\[0\\]='random'"),
       ({"paths": "square"}, "paths='square'"), ({"paths": [[[0.01, 0.0]]]}, "paths\\[0\\]"),
       ({"random_path": {"n_waypoint": 2}}, "n_waypoint"), ({"random_path": {"n_waypoints": 0}}, "n_waypoints=0"),
       ({"env_kwargs": {"control_dt": -1.0}}, "control_dt=-1.0"), ({"env_kwargs": {"path": "square"}}, "'path'"),
       ({"turn_map": "no_such_map.json"}, "no_such_map.json"), ({"action_cost": -1.0}, "action_cost=-1.0"),
       ({"render_mode": "human"}, "render_mode='human'")]


@pytest.mark.parametrize("kwargs, match", BAD, ids=[str(k) for k, _ in BAD])
def test_bad_arguments_fail_at_construction_naming_the_value(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TurnDecisionEnv(**kwargs)


def test_bad_actions_and_reset_options_fail_naming_the_value():
    straight = path_from_waypoints([[0.004, 0.0, 0.0]], name="straight", reach_radius_m=0.002)
    env = TurnDecisionEnv(preset="faithful", paths=[straight])
    with pytest.raises(ValueError, match="'seed'"):
        env.reset(options={"seed": 1})
    with pytest.raises(ValueError, match="'random'"):
        env.reset(options={"path": "random"})
    env.reset(seed=0, options={"path": [[0.004, 0.0, 0.0]]})
    for bad in ([0.1], [np.nan, 0.0], "left"):
        with pytest.raises(ValueError, match="action="):
            env.step(bad)


def _recording(env: TurnDecisionEnv) -> list[float]:
    """The rewards of the base env's control steps, from now on."""
    rewards: list[float] = []
    step = env.base.step

    def recorded(action):
        out = step(action)
        rewards.append(out[1])
        return out

    env.base.step = recorded
    return rewards


def test_reward_is_the_base_envs_reward_over_the_steps_less_the_action_cost():
    env = TurnDecisionEnv(**CHEAP, action_cost=2.0)
    base_rewards = _recording(env)
    obs, info = env.reset(seed=0)
    assert set(info) == INFO and info["path"] == "one_turn" and info["turns"] == 0 and info["time_s"] > 0
    assert obs.dtype == np.float32 and obs in env.observation_space and obs[0] > 0  # a planned turn
    before = sum(base_rewards)  # the cruise up to the first planned turn counts in the first step
    action = np.array([0.5, -0.5], np.float32)
    obs, reward, terminated, truncated, info = env.step(action)
    assert terminated and not truncated  # off the path during the burst
    assert reward == pytest.approx(sum(base_rewards) - 2.0 * 0.5, rel=1e-12)
    assert before != 0.0 and len(base_rewards) > 1
    assert set(info) == INFO and info["turns"] == 1 and not info["is_success"]
    assert np.array_equal(obs, np.zeros(N_FEATURES, np.float32))  # no turn waiting at the end
    with pytest.raises(RuntimeError, match="reset"):
        env.step(action)


def test_a_path_without_a_planned_turn_ends_at_the_first_step_whatever_the_action():
    straight = path_from_waypoints([[0.004, 0.0, 0.0]], name="straight", reach_radius_m=0.002)
    env = TurnDecisionEnv(preset="faithful", paths=[straight], action_cost=1.0)
    base_rewards = _recording(env)
    obs, _ = env.reset(seed=0)
    assert np.array_equal(obs, np.zeros(N_FEATURES, np.float32))
    _, reward, terminated, truncated, info = env.step(np.ones(2, np.float32))
    assert terminated and not truncated and info["is_success"] and info["turns"] == 0
    assert reward == pytest.approx(sum(base_rewards), rel=1e-12)  # the action is not charged


def test_a_seed_fixes_the_drawn_paths_and_reset_without_one_draws_the_next():
    # 4-6 mm paths within 30 deg of the heading: reached (or timed out) swimming straight, so cheap
    env = TurnDecisionEnv(preset="faithful", env_kwargs={"reach_radius_m": 0.002},
                          random_path={"n_waypoints": 1, "segment_length_m": [0.004, 0.006], "max_turn_deg": 30.0})

    def episode(seed: int | None) -> dict:
        env.reset(seed=seed)
        return env.step(np.zeros(2, np.float32))[4]

    first, second = episode(1), episode(None)
    assert first != second
    assert episode(1) == first and episode(None) == second


# --- issue 24: the same validation as FlagellumSteer-v0 ------------------------------------------------------
@pytest.mark.parametrize("kwargs, match", [
    ({"paths": []}, r"paths=\[\] holds no path"),
    ({"paths": [[[0.0, 0.0, 0.0]]]}, r"paths\[0\]: path: .*zero-length segment"),
    ({"paths": ["nowhere.json"]}, r"paths\[0\]: path='nowhere.json' is neither"),
    ({"paths": ["random"]}, r"paths\[0\]='random': a fixed path is needed here"),
    ({"speed": 3}, r"unknown argument\(s\) \['speed'\] for FlagellumTurn-v0; known arguments"),
    ({"random_path": {"n_waypoints": 2, "colour": 1}}, r"random_path: unknown key\(s\) \['colour'\]"),
    ({"limits": {"max_dtc": 0.1}}, "limits: "),
])
def test_bad_arguments_are_value_errors_at_make(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("FlagellumTurn-v0", **{"preset": "faithful", **kwargs})


def test_a_render_mode_it_does_not_have_is_refused():
    # (gym.make turns render_mode="human" into a HumanRendering wrapper around rgb_array: construct directly)
    with pytest.raises(ValueError, match="render_mode='human' is not allowed"):
        TurnDecisionEnv(preset="faithful", render_mode="human")


def test_bad_reset_options_and_actions_are_refused():
    env = TurnDecisionEnv(**CHEAP)
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['goal'\]"):
        env.reset(seed=0, options={"goal": 1})
    with pytest.raises(ValueError, match="waypoints is empty"):
        env.reset(seed=0, options={"path": []})
    env.reset(seed=0)
    for bad in (np.array([np.inf, 0.0]), np.array([0.1 + 1j, 0.0]), np.array([0.1])):
        with pytest.raises(ValueError, match="must be two finite numbers in"):
            env.step(bad)
    env.close()
