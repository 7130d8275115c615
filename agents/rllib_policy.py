"""Load an RLlib checkpoint (``flagellum train --engine ray``) as a controller (``--controller rllib:DIR``).

``DIR`` is a run folder (its newest checkpoint is used) or one checkpoint ``DIR/checkpoints/iter_NNNNNN``. The
checkpoint must come from a ``FlagellumTurn-*`` or a ``FlagellumBurst-*`` env (``rllib_controller_env_ids``):

- ``FlagellumTurn-*``: its policy is a residual agent that corrects the planner's turns, and it flies exactly as
  the ``ppo`` controller does (``agents.ppo_policy``): the planner named by the env's ``planner`` argument
  (default ``rule``) with the turn map of the preset flown, corrected by the policy within the env's ``limits``;
- ``FlagellumBurst-*``: its policy chooses burst commands with no planner (``agents.burst_design``), and it flies
  exactly as the ``ppo-scratch`` controller does: ``agents.burst_pilot.BurstPilot`` with the turn map of the
  preset flown and the env's ``limits`` (``burst_limits``).

The action is deterministic: the mean of the policy's action distribution (``to_deterministic``), clipped to
[-1, 1], after RLlib's MeanStdFilter when the run normalised its observations (its statistics are read from the
checkpoint, never updated here).

Loading needs Ray's Python package (``RLModule.from_checkpoint``) but no running Ray: nothing here calls
``ray.init``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.assets import default_turn_map, missing_turn_map_message
from agents.burst_pilot import BurstPilot
from agents.ppo_policy import AdaptivePPOController, PPOController
from agents.residual_planner import ResidualLimits, base_planner
from agents.rllib_config import CHECKPOINT_PREFIX, INFO_FILE, rllib_controller_env_ids
from agents.turn_map import TurnMap

#: Where RLlib's checkpoint keeps the policy and the observation filter.
MODULE_SUBDIR = Path("learner_group", "learner", "rl_module", "default_policy")
FILTER_SUBDIR = Path("env_runner", "env_to_module_connector", "MeanStdFilter")


def checkpoint_folder(arg: str) -> Path:
    """The checkpoint ``arg`` names: itself, or a run folder's newest; ValueError naming ``arg`` otherwise."""
    import json

    folder = Path(arg)
    if (folder / INFO_FILE).is_file():
        return folder
    found = [p for p in (folder / "checkpoints").glob(f"{CHECKPOINT_PREFIX}*") if (p / INFO_FILE).is_file()]
    if not found:
        raise ValueError(f"controller 'rllib:{arg}': no RLlib checkpoint there (no {INFO_FILE}, no "
                         f"checkpoints/iter_*/{INFO_FILE}); allowed: a folder written by 'flagellum train --engine "
                         "ray --out DIR' or one of its checkpoints")
    return max(found, key=lambda p: json.loads((p / INFO_FILE).read_text(encoding="utf-8"))["iteration"])


@dataclass
class RLlibAgent:
    """An RLlib policy with its observation filter; ``act(features, deterministic)`` like ``TrainedAgent``."""

    module: Any
    obs_filter: Any
    info: dict[str, Any]
    folder: Path

    def act(self, features: np.ndarray, deterministic: bool = True) -> np.ndarray:
        """The action in [-1, 1] for one feature vector: a residual agent's (2,) for the planner's turn features, a
        burst agent's (4,) for ``burst_observation``'s."""
        import torch

        f = np.asarray(features, dtype=np.float32).reshape(1, -1)
        if self.obs_filter is not None:
            f = self.obs_filter(f, update=False)
        with torch.no_grad():
            out = self.module.forward_inference({"obs": torch.as_tensor(f, dtype=torch.float32)})
            dist = self.module.get_inference_action_dist_cls().from_logits(out["action_dist_inputs"])
            if deterministic:
                dist = dist.to_deterministic()
            action = dist.sample()
        return np.clip(np.asarray(action, dtype=np.float64).reshape(-1), -1.0, 1.0)


def _load_filter(folder: Path, shape: tuple[int, ...]):
    """RLlib's MeanStdFilter of the checkpoint as a callable (``ray.rllib.utils.filter.MeanStdFilter`` with its
    running statistics), or None when the run did not normalise."""
    import pickle

    from ray.rllib.utils.filter import MeanStdFilter, RunningStat

    state_file = folder / FILTER_SUBDIR / "state.pkl"
    if not state_file.is_file():
        return None
    with open(state_file, "rb") as f:
        state = pickle.load(f)[None]  # one agent (no multi-agent key)
    filt = MeanStdFilter(np.array(shape), demean=state["de_mean_to_zero"], destd=state["de_std_to_one"],
                         clip=state["clip_by_value"])
    filt.running_stats = RunningStat.from_state(state["running_stats"][0])
    return filt


