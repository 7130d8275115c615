"""Train the residual PPO agent (stable-baselines3, PyTorch on the CPU); resumable.

``train(config, out_dir)`` runs PPO on ``TurnDecisionEnv`` (``agents.turn_decision_env``): a
``SubprocVecEnv`` of ``n_envs`` workers (a ``DummyVecEnv`` for one), ``VecMonitor`` and
``VecNormalize``; an ``EvalCallback`` on the fixed validation paths with the nominal swimmer
(reports ``is_success``);
the curriculum; checkpoints with their VecNormalize statistics; tensorboard logs; a progress bar;
a wall-time budget. ``out_dir`` receives::

    config.yml          the configuration trained from
    meta.json           mode, preset, the swimmer's head reading (``head_rotation``), commit, decisions, wall time,
                        versions (updated at each save), and the
                        agent's env: ``env_id`` and ``make_kwargs`` (``gymnasium.make(env_id, **make_kwargs)``)
    model.zip           the final policy          vecnormalize.pkl  its normalisation statistics
    episodes.csv        one row per training episode (appended; survives resume)
    eval/evaluations.npz  EvalCallback's log (kept across resume)
    checkpoints/        rl_model_<n>_steps.zip + rl_model_vecnormalize_<n>_steps.pkl
    tb/                 tensorboard logs
    training_curve.png  training episodes and validations against decisions (at the end of a run or a stop)

``resume=True`` continues from the newest checkpoint with its statistics, the decisions done and
the wall time already spent. A config with ``init_from`` starts from that trained agent's policy
and VecNormalize statistics instead of a fresh network (fine-tuning, e.g. on another preset);
meta.json then records the agent it started from, with that agent's own decisions and wall time.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import re
import shutil
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from agents.burst_design import BurstLimits
from agents.ppo_config import TrainConfig
from agents.residual_planner import ResidualLimits
from batch.provenance import git_commit
from batch.store import drop_rows_after
from physics.errors import is_interrupt

#: meta.json's "mode" by ``task.design``: a residual agent corrects a planner; a scratch agent has none.
MODES = {"residual": "residual", "burst": "scratch"}
CHECKPOINT_PREFIX = "rl_model"
#: meta.json is rewritten after a rollout at most this often (s of wall time), and at every save.
META_EVERY_S = 10.0
EPISODE_FIELDS = ("decisions", "wall_time_s", "stage", "return", "length", "is_success", "waypoints_reached",
                  "mean_cross_track_m", "time_s", "energy_J", "buckling_events", "tier")


@dataclass(frozen=True)
class TrainResult:
    out_dir: Path
    decisions: int
    wall_time_s: float
    stopped_by_budget: bool
    interrupted: bool = False


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped ``train``; the model, its statistics and a checkpoint at ``result.decisions``
    were saved first, so ``resume=True`` continues from there."""

    def __init__(self, result: TrainResult) -> None:
        super().__init__(f"training interrupted after {result.decisions} decisions; saved in {result.out_dir}")
        self.result = result


@contextmanager
def _signals_deferred() -> Iterator[None]:
    """Ctrl-C / SIGTERM during the block (a gradient update, a log row) take effect after it, as a
    KeyboardInterrupt; a second signal stops at once (``physics.run.stop_requests``)."""
    from physics.run import stop_requests

    with stop_requests() as stop:
        yield
    if stop.requested:
        raise KeyboardInterrupt


def _deferring(fn):
    """``fn`` run under ``_signals_deferred`` (PPO's ``train``: the policy is never left half-updated)."""
    def wrapper(*args, **kwargs):
        with _signals_deferred():
            return fn(*args, **kwargs)
    return wrapper


