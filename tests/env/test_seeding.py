"""A seeded reset followed by the same actions gives the same trajectory, bit for bit, whatever
the state of the steady-start cache."""

from __future__ import annotations

import numpy as np
import pytest

from flagellum_env import steady_start


def _trajectory(env, seed: int, n_steps: int = 8, action_seed: int = 0):
    rng = np.random.default_rng(action_seed)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(n_steps):
        a = _action(env, rng)
        obs, r, term, trunc, info = env.step(a)
        out += [obs, np.float64(r), info["head_position_m"], np.float64(info["energy_j"])]
        if term or trunc:
            break
    return out


def _action(env, rng):
    if env.config.action_type == "discrete":
        return int(rng.integers(env.action_space.n))
    return rng.uniform(-1, 1, size=1).astype(np.float32)


def _same(a, b) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))


@pytest.mark.parametrize("overrides", [
    {},
    {"action_type": "discrete"},
    {"path": "random", "random_path": {"segment_length_m": (0.003, 0.004), "n_waypoints": 2}},
    {"randomize": {"youngs_modulus": 0.1, "viscosity": 0.1, "head_radius": 0.1, "geometry": 0.05,
                   "obs_noise_std": 0.01}},
], ids=["continuous", "discrete", "random-path", "randomized"])
def test_same_seed_and_actions_give_identical_trajectories(make_env, overrides):
    a = _trajectory(make_env(**overrides), seed=3)
    b = _trajectory(make_env(**overrides), seed=3)
    assert _same(a, b)


def test_reusing_an_env_gives_the_same_trajectory_as_a_fresh_one(make_env):
    env = make_env()
    first = _trajectory(env, seed=5)
    _trajectory(env, seed=9, action_seed=1)  # something else in between
    assert _same(first, _trajectory(env, seed=5))


def test_different_seeds_give_different_random_paths(make_env):
    env = make_env(path="random")
    _, a = env.reset(seed=1)
    _, b = env.reset(seed=2)
    assert a["path_length_m"] != b["path_length_m"]


def test_trajectory_does_not_depend_on_the_cache_state(make_env, tmp_path):
    kwargs = {"cache_dir": str(tmp_path / "cache"), "settle_time_s": 4.0}
    steady_start.clear_memory_cache()
    computed = _trajectory(make_env(**kwargs), seed=0)  # empty cache: computed and stored
    assert len(list((tmp_path / "cache" / "steady_start").glob("*.npz"))) == 1
    steady_start.clear_memory_cache()
    loaded = _trajectory(make_env(**kwargs), seed=0)  # read back from disk
    in_memory = _trajectory(make_env(**kwargs), seed=0)  # from memory
    no_disk = _trajectory(make_env(disk_cache=False, settle_time_s=4.0), seed=0)
    assert _same(computed, loaded) and _same(computed, in_memory) and _same(computed, no_disk)