def load_rllib_agent(arg: str, n_features: int | None = None, features: str = "the expected observations"
                     ) -> RLlibAgent:
    """The agent in checkpoint ``arg`` (``checkpoint_folder``); ValueError naming both sides when it was not
    trained on one of ``rllib_controller_env_ids`` (a FlagellumTurn or FlagellumBurst env) or its observations are
    not ``(n_features,)`` (``features`` says what they should be, e.g. "the rule planner's turn features")."""
    import json

    from ray.rllib.core.rl_module.rl_module import RLModule

    folder = checkpoint_folder(arg)
    info = json.loads((folder / INFO_FILE).read_text(encoding="utf-8"))
    allowed = rllib_controller_env_ids()
    if info.get("env_id") not in allowed:
        raise ValueError(f"controller 'rllib:{arg}': the checkpoint was trained on {info.get('env_id')!r}; a "
                         "controller corrects the planner's turns (FlagellumTurn) or chooses bursts (FlagellumBurst): "
                         f"allowed: a checkpoint of one of {allowed}")
    shape = tuple(info["observation_shape"])
    if n_features is not None and shape != (n_features,):
        raise ValueError(f"controller 'rllib:{arg}': the checkpoint was trained on {info['env_id']} with "
                         f"observations {shape}; {features} are ({n_features},): retrain it")
    # RLlib 2.60 warns about its own deprecated RLModule(config=...) here
    logs = [logging.getLogger(name) for name in ("ray.rllib", "ray._common.deprecation")]
    levels = [log.level for log in logs]
    for log in logs:
        log.setLevel(logging.ERROR)
    try:
        module = RLModule.from_checkpoint(str((folder / MODULE_SUBDIR).resolve()))
    finally:
        for log, level in zip(logs, levels, strict=True):
            log.setLevel(level)
    module.eval()
    if tuple(module.observation_space.shape) != shape:
        raise ValueError(f"controller 'rllib:{arg}': the policy takes observations {module.observation_space.shape}, "
                         f"its {INFO_FILE} says {shape}: the checkpoint is inconsistent")
    return RLlibAgent(module, _load_filter(folder, shape) if info.get("normalize_obs", True) else None, info, folder)


def load_rllib_controller(arg: str, env, preset: str) -> PPOController | AdaptivePPOController | BurstPilot:
    """``--controller rllib:DIR`` for this env (module docstring): a FlagellumTurn checkpoint as the ``ppo``
    controller (its planner and limits), a FlagellumBurst one as a ``BurstPilot`` (its limits); both with the turn
    map of ``preset``."""
    import json

    from agents.burst_design import N_BURST_FEATURES, burst_limits
    from agents.registration import BURST_ENV_IDS
    from agents.turn_decision_env import residual_limits
    from agents.turn_planner import RulePlanner

    folder = checkpoint_folder(arg)
    info = json.loads((folder / INFO_FILE).read_text(encoding="utf-8"))
    env_kwargs = info.get("env_kwargs", {})
    if info.get("env_id") in BURST_ENV_IDS:
        agent = load_rllib_agent(arg, N_BURST_FEATURES, "this version's burst observations")
        tmap = _turn_map(preset, "the RLlib burst agent flies its bursts by the turn map's speeds and timing: ")
        return BurstPilot(agent, RulePlanner.for_env(env, tmap), burst_limits(env_kwargs.get("limits")))
    planner = env_kwargs.get("planner", "rule")
    kind, planner_cls, config = base_planner(planner)
    agent = load_rllib_agent(arg, planner_cls.n_features, f"the {planner} planner's turn features")
    tmap = _turn_map(preset, "the RLlib agent corrects the turn planner, which needs a turn map: ")
    limits = residual_limits(env_kwargs.get("limits")) or ResidualLimits()
    cls = AdaptivePPOController if kind == "adaptive" else PPOController
    ctrl = cls.for_env(env, tmap, config, limits=limits)
    ctrl.drive_with(agent)
    return ctrl


def _turn_map(preset: str, why: str) -> TurnMap:
    """The turn map of ``preset``; ValueError (``why`` and ``missing_turn_map_message``) when it is missing."""
    tmap_file = default_turn_map(preset)
    if not tmap_file.is_file():
        raise ValueError(why + missing_turn_map_message(tmap_file, preset))
    return TurnMap.load(tmap_file)