def agent_env(config: TrainConfig) -> tuple[str, dict[str, Any]]:
    """The trained agent's env as a registered id and its ``gymnasium.make`` arguments (every one explicit, so
    that later changes of the defaults do not change it): the config's task on the last curriculum stage's
    paths, nominal or randomised as trained. ``PPO.load`` and ``VecNormalize.load`` of the agent's files on
    ``make_vec_env(env_id, env_kwargs=make_kwargs)`` reproduce it with plain stable-baselines3."""
    from agents.registration import (BURST_ENV_ID, BURST_SURROGATE_ENV_ID, TURN_ENV_ID, TURN_FAST_ENV_ID,
                                     TURN_SURROGATE_ENV_ID)

    if config.design == "burst":
        return BURST_SURROGATE_ENV_ID if config.tier == "surrogate" else BURST_ENV_ID, {"preset": config.preset, "turn_map": config.turn_map,
                                        "env_kwargs": dict(config.env_kwargs),
                                        "limits": dataclasses.asdict(BurstLimits(**config.limits)),
                                        "random_path": dict(config.curriculum[-1].random_path),
                                        # the surrogate's randomised map; agents trained without it store none
                                        **({"map_noise": dict(config.map_noise)}
                                           if config.map_noise is not None and config.tier == "surrogate" else {})}
    if config.tier == "surrogate":
        env_id = TURN_SURROGATE_ENV_ID
    else:
        env_id = {"fast": TURN_FAST_ENV_ID}.get(config.preset, TURN_ENV_ID)
    return env_id, {"preset": config.preset, "turn_map": config.turn_map, "env_kwargs": dict(config.env_kwargs),
                    "limits": dataclasses.asdict(ResidualLimits(**config.limits)), "action_cost": config.action_cost,
                    "random_path": dict(config.curriculum[-1].random_path),
                    # the rule planner's agents from before the choice existed store no "planner" (its default)
                    **({"planner": config.planner} if config.planner != "rule" else {})}


def trained_head_rotation(preset: str, env_kwargs: dict[str, Any]) -> str:
    """The reading of the head (``SwimmerParams.head_rotation``) of the swimmer an agent trains on: the preset's,
    or the env's ``params`` override."""
    from flagellum_env.config import make_config

    physics = {k: v for k, v in env_kwargs.items() if k in ("params", "numerics")}
    return make_config(preset=preset, **physics).physics()[0].head_rotation


def _make_env(config: TrainConfig, rank: int, paths=None):
    """A picklable factory of the agent's env (``agent_env``, unwrapped): training (the curriculum's first stage,
    the config's randomisation and ``map_noise``) or, with ``paths``, validation (those paths, nominal parameters,
    the map as measured)."""
    parent = os.getpid()
    env_id, make_kwargs = agent_env(config)

    def factory():
        if os.getpid() != parent:  # a SubprocVecEnv worker: quiet on Ctrl-C, gone with its parent
            from batch.worker import watch_parent

            signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops training and closes the workers
            watch_parent(parent, interval_s=0.2)  # exit before a finished step hits the closed pipe
        import gymnasium as gym

        import agents  # noqa: F401  (registers the ids in a spawned worker)

        kwargs = dict(config.env_kwargs)
        if paths:
            kwargs.pop("randomize", None)
        env_class = gym.envs.registration.load_env_creator(gym.spec(env_id).entry_point)
        arguments = {**make_kwargs, "env_kwargs": kwargs, "paths": paths,
                     "random_path": None if paths else config.curriculum[0].random_path}
        if paths and "map_noise" in arguments:
            arguments["map_noise"] = None
        env = env_class(**arguments)
        if config.cheap_fraction > 0.0 and not paths:  # surrogate episodes in the mix (validation: the rod only)
            from agents.surrogate_burst_env import SurrogateBurstEnv
            from agents.tier_mixture import TierMixture

            noise = {"map_noise": dict(config.map_noise)} if config.map_noise is not None else {}
            env = TierMixture(env, SurrogateBurstEnv(**arguments, **noise), config.cheap_fraction)
        env.reset(seed=config.seed + rank)
        return env
    return factory


