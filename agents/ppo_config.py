"""Training configuration of the PPO agents: a YAML file in the style of rl-zoo3, validated.

The file has one top-level key, the agent's name, holding the stable-baselines3 PPO
hyperparameters (flat, as in rl-zoo3's ``hyperparams/ppo.yml``) and a ``task`` section::

    ppo_residual:
      policy: MlpPolicy
      n_envs: 2                 # SubprocVecEnv workers
      n_timesteps: 640          # turn decisions (steps of TurnDecisionEnv)
      max_wall_time_s: 5400     # stop (and save) after this much training wall time
      seed: 0
      init_from: null           # or a trained agent's folder (model.zip, vecnormalize.pkl): fine-tune it
      checkpoint_every: 32      # decisions
      normalize: {norm_obs: true, norm_reward: true, clip_obs: 10.0}
      n_steps: 16               # per env and rollout
      batch_size: 32
      ...                       # any other PPO argument (PPO_KEYS)
      policy_kwargs: {net_arch: [64, 64], log_std_init: -1.0}
      task:
        design: residual        # or burst: a burst command per decision, no planner (agents.burst_design)
        tier: physics           # or surrogate: the turn-level surrogate of the default preset's map
        preset: faithful        # fast, reference or paper; the retired coarse is refused
        turn_map: null          # null: the preset's turn map (agents.assets.default_turn_map)
        planner: rule            # the planner corrected: rule or adaptive (agents.residual_planner)
        limits: {max_dtc_fraction: 0.05, max_dphase_deg: 15}   # design burst: BurstLimits fields (t_c_max_s,
                                # cruise_min_s, cruise_max_s, burst_end: time or ratio)
        action_cost: 5.0        # reward - action_cost |a|^2 per decision
        env_kwargs: {randomize: true, reward: {cross_track_per_cm_s: 0.05}}
        map_noise: null         # design burst, tier surrogate only: {direction_deg: D, turn_scale: S}, the map
                                # randomised per episode (FlagellumBurst-surrogate-v0's map_noise)
        cheap_fraction: 0.0     # design burst, tier physics only: this fraction of the episodes is played in the
                                # surrogate (agents.tier_mixture; map_noise, if given, applies to those)
        curriculum:             # stages by decisions done; random_path = RandomPathConfig fields
          - {name: single_turns, until: 160, random_path: {n_waypoints: 2, ...}}
          - {name: eval_like, until: 480, random_path: {...}}
        validation: {seeds: [900, 901], every: 160, random_path: {...}}

``TrainConfig.from_yaml`` raises ``ValueError`` naming the file, the key and what is allowed.
Training paths are drawn from the envs' generators (seeded by ``seed``); validation paths from
``numpy.random.default_rng(s)`` for ``s`` in ``validation.seeds``, which must be below 1000:
seeds from 1000 on are the held-out evaluation paths (``scripts/make_eval_paths.py``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.burst_design import BurstLimits, parse_map_noise
from agents.residual_planner import ResidualLimits, base_planner
from flagellum_env.paths import RandomPathConfig, WaypointPath, random_path
from physics.presets import DEFAULT_PRESET, check_preset
from physics.validation import require_finite

#: PPO constructor arguments a config may set (stable-baselines3 2.x).
PPO_KEYS = ("learning_rate", "n_steps", "batch_size", "n_epochs", "gamma", "gae_lambda", "clip_range", "ent_coef",
            "vf_coef", "max_grad_norm", "target_kl", "policy_kwargs", "normalize_advantage", "use_sde")
#: SAC constructor arguments a config may set (stable-baselines3 2.x); ``ent_coef`` may also be "auto".
SAC_KEYS = ("learning_rate", "buffer_size", "learning_starts", "batch_size", "tau", "gamma", "train_freq",
            "gradient_steps", "ent_coef", "policy_kwargs", "use_sde")
#: ``algorithm``: stable-baselines3's PPO (on-policy) or SAC (off-policy: a replay buffer, checkpointed with the
#: model), and the constructor arguments each takes.
ALGORITHM_KEYS = {"ppo": PPO_KEYS, "sac": SAC_KEYS}
NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma")
TOP_KEYS = ("algorithm", "policy", "n_envs", "n_timesteps", "max_wall_time_s", "seed", "checkpoint_every",
            "normalize", "task", "init_from", *dict.fromkeys(PPO_KEYS + SAC_KEYS))
TASK_KEYS = ("design", "tier", "preset", "turn_map", "planner", "limits", "action_cost", "env_kwargs", "map_noise",
             "cheap_fraction", "curriculum", "validation")
#: ``task.design``: what an action is. "residual": a correction of the planner's turn (``FlagellumTurn-*``);
#: "burst": a burst command with no planner (``FlagellumBurst-*``, ``agents.burst_design``).
DESIGNS = ("residual", "burst")
#: ``task.tier``: the swimmer trained on. "physics": the rod at ``task.preset``; "surrogate": the turn-level
#: surrogate of the default preset's map (``agents.surrogate_swimmer``).
TIERS = ("physics", "surrogate")
#: Seeds from here on are the held-out evaluation paths.
HELD_OUT_SEED0 = 1000


@dataclass(frozen=True)
class CurriculumStage:
    """Train on ``random_path`` paths until ``until`` decisions have been made in all."""

    name: str
    until: int
    random_path: Mapping[str, Any]


@dataclass(frozen=True)
class ValidationConfig:
    """Fixed validation paths (seeds < 1000) evaluated every ``every`` decisions."""

    seeds: tuple[int, ...]
    every: int
    random_path: Mapping[str, Any]

    def paths(self) -> list[WaypointPath]:
        """One path per seed; ``planar`` may be a list, cycled over the seeds."""
        rp = dict(self.random_path)
        planar = rp.pop("planar", True)
        cycle = planar if isinstance(planar, (list, tuple)) else [planar]
        out = []
        for k, s in enumerate(self.seeds):
            cfg = RandomPathConfig(**{**rp, "planar": bool(cycle[k % len(cycle)])})
            p = random_path(np.random.default_rng(s), cfg)
            out.append(WaypointPath(f"{'planar' if cfg.planar else '3d'}_{s}", p.waypoints, p.reach_radius_m))
        return out


@dataclass(frozen=True)
class TrainConfig:
    """A validated training configuration (module docstring)."""

    name: str
    n_timesteps: int
    curriculum: tuple[CurriculumStage, ...]
    validation: ValidationConfig
    policy: str = "MlpPolicy"
    n_envs: int = 2
    max_wall_time_s: float | None = None
    seed: int = 0
    checkpoint_every: int = 32
    normalize: Mapping[str, Any] = field(default_factory=lambda: {"norm_obs": True, "norm_reward": True})
    #: the algorithm's constructor arguments (``ALGORITHM_KEYS[algorithm]``)
    hyperparameters: Mapping[str, Any] = field(default_factory=dict)
    preset: str = DEFAULT_PRESET
    turn_map: str | None = None
    limits: Mapping[str, Any] = field(default_factory=dict)
    action_cost: float = 0.0
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    init_from: str | None = None
    source: str = "<dict>"
    planner: str = "rule"
    design: str = "residual"
    tier: str = "physics"
    algorithm: str = "ppo"
    #: ``FlagellumBurst-surrogate-v0``'s ``map_noise`` (design burst; tier surrogate, or tier physics with
    #: ``cheap_fraction`` > 0: the cheap episodes' map); None: off
    map_noise: Mapping[str, Any] | None = None
    #: the fraction of episodes played in the surrogate (design burst, tier physics: ``agents.tier_mixture``)
    cheap_fraction: float = 0.0

    def stage_at(self, decisions: int) -> CurriculumStage:
        """The curriculum stage in force after ``decisions`` decisions."""
        for st in self.curriculum:
            if decisions < st.until:
                return st
        return self.curriculum[-1]

    @classmethod
    def from_yaml(cls, path: str | Path) -> TrainConfig:
        """Read and validate a config file (module docstring)."""
        path = Path(path)
        try:
            doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as exc:
            raise ValueError(f"cannot read the training config {str(path)!r}: {exc}") from None
        return cls.from_dict(doc, source=str(path))

    @classmethod
    def from_dict(cls, doc: Any, source: str = "<dict>") -> TrainConfig:
        where = f"training config {source!r}"
        if not isinstance(doc, Mapping) or len(doc) != 1:
            raise ValueError(f"{where}: must hold exactly one top-level key, the agent's name")
        (name, body), = doc.items()
        if not isinstance(body, Mapping):
            raise ValueError(f"{where}: {name!r} must be a mapping of settings")
        _only(body, TOP_KEYS, f"{where}: {name}")
        task = body.get("task")
        if not isinstance(task, Mapping):
            raise ValueError(f"{where}: {name}.task is required (a mapping with {list(TASK_KEYS)})")
        _only(task, TASK_KEYS, f"{where}: {name}.task")
        n_timesteps = _int(body.get("n_timesteps"), f"{where}: {name}.n_timesteps", 1)
        stages = task.get("curriculum")
        if not isinstance(stages, list) or not stages:
            raise ValueError(f"{where}: {name}.task.curriculum must be a non-empty list of stages")
        curriculum, last = [], 0
        for i, st in enumerate(stages):
            label = f"{where}: {name}.task.curriculum[{i}]"
            if not isinstance(st, Mapping):
                raise ValueError(f"{label} must be a mapping with name, until, random_path")
            _only(st, ("name", "until", "random_path"), label)
            until = _int(st.get("until"), f"{label}.until", last + 1)
            rp = _random_path(st.get("random_path"), f"{label}.random_path")
            curriculum.append(CurriculumStage(str(st.get("name", f"stage{i}")), until, rp))
            last = until
        val = task.get("validation")
        if not isinstance(val, Mapping):
            raise ValueError(f"{where}: {name}.task.validation is required (seeds, every, random_path)")
        _only(val, ("seeds", "every", "random_path"), f"{where}: {name}.task.validation")
        seeds = val.get("seeds")
        if not isinstance(seeds, list) or not seeds or not all(
                isinstance(s, int) and not isinstance(s, bool) and 0 <= s < HELD_OUT_SEED0 for s in seeds):
            raise ValueError(f"{where}: {name}.task.validation.seeds={seeds!r} must be a non-empty list of integers "
                             f"from 0 to {HELD_OUT_SEED0 - 1} (seeds from {HELD_OUT_SEED0} on are held out)")
        validation = ValidationConfig(tuple(seeds), _int(val.get("every"), f"{where}: {name}.task.validation.every", 1),
                                      _random_path(val.get("random_path"), f"{where}: {name}.task.validation.random_path"))
        preset = task.get("preset", DEFAULT_PRESET)
        try:
            check_preset(preset, f"{name}.task.preset")
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        design, tier = task.get("design", "residual"), task.get("tier", "physics")
        for key, value, allowed in (("design", design, DESIGNS), ("tier", tier, TIERS)):
            if value not in allowed:
                raise ValueError(f"{where}: {name}.task.{key}={value!r} is not allowed; allowed: {list(allowed)}")
        if tier == "surrogate" and preset != DEFAULT_PRESET:
            raise ValueError(f"{where}: {name}.task.preset={preset!r} is not allowed with tier 'surrogate'; allowed: "
                             f"{DEFAULT_PRESET!r} (the map the surrogate replays)")
        planner = task.get("planner", "rule")
        if design == "burst" and ("planner" in task or "action_cost" in task):
            raise ValueError(f"{where}: {name}.task: design 'burst' has no planner and no action_cost; remove "
                             f"{[k for k in ('planner', 'action_cost') if k in task]}")
        try:
            base_planner(planner)
        except ValueError as exc:
            raise ValueError(f"{where}: {name}.task.{exc}") from None
        limits = dict(task.get("limits") or {})
        try:
            if design == "burst":
                BurstLimits(**limits)
            else:
                ResidualLimits(**limits)
        except TypeError as exc:
            raise ValueError(f"{where}: {name}.task.limits: {exc}") from None
        except ValueError as exc:
            raise ValueError(f"{where}: {name}.task.limits: {exc}") from None
        cheap = task.get("cheap_fraction", 0.0)
        if "cheap_fraction" in task:
            if design != "burst" or tier != "physics":
                raise ValueError(f"{where}: {name}.task.cheap_fraction is only allowed with design 'burst' and tier "
                                 f"'physics' (surrogate episodes mixed into the rod's); this task has design "
                                 f"{design!r}, tier {tier!r}")
            if isinstance(cheap, bool) or not isinstance(cheap, (int, float)) or not 0.0 <= cheap < 1.0:
                raise ValueError(f"{where}: {name}.task.cheap_fraction={cheap!r} is not allowed; give a fraction in "
                                 "[0, 1)")
        map_noise = task.get("map_noise")
        if map_noise is not None:
            if design != "burst" or not (tier == "surrogate" or cheap > 0.0):
                raise ValueError(f"{where}: {name}.task.map_noise is only allowed with design 'burst' and tier "
                                 f"'surrogate' (FlagellumBurst-surrogate-v0), or tier 'physics' with cheap_fraction "
                                 f"> 0 (its surrogate episodes); this task has design {design!r}, tier {tier!r}")
            try:
                parse_map_noise(map_noise)
            except ValueError as exc:
                raise ValueError(f"{where}: {name}.task.{exc}") from None
            map_noise = dict(map_noise)
        cost = require_finite(f"{where}: {name}.task.action_cost", task.get("action_cost", 0.0), 0.0)
        normalize = dict(body.get("normalize") or {"norm_obs": True, "norm_reward": True})
        _only(normalize, NORMALIZE_KEYS, f"{where}: {name}.normalize")
        wall = body.get("max_wall_time_s")
        if wall is not None and not (isinstance(wall, (int, float)) and not isinstance(wall, bool)
                                     and math.isfinite(wall) and wall > 0):
            raise ValueError(f"{where}: {name}.max_wall_time_s={wall!r} must be a number of seconds > 0 or null")
        init_from = body.get("init_from")
        if init_from is not None:
            missing = [f for f in ("model.zip", "vecnormalize.pkl") if not (Path(str(init_from)) / f).is_file()]
            if missing:
                raise ValueError(f"{where}: {name}.init_from={init_from!r} must be a trained agent's folder; it lacks "
                                 f"{missing}")
            init_from = str(init_from)
        policy = body.get("policy", "MlpPolicy")
        if policy != "MlpPolicy":
            raise ValueError(f"{where}: {name}.policy={policy!r} is not allowed; the turn features are a flat "
                             "vector: use MlpPolicy")
        algorithm = body.get("algorithm", "ppo")
        if algorithm not in ALGORITHM_KEYS:
            raise ValueError(f"{where}: {name}.algorithm={algorithm!r} is not allowed; allowed: {list(ALGORITHM_KEYS)}")
        keys = ALGORITHM_KEYS[algorithm]
        foreign = sorted(k for k in body if k in PPO_KEYS + SAC_KEYS and k not in keys)
        if foreign:
            raise ValueError(f"{where}: {name}: {foreign} are not {algorithm} arguments; allowed: {list(keys)}")
        for key in keys:
            if key in body:
                _check_ppo_value(key, body[key], f"{where}: {name}.{key}")
        return cls(name=str(name), n_timesteps=n_timesteps, curriculum=tuple(curriculum), validation=validation,
                   policy=policy, n_envs=_int(body.get("n_envs", 2), f"{where}: {name}.n_envs", 1),
                   max_wall_time_s=None if wall is None else float(wall),
                   seed=_int(body.get("seed", 0), f"{where}: {name}.seed", 0),
                   checkpoint_every=_int(body.get("checkpoint_every", 32), f"{where}: {name}.checkpoint_every", 1),
                   normalize=normalize, hyperparameters={k: body[k] for k in keys if k in body}, preset=preset,
                   turn_map=task.get("turn_map"), limits=limits, action_cost=cost,
                   env_kwargs=dict(task.get("env_kwargs") or {}), init_from=init_from,
                   source=source, planner=planner, design=design, tier=tier, algorithm=algorithm,
                   map_noise=map_noise, cheap_fraction=float(cheap))


def _only(d: Mapping[str, Any], allowed: tuple[str, ...], where: str) -> None:
    unknown = sorted(set(d) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed: {list(allowed)}")


#: What each numeric PPO setting may be: (kind, lower bound, lower bound included, upper bound or None).
_PPO_RANGES: dict[str, tuple[str, float, bool, float | None]] = {
    "learning_rate": ("number", 0.0, True, None), "n_steps": ("integer", 1, True, None),
    "batch_size": ("integer", 1, True, None), "n_epochs": ("integer", 1, True, None),
    "gamma": ("number", 0.0, True, 1.0), "gae_lambda": ("number", 0.0, True, 1.0),
    "clip_range": ("number", 0.0, False, None), "ent_coef": ("number", 0.0, True, None),
    "vf_coef": ("number", 0.0, True, None), "max_grad_norm": ("number", 0.0, False, None),
    "target_kl": ("number", 0.0, False, None), "buffer_size": ("integer", 1, True, None),
    "learning_starts": ("integer", 0, True, None), "tau": ("number", 0.0, False, 1.0),
    "train_freq": ("integer", 1, True, None), "gradient_steps": ("integer", 1, True, None)}


def _check_ppo_value(key: str, v: Any, where: str) -> None:
    """ValueError naming the file and key when a PPO setting is out of range (stable-baselines3 would fail later
    with a message that names neither)."""
    if key in ("normalize_advantage", "use_sde"):
        if not isinstance(v, bool):
            raise ValueError(f"{where}={v!r} is not allowed; allowed: true or false")
        return
    if key == "policy_kwargs":
        if v is not None and not isinstance(v, Mapping):
            raise ValueError(f"{where}={v!r} is not allowed; allowed: a mapping of policy arguments or null")
        _check_policy_kwargs(v or {}, where)
        return
    kind, lo, lo_ok, hi = _PPO_RANGES[key]
    if (key == "target_kl" and v is None) or (key == "ent_coef" and v == "auto"):
        return
    ok_type = (isinstance(v, int) if kind == "integer" else isinstance(v, (int, float))) and not isinstance(v, bool)
    if not ok_type or not math.isfinite(v) or (v < lo if lo_ok else v <= lo) or (hi is not None and v > hi):
        bound = f"{'>=' if lo_ok else '>'} {lo:g}" + (f" and <= {hi:g}" if hi is not None else "")
        raise ValueError(f"{where}={v!r} is not allowed; allowed: {'an integer' if kind == 'integer' else 'a number'} "
                         f"{bound}")


#: MlpPolicy arguments a YAML config can give (values that YAML can express), and what each may be.
POLICY_KWARGS = {"net_arch": "a list of layer sizes (integers >= 1) or {pi: [...], vf: [...]}",
                 "log_std_init": "a finite number", "ortho_init": "true or false", "full_std": "true or false",
                 "use_expln": "true or false", "squash_output": "true or false",
                 "share_features_extractor": "true or false"}


def _check_policy_kwargs(kw: Mapping[str, Any], where: str) -> None:
    """ValueError naming the key when stable-baselines3 would fail with a TypeError after the run folder exists."""
    unknown = sorted(set(kw) - set(POLICY_KWARGS))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; allowed: {list(POLICY_KWARGS)}")

    def layers(x: Any) -> bool:
        return isinstance(x, list) and all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in x)

    for k, v in kw.items():
        if k == "net_arch":
            ok = layers(v) or (isinstance(v, Mapping) and set(v) <= {"pi", "vf"} and all(layers(x) for x in v.values()))
        elif k == "log_std_init":
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        else:
            ok = isinstance(v, bool)
        if not ok:
            raise ValueError(f"{where}.{k}={v!r} is not allowed; allowed: {POLICY_KWARGS[k]}")


def _int(v: Any, where: str, lo: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{where}={v!r} must be an integer >= {lo}")
    return v


def _random_path(v: Any, where: str) -> dict[str, Any]:
    if not isinstance(v, Mapping):
        raise ValueError(f"{where} must be a mapping of RandomPathConfig fields")
    rp = dict(v)
    planar = rp.get("planar", True)
    try:
        for p in (planar if isinstance(planar, list) else [planar]):
            RandomPathConfig(**{**rp, "planar": p})
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    return rp
