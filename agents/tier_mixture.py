"""Episodes drawn from two twin envs: a fine-tune on the rod with cheap episodes still in the mix.

``TierMixture`` holds an accurate env and a cheap twin of it (the same observation and action spaces and ``info``
keys: ``FlagellumBurst-v0`` and ``FlagellumBurst-surrogate-v0``) and plays each episode in the cheap one with
probability ``cheap_fraction``, drawn at ``reset`` from its own generator. An agent fine-tuned on the rod so keeps
seeing the broad (and cheap) episodes it learned on, at a cost per cheap episode of ~1 ms against ~10-40 CPU s
(``flagellum train``'s ``task.cheap_fraction``, docs/rl.md).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

#: Added to the seed of the first reset for the cheap twin, so that its swimmers and paths are not the rod's.
CHEAP_SEED_OFFSET = 1_000_003


class TierMixture(gym.Env):
    """``accurate`` or, with probability ``cheap_fraction`` per episode, ``cheap`` (spaces must match; ValueError
    otherwise or if ``cheap_fraction`` is not in [0, 1]). ``info["cheap"]`` says which one played the episode."""

    def __init__(self, accurate: gym.Env, cheap: gym.Env, cheap_fraction: float) -> None:
        if not 0.0 <= float(cheap_fraction) <= 1.0:
            raise ValueError(f"cheap_fraction={cheap_fraction!r} is not allowed; give a fraction in [0, 1]")
        if accurate.observation_space != cheap.observation_space or accurate.action_space != cheap.action_space:
            raise ValueError("the cheap env's spaces differ from the accurate env's: "
                             f"{cheap.observation_space}, {cheap.action_space} against "
                             f"{accurate.observation_space}, {accurate.action_space}")
        self.accurate, self.cheap, self.cheap_fraction = accurate, cheap, float(cheap_fraction)
        self.observation_space, self.action_space = accurate.observation_space, accurate.action_space
        self.metadata = accurate.metadata
        self.playing: gym.Env = accurate

    def _seed_of(self, env: gym.Env, seed: int) -> int:
        return seed + CHEAP_SEED_OFFSET if env is self.cheap else seed

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.playing = self.cheap if self.np_random.random() < self.cheap_fraction else self.accurate
        if seed is None:
            obs, info = self.playing.reset(options=options)
        else:  # a seed seeds both twins (the one not playing now through a reset of its own)
            other = self.accurate if self.playing is self.cheap else self.cheap
            other.reset(seed=self._seed_of(other, seed))
            obs, info = self.playing.reset(seed=self._seed_of(self.playing, seed), options=options)
        return obs, {**info, "cheap": self.playing is self.cheap}

    def set_random_path(self, random_path: Any) -> None:
        """The curriculum's random paths (``TurnEpisodes.set_random_path``) for both twins."""
        self.accurate.set_random_path(random_path)
        self.cheap.set_random_path(random_path)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.playing.step(action)
        return obs, reward, terminated, truncated, {**info, "cheap": self.playing is self.cheap}

    def close(self) -> None:
        self.accurate.close()
        self.cheap.close()