def _vec_env(config: TrainConfig, n: int, paths=None, seed_offset: int = 0):
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    class InProcessVecEnv(DummyVecEnv):
        """The envs in this process, each step and reset under ``_signals_deferred``: Ctrl-C or SIGTERM take effect
        once the step is done, never as an exception inside the rod's compiled kernels (which crashed the process
        with SIGSEGV at ``faithful``); SubprocVecEnv's workers ignore the signals and the parent waits on pipes."""

        def step_wait(self):
            with _signals_deferred():
                return super().step_wait()

        def reset(self):
            with _signals_deferred():
                return super().reset()

    fns = [_make_env(config, seed_offset + i, paths) for i in range(n)]
    venv = SubprocVecEnv(fns, start_method="spawn") if n > 1 else InProcessVecEnv(fns)
    return VecMonitor(venv, info_keywords=("is_success",))


def _csv_header(file: Path) -> list[str]:
    """The column names of a CSV file's first line."""
    with open(file, newline="", encoding="utf-8") as f:
        return next(csv.reader(f), [])


def run_identity(config: TrainConfig) -> dict[str, Any]:
    """What makes a training run the same run (a resume must not change it): the agent, its task and its network.
    The budget (n_timesteps, max_wall_time_s), the curriculum, validation, checkpoints and PPO's step sizes may
    change between resumes."""
    return json.loads(json.dumps({
        "name": config.name, "preset": config.preset, "turn_map": config.turn_map, "limits": dict(config.limits),
        "action_cost": config.action_cost, "env_kwargs": dict(config.env_kwargs), "policy": config.policy,
        "policy_kwargs": dict(config.hyperparameters.get("policy_kwargs") or {}), "n_envs": config.n_envs,
        "normalize": dict(config.normalize), "seed": config.seed, "init_from": config.init_from,
        # runs from before the designs and tiers existed have neither (residual on the physics)
        **({"design": config.design} if config.design != "residual" else {}),
        **({"tier": config.tier} if config.tier != "physics" else {}),
        **({"algorithm": config.algorithm} if config.algorithm != "ppo" else {}),
        **({"map_noise": dict(config.map_noise)} if config.map_noise is not None else {}),
        **({"cheap_fraction": config.cheap_fraction} if config.cheap_fraction > 0.0 else {}),
        # the rule planner's runs from before the choice existed have no "planner"
        **({"planner": config.planner} if config.planner != "rule" else {})}, default=str))


def _check_same_run(out: Path, meta: dict[str, Any], config: TrainConfig) -> None:
    """ValueError naming the first difference when ``out`` holds a run of another agent or task."""
    from batch.store import short_repr, first_difference

    new = run_identity(config)
    old = meta.get("run")
    if old is None:  # a run from before meta.json recorded it: compare what meta.json has
        keys = ("name", "preset", "turn_map", "limits", "action_cost", "env_kwargs", "n_envs")
        old = {k: meta[k] for k in keys if k in meta}
        new = {k: new[k] for k in old}
    diff = first_difference(old, new)
    if diff is not None:
        key, a, b = diff
        raise ValueError(f"--resume: {str(out)!r} holds another training run: {key} is {short_repr(a)} there and "
                         f"{short_repr(b)} in this config; allowed: the same agent, task and network, or another --out")


def algorithm_class(name: str):
    """stable-baselines3's class of ``TrainConfig.algorithm`` ("ppo" or "sac")."""
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC}[name]


def replay_buffer_file(folder: Path, decisions: int) -> Path:
    """A SAC checkpoint's replay buffer (``CheckpointCallback``'s name)."""
    return folder / f"{CHECKPOINT_PREFIX}_replay_buffer_{decisions}_steps.pkl"


