"""``--controller ppo-scratch[:DIR]``: a from-scratch agent (``flagellum train`` with ``task.design: burst``, no
planner inside) flying ``FlagellumSteer-v0`` one control step at a time.

The agent chooses burst commands (``agents.burst_design``); the pilot flies each one with ``agents.burst_flight``,
the code ``FlagellumBurst-v0`` flies it with, and asks the agent for the next command when it is done. Where the env
reads the head and the waypoint index from its base env, the pilot reads them from the observations, as the rule
planner does (``dead_reckon``: the head from the change of the targets relative to it; a waypoint counted reached
when the first target moves), so it needs nothing but ``predict(obs)``. Without ``DIR`` the agent shipped with the
package (``SCRATCH_AGENT_DIR``, package data) flies. ``--controller rllib:DIR`` of a ``FlagellumBurst-*`` checkpoint
(``flagellum train --engine ray``) flies through the same pilot (``agents.rllib_policy``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Protocol

import numpy as np

from agents.assets import default_turn_map, missing_turn_map_message, package_file
from agents.burst_design import (N_BURST_FEATURES, BurstHistory, BurstLimits, burst_observation, decode_burst_action,
                                 turn_seen)
from agents.burst_flight import BurstFlight
from agents.ppo_policy import TrainedAgent, load_policy
from agents.turn_map import TurnMap
from agents.turn_planner import RulePlanner, dead_reckon

#: The from-scratch agent shipped with the package (``ppo-scratch`` without a folder).
SCRATCH_AGENT_DIR = package_file("pretrained", "sac_burst_scratch")
#: A target that moves by more than this (m) between two control steps was reached (the next one is shown).
_TARGET_SWITCH_M = 1e-3


class BurstAgent(Protocol):
    """What the pilot asks of an agent: a burst action (4,) in [-1, 1] for one ``burst_observation``
    (``TrainedAgent``, a stable-baselines3 agent; ``agents.rllib_policy.RLlibAgent``, an RLlib one)."""

    def act(self, features: np.ndarray, deterministic: bool = True) -> np.ndarray: ...


def burst_agent_folder(arg: str | None) -> Path:
    """The folder of ``ppo-scratch`` (None: the shipped agent) or ``ppo-scratch:DIR`` (a folder or its
    ``model.zip``); ValueError if it holds no agent or one of another design."""
    folder = SCRATCH_AGENT_DIR if arg is None else Path(arg)
    if folder.suffix == ".zip":
        folder = folder.parent
    missing = [n for n in ("model.zip", "meta.json", "vecnormalize.pkl") if not (folder / n).is_file()]
    if missing:
        raise ValueError(f"no trained from-scratch agent at {str(folder)!r} (missing {', '.join(missing)}); train "
                         "one with 'flagellum train --config agents/configs/sac_scratch_surrogate.yml --out DIR' "
                         "and use --controller ppo-scratch:DIR")
    meta = json.loads((folder / "meta.json").read_text(encoding="utf-8"))
    if meta.get("mode") != "scratch" or meta.get("design") != "burst":
        raise ValueError(f"the agent in {str(folder)!r} has mode {meta.get('mode')!r} and design "
                         f"{meta.get('design')!r}; --controller ppo-scratch flies mode 'scratch', design 'burst' "
                         "(a residual agent flies with --controller ppo:DIR)")
    return folder


class BurstPilot:
    """A burst agent as a controller of ``FlagellumSteer-v0`` with a stable-baselines3-like ``predict`` (one env).

    agent: the trained policy (``BurstAgent``: ``load_policy``'s, or an RLlib checkpoint's for ``rllib:DIR``,
    ``agents.rllib_policy``); planner: the rule planner of the env and its turn map, used as an instrument (speed ->
    action, observation layout, timing); limits: the agent's ``BurstLimits``. The env must show two waypoints and
    the time left (``n_lookahead=2``, the default; ValueError otherwise).
    """

    def __init__(self, agent: BurstAgent, planner: RulePlanner, limits: BurstLimits) -> None:
        self.agent, self.limits = agent, limits
        self.action_of, self.layout = planner.action_of, planner.layout
        if self.layout.time_left is None or self.layout.waypoints.stop - self.layout.waypoints.start != 6:
            raise ValueError("a burst agent (ppo-scratch, or rllib:DIR of a FlagellumBurst run) reads the next two "
                             "waypoints and the time left from the observation; make FlagellumSteer-v0 with "
                             "n_lookahead=2 (the default)")
        self.flight = BurstFlight.for_planner(planner)
        self.reset()

    @classmethod
    def for_env(cls, env, agent: TrainedAgent, turn_map: TurnMap) -> BurstPilot:
        """A pilot for this env (``RulePlanner.for_env`` checks the map against the env's swimmer and speeds)."""
        limits = BurstLimits(**agent.meta.get("make_kwargs", {}).get("limits", {}))
        return cls(agent, RulePlanner.for_env(env, turn_map), limits)

    def reset(self) -> None:
        """Forget the episode (the next ``predict`` starts a new one)."""
        self._speeds = None
        self._steps = 0
        self.turns: list[dict] = []  # per burst commanded: t_c, beta, cruise (s, rad), the time it was chosen (s)

    def predict(self, observation: np.ndarray, state=None, episode_start=None, deterministic: bool = True):
        """(action, None) for one observation of ``FlagellumSteer-v0`` (D,) or a batch of one (1, D)."""
        obs = np.asarray(observation, dtype=np.float64)
        if obs.ndim == 2 and obs.shape[0] != 1:
            raise ValueError(f"a burst agent (ppo-scratch, or rllib:DIR of a FlagellumBurst run) flies one env; got a "
                             f"batch of {obs.shape[0]} observations")
        single = obs.ndim == 1
        obs = obs.reshape(-1)
        if episode_start is not None and bool(np.asarray(episode_start).reshape(-1)[0]):
            self.reset()
        rel = self.layout.read(obs)[0]
        if self._speeds is None:
            self._start(obs, rel)
        else:
            self._observe(obs, rel)
        rpm = next(self._speeds, None)
        while rpm is None:  # the command is flown (or, at the start, the heading measured): the agent decides
            self._decide(deterministic)
            rpm = next(self._speeds, None)
        action = self.action_of(rpm)
        return (action if single else np.asarray(action)[None]), None

    # --- reading the observations -------------------------------------------------------------------
    def _start(self, obs: np.ndarray, rel: np.ndarray) -> None:
        self._rel, self._index = rel, 0
        self._segment = (np.zeros(3), rel[0].copy())  # the path starts at the head's start
        self.flight.start(np.zeros(3), obs, 0, 0.0)
        self.history, self._command = BurstHistory(), None
        self._speeds = self.flight.cruise(self.flight.period_steps + 1, stop_at_waypoint=False)

    def _observe(self, obs: np.ndarray, rel: np.ndarray) -> None:
        head = dead_reckon(self.flight.head, self._rel, rel)
        target, before = head + rel[0], self.flight.head + self._rel[0]
        if float(np.linalg.norm(target - before)) > _TARGET_SWITCH_M:
            self._index += 1
            self._segment = (before, target)
        self._rel, self._steps = rel, self._steps + 1
        self.flight.observe(head, obs, self._index, self._steps * self.flight.control_dt)

    def _decide(self, deterministic: bool) -> None:
        """Close the command just flown (its burst into the history, as ``FlagellumBurst-v0.step``) and ask the
        agent for the next one."""
        heading = self.flight.heading
        if self._command is not None and self._command.t_c_s > 0.0:
            self.history.record(self._command.t_c_s / self.limits.t_c_max_s,
                                *turn_seen(self._decision_heading, heading), self._command.beta_rad)
        self._decision_heading = heading
        head = self.flight.head
        time_left = float(self.flight.obs[self.layout.time_left][0])
        features = burst_observation(head, heading, head + self._rel, self._segment, time_left, self.history)
        self._command = decode_burst_action(self.agent.act(features, deterministic), self.limits,
                                            self.flight.control_dt)
        if self._command.t_c_s > 0.0:
            self.turns.append({"t_c": self._command.t_c_s, "beta": self._command.beta_rad,
                               "cruise": self._command.cruise_s, "time_s": self.flight.time_s})
        self._speeds = self.flight.fly(self._command)


def load_burst_pilot(arg: str | None, env, preset: str) -> BurstPilot:
    """``--controller ppo-scratch[:DIR]`` for this env: the agent plus the turn map of ``preset``."""
    folder = burst_agent_folder(arg)
    tmap_file = default_turn_map(preset)
    if not tmap_file.is_file():
        raise ValueError("the from-scratch agent flies its bursts by the turn map's speeds and timing: "
                         + missing_turn_map_message(tmap_file, preset))
    agent = load_policy(folder)
    if agent.model.observation_space.shape != (N_BURST_FEATURES,):
        raise ValueError(f"the agent in {str(folder)!r} expects {agent.model.observation_space.shape} observations; "
                         f"this version's burst observation has ({N_BURST_FEATURES},): retrain it")
    return BurstPilot.for_env(env, agent, TurnMap.load(tmap_file))
