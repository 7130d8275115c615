"""Rendering: RGB frames of the documented shape, the human window, and RecordVideo."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import flagellum_env  # noqa: F401


def test_rgb_array_frame_has_the_documented_shape(make_env):
    env = make_env(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([1.0], np.float32))
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # something is drawn
    small = make_env(render_mode="rgb_array", render_size=(320, 200))
    small.reset(seed=0)
    assert small.render().shape == (200, 320, 3)


def test_render_without_mode_warns_and_returns_none(make_env):
    env = make_env()
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_human_mode_runs_without_a_display(make_env):
    env = make_env(render_mode="human")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Agg cannot show windows; it says so
        env.reset(seed=0)
        env.step(np.array([0.0], np.float32))
        assert env.render() is None
    env.close()


def test_record_video_writes_a_file(small_kwargs, tmp_path):
    pytest.importorskip("moviepy")
    env = gym.make("FlagellumSteer-v0", render_mode="rgb_array", **{**small_kwargs, "max_sim_time_s": 1.0})
    env = gym.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda _: True, disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        done = term or trunc
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