class _RolloutCheckpoint(BaseCallback):
    """SAC's checkpoints (model, replay buffer, VecNormalize statistics; ``latest_checkpoint``'s names) every
    ``save_freq`` env steps, written at the end of a rollout: SAC stores a step's transition after the step's
    callbacks, so a checkpoint written there (CheckpointCallback) lacks the last one and a resumed run would too."""

    def __init__(self, save_freq: int, out: Path) -> None:
        super().__init__()
        self.save_freq, self.out, self.saved = save_freq, out, 0

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        due = self.n_calls // self.save_freq
        if due > self.saved:
            self.saved = due
            steps = self.num_timesteps
            self.model.save(str(self.out / f"{CHECKPOINT_PREFIX}_{steps}_steps.zip"))
            self.model.save_replay_buffer(str(replay_buffer_file(self.out, steps)))
            self.model.get_vec_normalize_env().save(str(self.out / f"{CHECKPOINT_PREFIX}_vecnormalize_{steps}_steps.pkl"))


def _check_init_algorithm(init: Path, config: TrainConfig) -> None:
    """ValueError when ``init_from`` holds an agent of another algorithm or action design than ``config``."""
    meta_file = init / "meta.json"
    meta = json.loads(meta_file.read_text(encoding="utf-8")) if meta_file.is_file() else {}
    for key, default in (("algorithm", "ppo"), ("design", "residual")):
        had = (meta.get("run") or {}).get(key, default) if meta else getattr(config, key)
        if had != getattr(config, key):
            raise ValueError(f"init_from={str(init)!r} holds a {key} {had!r} agent; this config trains {key} "
                             f"{getattr(config, key)!r}; allowed: an agent of the same {key}")


def latest_checkpoint(out_dir: Path) -> tuple[Path, Path, int] | None:
    """(model, vecnormalize, decisions) of the newest checkpoint in ``out_dir/checkpoints``."""
    best = None
    for f in (out_dir / "checkpoints").glob(f"{CHECKPOINT_PREFIX}_*_steps.zip"):
        m = re.fullmatch(rf"{CHECKPOINT_PREFIX}_(\d+)_steps\.zip", f.name)
        if m and (best is None or int(m.group(1)) > best[2]):
            stats = f.with_name(f"{CHECKPOINT_PREFIX}_vecnormalize_{m.group(1)}_steps.pkl")
            if stats.is_file():
                best = (f, stats, int(m.group(1)))
    return best


