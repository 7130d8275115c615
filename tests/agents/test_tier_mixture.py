"""agents/tier_mixture.py: episodes drawn from two twin envs (the rod's fine-tune with surrogate episodes in the mix),
and ``task.cheap_fraction`` building it for training."""

from __future__ import annotations

import numpy as np
import pytest

from agents.ppo_config import TrainConfig
from agents.surrogate_burst_env import SurrogateBurstEnv
from agents.tier_mixture import TierMixture

PATHS = {"n_waypoints": 1, "segment_length_m": [0.05, 0.08], "min_turn_deg": 30.0, "max_turn_deg": 90.0}
NOISE = {"direction_deg": 30.0, "turn_scale": 0.15}


def _mixture(fraction: float) -> TierMixture:
    # two surrogates stand for the rod and its twin: the mixture only needs equal spaces and info keys
    return TierMixture(SurrogateBurstEnv(random_path=PATHS), SurrogateBurstEnv(random_path=PATHS, map_noise=NOISE),
                       fraction)


def _episodes(env: TierMixture, n: int, seed: int) -> list[tuple[bool, bytes]]:
    out = []
    for k in range(n):
        obs, info = env.reset(seed=seed if k == 0 else None)
        assert info["cheap"] == (env.playing is env.cheap)
        _, _, _, _, info = env.step(np.array([0.5, 1.0, 0.0, 0.0], dtype=np.float32))
        assert info["cheap"] == (env.playing is env.cheap)
        out.append((info["cheap"], obs.tobytes()))
    return out


def test_the_cheap_fraction_of_episodes_is_played_in_the_cheap_twin():
    runs = _episodes(_mixture(0.3), 400, seed=7)
    share = np.mean([cheap for cheap, _ in runs])
    assert abs(share - 0.3) < 4 * np.sqrt(0.3 * 0.7 / 400)  # binomial, 4 sigma
    assert not any(c for c, _ in _episodes(_mixture(0.0), 50, seed=7))
    assert all(c for c, _ in _episodes(_mixture(1.0), 50, seed=7))


def test_a_seed_repeats_the_episodes_and_the_twins_are_seeded_apart():
    assert _episodes(_mixture(0.5), 30, seed=3) == _episodes(_mixture(0.5), 30, seed=3)
    env = _mixture(0.5)
    env.reset(seed=3)
    assert not np.array_equal(env.accurate.path.waypoints, env.cheap.path.waypoints)


def test_the_curriculum_reaches_both_twins_and_bad_arguments_are_refused():
    env = _mixture(0.5)
    env.set_random_path({**PATHS, "n_waypoints": 3})
    for _ in range(6):
        env.reset()
        assert env.playing.path.n_waypoints == 3
    with pytest.raises(ValueError, match=r"cheap_fraction=1.5 is not allowed; give a fraction in \[0, 1\]"):
        TierMixture(SurrogateBurstEnv(), SurrogateBurstEnv(), 1.5)


def test_training_mixes_surrogate_episodes_into_the_rods():
    from agents.ppo_training import _make_env, agent_env
    from agents.burst_decision_env import BurstDecisionEnv

    doc = {"fine": {"algorithm": "sac", "n_envs": 1, "n_timesteps": 8, "seed": 0, "checkpoint_every": 8,
                    "task": {"design": "burst", "tier": "physics", "cheap_fraction": 0.5, "map_noise": NOISE,
                             "curriculum": [{"name": "one", "until": 8, "random_path": PATHS}],
                             "validation": {"seeds": [5], "every": 8, "random_path": PATHS}}}}
    config = TrainConfig.from_dict(doc)
    assert config.cheap_fraction == 0.5
    env_id, make_kwargs = agent_env(config)
    assert env_id == "FlagellumBurst-v0" and "map_noise" not in make_kwargs  # the agent's env: the rod
    env = _make_env(config, 0)()
    assert isinstance(env, TierMixture) and isinstance(env.accurate, BurstDecisionEnv)
    assert env.cheap.map_noise is not None
    doc["fine"]["task"].pop("cheap_fraction")
    with pytest.raises(ValueError, match="or tier 'physics' with cheap_fraction > 0"):
        TrainConfig.from_dict(doc)
