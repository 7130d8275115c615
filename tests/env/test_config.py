"""Bad arguments raise ValueError naming the argument and the allowed values."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import flagellum_env  # noqa: F401
from flagellum_env.config import SteerConfig
from flagellum_env.steer_env import FlagellumSteerEnv


@pytest.mark.parametrize("kwargs, match", [
    ({"path": "circle"}, r"path='circle' is neither one of \['square', 'random'\]"),
    ({"path": [[0.0, 0.0, 0.0]]}, "zero-length segment"),
    ({"path": 3}, "path=3 must be one of"),
    ({"preset": "slow"}, r"preset='slow' is not allowed; choose one of \['reference', 'paper', 'faithful', 'fast'\]"),
    ({"preset": "coarse"}, r"^preset 'coarse' was retired \(slower than 'faithful' and wrong: it does not buckle; "
                           r"docs/presets.md\); use 'faithful' \(the default\), or FlagellumTurn-surrogate-v0"),
    ({"control_dt": 0.0}, r"control_dt=0.0 is not allowed; allowed: a finite number > 0 and <= 600 s"),
    ({"control_dt": 0.0301}, r"control_dt=0.0301 s must be a whole multiple of the physics time step dt="),
    ({"omega_range_rpm": (60, 10)}, r"omega_range_rpm=\(60, 10\) must be \(lo, hi\) rpm with 0 < lo < hi"),
    ({"omega_range_rpm": (0, 10)}, "omega_range_rpm"),
    ({"omega_range_rpm": 10}, "omega_range_rpm"),
    ({"action_type": "box"}, r"action_type='box' is not allowed; choose one of \['continuous', 'discrete'\]"),
    ({"discrete_speeds_rpm": (60, 10)}, "discrete_speeds_rpm"),
    ({"discrete_speeds_rpm": (10,)}, "at least two"),
    ({"observation_type": "image"}, r"choose one of \['flat', 'dict'\]"),
    ({"n_lookahead": 3}, "n_lookahead=3 must be an integer from 1 to 2"),
    ({"n_shape_nodes": 1}, "n_shape_nodes"),
    ({"n_shape_nodes": 500}, "n_shape_nodes=500 must be at most"),
    ({"reach_radius_m": -0.01}, "reach_radius_m"),
    ({"max_sim_time_s": float("nan")}, "max_sim_time_s"),
    ({"off_path_m": 0}, "off_path_m"),
    ({"randomize": "yes"}, "randomize='yes' must be False, True"),
    ({"randomize": {"viscosity": 0.9}}, r"randomize.viscosity=0.9 is not allowed; allowed: a finite number >= 0 and <= 0.5"),
    ({"randomize": {"stiffness": 0.1}}, r"randomize: unknown key\(s\) \['stiffness'\]"),
    ({"reward": {"waypoint_bonus": -1}}, "reward.waypoint_bonus"),
    ({"params": {"viscosity": -1.0}}, "params: viscosity=-1.0"),
    ({"params": {"colour": 1}}, r"params: unknown field\(s\) \['colour'\]"),
    ({"numerics": {"dt": 5.0}}, "numerics: dt=5.0"),
    ({"buckling_threshold": 0.99}, "buckling_threshold"),
    ({"render_size": (10, 10)}, "render_size"),
    ({"render_mode": "window"}, r"render_mode='window' is not allowed; choose one of \[None, 'human', 'rgb_array'\]"),
    ({"speed": 3}, r"unknown argument\(s\) \['speed'\] for FlagellumSteer-v0; known arguments"),
])
def test_bad_arguments_raise_value_errors_naming_them(small_kwargs, kwargs, match):
    with pytest.raises(ValueError, match=match):
        FlagellumSteerEnv(**{**small_kwargs, **kwargs})


def test_bad_arguments_through_gymnasium_make():
    with pytest.raises(ValueError, match="action_type"):
        gym.make("FlagellumSteer-v0", action_type="joystick")


def test_bad_path_file_raises_through_the_env(tmp_path, small_kwargs):
    f = tmp_path / "bad.json"
    f.write_text('{"waypoints": [[0.01, 0, 0], [0.01, 0, 0]]}')
    with pytest.raises(ValueError, match="zero-length segment"):
        FlagellumSteerEnv(**{**small_kwargs, "path": str(f)})


def test_defaults_are_documented_values():
    cfg = SteerConfig()
    assert cfg.preset == "faithful"
    assert cfg.control_dt == 2.0
    assert cfg.action_type == "continuous"
    assert cfg.fixed_path is None  # "random"
    assert SteerConfig(path="square").fixed_path.length_m == pytest.approx(1.0)


def test_bad_reset_option_raises(make_env):
    env = make_env()
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['goal'\]"):
        env.reset(seed=0, options={"goal": 1})


# --- issue 24 -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, match", [
    ({"control_dt": 1e9}, r"control_dt=1000000000.0 is not allowed; allowed: a finite number > 0 and <= 600 s"),
    ({"path": [[1e308, 0.0, 0.0]]}, r"coordinate 1e\+308 m out of reach; allowed: coordinates within \+-100 m"),
    ({"path": [[0.01, 0.0, 0.0], [1e6, 0.0, 0.0]]}, r"waypoint 1 .* out of reach"),
])
def test_settings_that_would_exhaust_memory_or_never_end_are_refused(small_kwargs, kwargs, match):
    with pytest.raises(ValueError, match=match):
        FlagellumSteerEnv(**{**small_kwargs, **kwargs})


@pytest.mark.parametrize("action", [np.array([0.5 + 1j]), 0.5j, np.array([True]), "0.5"])
def test_a_continuous_action_must_be_a_real_number(make_env, action):
    env = make_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="must be one finite number in"):
        env.step(action)