def train(config: TrainConfig, out_dir: str | Path, resume: bool = False, progress: bool = True,
          config_text: str | None = None) -> TrainResult:
    """Train (or resume) the agent of ``config`` into ``out_dir`` (module docstring)."""
    import torch
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback, EvalCallback
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # the env workers use the cores; the small MLP does not need them
    out = Path(out_dir)
    ckpt = latest_checkpoint(out) if resume else None
    if resume and ckpt is None:
        raise ValueError(f"--resume: no checkpoint in {str(out / 'checkpoints')!r} to resume from")
    if not resume and (out / "checkpoints").exists() and any((out / "checkpoints").iterdir()):
        raise ValueError(f"{str(out)!r} already holds a training run; pass --resume to continue it or choose "
                         "another --out")
    meta_file = out / "meta.json"
    meta = json.loads(meta_file.read_text(encoding="utf-8")) if resume and meta_file.is_file() else {}
    if resume:
        _check_same_run(out, meta, config)
        if ckpt[2] >= config.n_timesteps:
            raise ValueError(f"--resume: the run in {str(out)!r} has done {ckpt[2]} decisions, n_timesteps="
                             f"{config.n_timesteps}: nothing to resume; allowed: a config with a larger n_timesteps "
                             "to train on")
    out.mkdir(parents=True, exist_ok=True)
    (out / "checkpoints").mkdir(exist_ok=True)
    if config_text is not None:
        (out / "config.yml").write_text(config_text, encoding="utf-8")
    if ckpt is not None:  # what an earlier, killed run logged after its last checkpoint is redone: keep it once
        drop_rows_after(out / "episodes.csv", "decisions", ckpt[2], EPISODE_FIELDS)
    spent_before = float(meta.get("wall_time_s", 0.0))
    meta["run"] = run_identity(config)

    raw = _vec_env(config, config.n_envs)
    eval_raw = _vec_env(config, 1, paths=config.validation.paths(), seed_offset=10_000)
    algorithm = algorithm_class(config.algorithm)
    if ckpt is not None:
        venv = VecNormalize.load(str(ckpt[1]), raw)
        venv.training = True
        model = algorithm.load(str(ckpt[0]), env=venv, device="cpu", tensorboard_log=str(out / "tb"))
        if config.algorithm == "sac":  # an off-policy run goes on with the experience it had
            model.load_replay_buffer(str(replay_buffer_file(out / "checkpoints", ckpt[2])))
    elif config.init_from is not None:  # fine-tune: the trained policy and its statistics, this config's settings
        init = Path(config.init_from)
        _check_init_algorithm(init, config)
        venv = VecNormalize.load(str(init / "vecnormalize.pkl"), raw)
        venv.training = True
        hyper = {k: v for k, v in config.hyperparameters.items() if k != "policy_kwargs"}  # the trained network
        model = algorithm.load(str(init / "model.zip"), env=venv, device="cpu", tensorboard_log=str(out / "tb"),
                               seed=config.seed, **hyper)
        model.num_timesteps = 0  # this run's decisions count from 0 (curriculum, budget, checkpoints)
        init_meta = init / "meta.json"
        meta["init_from"] = {"path": str(init), **({k: v for k, v in json.loads(init_meta.read_text()).items()
                                                   if k in ("name", "preset", "decisions", "wall_time_s", "commit")}
                                                if init_meta.is_file() else {})}
    else:
        norm = dict(config.normalize)
        venv = VecNormalize(raw, **norm)
        model = algorithm(config.policy, venv, seed=config.seed, device="cpu", tensorboard_log=str(out / "tb"),
                          verbose=0, **dict(config.hyperparameters))
    eval_env = VecNormalize(eval_raw, training=False, norm_obs=bool(config.normalize.get("norm_obs", True)),
                            norm_reward=False, clip_obs=float(config.normalize.get("clip_obs", 10.0)))

    n = config.n_envs
    eval_cb = EvalCallback(eval_env, n_eval_episodes=len(config.validation.seeds),
                           eval_freq=max(1, config.validation.every // n), log_path=str(out / "eval"),
                           best_model_save_path=None, deterministic=True, verbose=0)
    _restore_eval_log(eval_cb, out / "eval" / "evaluations.npz", upto=None if ckpt is None else ckpt[2])
    if config.algorithm == "sac":
        ckpt_cb = _RolloutCheckpoint(save_freq=max(1, config.checkpoint_every // n), out=out / "checkpoints")
    else:
        ckpt_cb = CheckpointCallback(save_freq=max(1, config.checkpoint_every // n), save_path=str(out / "checkpoints"),
                                     name_prefix=CHECKPOINT_PREFIX, save_vecnormalize=True)
    if ckpt is not None:
        # the callbacks count their own calls from 0; a resumed run must evaluate and checkpoint at the
        # same decision counts as an uninterrupted one (every `validation.every` decisions, and at the end)
        eval_cb.n_calls = ckpt_cb.n_calls = int(model.num_timesteps) // n
        if config.algorithm == "sac":
            ckpt_cb.saved = ckpt_cb.n_calls // ckpt_cb.save_freq
    book = _Bookkeeping(config, out, spent_before, meta)
    t0 = time.perf_counter()
    remaining = max(0, config.n_timesteps - model.num_timesteps)
    interrupted = False
    if remaining:
        # a signal never lands in the middle of a gradient update (on the class while learning: an attribute of
        # the model would be pickled into its checkpoints)
        cls, update = type(model), type(model).train
        cls.train = _deferring(update)
        try:
            model.learn(remaining, callback=CallbackList([book, ckpt_cb, eval_cb]), progress_bar=progress,
                        reset_num_timesteps=ckpt is None, tb_log_name=config.algorithm)
        except BaseException as exc:  # Ctrl-C / SIGTERM, also when it surfaced from a Numba kernel
            if not is_interrupt(exc):
                _close(venv, eval_env, at_once=True)
                raise
            interrupted = True
        finally:
            cls.train = update
    from physics.run import stop_requests

    with stop_requests():  # the files are written whole (a second signal stops at once)
        decisions = int(model.num_timesteps)
        model.save(str(out / "model.zip"))
        venv.save(str(out / "vecnormalize.pkl"))
        if interrupted:  # a checkpoint here: --resume continues from this decision, nothing is redone
            model.save(str(out / "checkpoints" / f"{CHECKPOINT_PREFIX}_{decisions}_steps.zip"))
            venv.save(str(out / "checkpoints" / f"{CHECKPOINT_PREFIX}_vecnormalize_{decisions}_steps.pkl"))
            if config.algorithm == "sac":
                model.save_replay_buffer(str(replay_buffer_file(out / "checkpoints", decisions)))
        book.num_timesteps = decisions
        book.write_meta(final=not interrupted, interrupted=interrupted, defer_signals=False)
        _close(venv, eval_env, at_once=interrupted)
    write_training_curve(out, config)
    result = TrainResult(out, decisions, spent_before + time.perf_counter() - t0, book.stopped, interrupted)
    if interrupted:
        raise TrainingInterrupted(result)
    return result


def write_training_curve(out: Path, config: TrainConfig) -> Path | None:
    """``out/training_curve.png``: the run's training episodes and validations (``agents.training_plots``);
    None when no episode has been logged yet."""
    from agents.training_plots import training_figure

    if not (out / "episodes.csv").is_file() or (out / "episodes.csv").stat().st_size == 0:
        return None
    what = (f"{config.algorithm.upper()} residual on the {config.planner} planner" if config.design == "residual"
            else f"{config.algorithm.upper()} from scratch, burst actions")
    fig = training_figure(out, title=f"{config.name}: {what}, {config.preset} ({config.tier})")
    fig.savefig(out / "training_curve.png", dpi=110)
    return out / "training_curve.png"


def stop_vec_workers(vec) -> bool:
    """Stop the worker processes under the vector env ``vec`` at once, whatever step they are in (SIGTERM, then
    SIGKILL after 2 s for a worker that ignores it or is inside a long compiled kernel), and mark it closed.
    False when ``vec`` has no worker processes (a ``DummyVecEnv``: nothing to stop)."""
    inner = vec
    while hasattr(inner, "venv"):
        inner = inner.venv
    procs = list(getattr(inner, "processes", []))
    if not hasattr(inner, "processes"):
        return False
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
    for proc in procs:
        proc.join(timeout=2)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout=5)
    inner.closed = True  # nothing left to close
    return True


def _close(venv, eval_env, at_once: bool) -> None:
    """Close the envs; ``at_once`` (after an interrupt): stop the worker processes instead of waiting for the
    step they are in."""
    if at_once:
        for vec in (venv, eval_env):
            if not stop_vec_workers(vec):
                vec.close()
        return
    venv.close()
    eval_env.close()


def _restore_eval_log(cb, file: Path, upto: int | None = None) -> None:
    """Keep the evaluations of earlier runs (EvalCallback starts a fresh log otherwise), those up to decision
    ``upto`` (the checkpoint resumed from: a killed run's later ones are redone)."""
    if not file.is_file():
        return
    with np.load(file) as d:
        keep = [i for i, t in enumerate(d["timesteps"]) if upto is None or int(t) <= upto]
        cb.evaluations_timesteps = [int(d["timesteps"][i]) for i in keep]
        cb.evaluations_results = [list(d["results"][i]) for i in keep]
        cb.evaluations_length = [list(d["ep_lengths"][i]) for i in keep]
        if "successes" in d:
            cb.evaluations_successes = [list(d["successes"][i]) for i in keep]


class _Bookkeeping(BaseCallback):
    """Curriculum switches, the episode log, the wall-time budget and meta.json."""

    def __init__(self, config: TrainConfig, out: Path, spent_before: float, meta: dict[str, Any]) -> None:
        super().__init__()
        self.config, self.out, self.spent_before, self.meta = config, out, spent_before, meta
        self.commit = git_commit()  # once per session (meta.json is rewritten as training goes)
        self.meta_written = -math.inf
        self.t0 = time.perf_counter()
        self.stage: str | None = None
        self.stopped = False

    def elapsed(self) -> float:
        return self.spent_before + time.perf_counter() - self.t0

    def _on_training_start(self) -> None:
        self._set_stage()
        self.write_meta(final=False)

    def _set_stage(self) -> None:
        st = self.config.stage_at(self.num_timesteps)
        if st.name != self.stage:
            self.training_env.env_method("set_random_path", dict(st.random_path))
            self.stage = st.name

    def _on_step(self) -> bool:
        file = self.out / "episodes.csv"
        new = not file.exists()
        rows = []
        for info in self.locals.get("infos", []):
            ep = info.get("episode")
            if ep is None:
                continue
            rows.append({"decisions": self.num_timesteps, "wall_time_s": round(self.elapsed(), 1), "stage": self.stage,
                         "return": ep["r"], "length": ep["l"], **{k: info.get(k) for k in EPISODE_FIELDS[5:-1]},
                         "tier": "surrogate" if info.get("cheap") else self.config.tier})
        if rows:
            # a run begun before a column was added keeps its header (the new column is left out)
            fields = EPISODE_FIELDS if new else _csv_header(file)
            with _signals_deferred(), open(file, "a", newline="", encoding="utf-8") as f:
                w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
                if new:
                    w.writeheader()
                w.writerows(rows)
        self._set_stage()
        if self.config.max_wall_time_s is not None and self.elapsed() > self.config.max_wall_time_s:
            self.stopped = True
            return False
        return True

    def _on_rollout_end(self) -> None:
        # PPO's rollouts are long; SAC's are one step each (train_freq): meta.json at most every 10 s of wall time
        if time.perf_counter() - self.meta_written >= META_EVERY_S:
            self.write_meta(final=False)

    def write_meta(self, final: bool, interrupted: bool = False, defer_signals: bool = True) -> None:
        import stable_baselines3
        import torch

        env_id, make_kwargs = agent_env(self.config)
        self.meta.update({
            "name": self.config.name, "mode": MODES[self.config.design], "design": self.config.design,
            "tier": self.config.tier, "preset": self.config.preset, "turn_map": self.config.turn_map,
            "head_rotation": trained_head_rotation(self.config.preset, self.config.env_kwargs),
            "planner": self.config.planner,
            "config": self.config.source, "n_envs": self.config.n_envs,
            "limits": dict(self.config.limits), "action_cost": self.config.action_cost,
            "env_kwargs": dict(self.config.env_kwargs), "env_id": env_id, "make_kwargs": make_kwargs,
            "decisions": int(self.num_timesteps), "wall_time_s": round(self.elapsed(), 1),
            "stopped_by_wall_time_budget": self.stopped, "finished": final, "interrupted": interrupted,
            "commit": self.meta.get("commit") or self.commit, "last_commit": self.commit,
            "updated": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "versions": {"stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__},
        })
        self.meta_written = time.perf_counter()
        with _signals_deferred() if defer_signals else nullcontext():
            tmp = self.out / "meta.json.tmp"
            tmp.write_text(json.dumps(self.meta, indent=1) + "\n", encoding="utf-8")
            shutil.move(str(tmp), str(self.out / "meta.json"))
