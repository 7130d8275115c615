"""From-scratch PPO on the raw ``FlagellumSteer-v0``: one action = the motor speed for ``control_dt`` s.

The from-scratch baseline (``scripts/train_raw_ppo.py`` is its command line): stable-baselines3 PPO with
``MlpPolicy`` (SB3's defaults except ``n_steps`` and ``batch_size``), ``VecNormalize`` on observations and rewards,
no planner and no turn map. The bookkeeping is stable-baselines3's own:

- SB3's logger (``stable_baselines3.common.logger.configure``, CSV and stdout outputs) writes ``progress.csv``,
  one row per PPO update: SB3's ``time/*``, ``rollout/*`` (``ep_rew_mean``, ``ep_len_mean``, ``success_rate``:
  means over the last 100 episodes of the session) and ``train/*`` (SB3 logs an update's statistics in the next
  row), plus this run's ``run/*`` (update, wall and CPU seconds of the whole run, episodes and successes so far,
  the 1-min load average) and ``rollout/env_steps_per_s`` and ``rollout/episodes`` of that rollout;
- ``VecMonitor(OUT/monitor.csv, info_keywords=INFO_KEYS)`` writes one row per finished training episode;
- ``CheckpointCallback`` writes ``checkpoints/rl_model_<n>_steps.zip`` and ``rl_model_vecnormalize_<n>_steps.pkl``
  after every update (called once per update, after it, instead of every ``save_freq`` env steps), beside
  ``rl_model_state_<n>_steps.json``: the run's wall and CPU time, episode counts and the env workers' path
  generators, which SB3 does not save.

Resume (``resolve_run(..., resume=True)``) continues from the newest checkpoint with its statistics and path
generators; the rows of progress.csv and monitor.csv written after that checkpoint (a rollout that did not
finish) are dropped, so no env step is counted twice. A resume that asks for other run settings is refused,
naming the first difference. Ctrl-C or SIGTERM stops after the current env step; model.zip and vecnormalize.pkl
are then the newest checkpoint's (the last finished update); a second Ctrl-C aborts at once.
"""

from __future__ import annotations

import functools
import json
import math
import os
import platform
import shutil
import signal
import sys
import time
import warnings
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from agents.ppo_config import HELD_OUT_SEED0, PPO_KEYS
from agents.ppo_training import CHECKPOINT_PREFIX, latest_checkpoint, stop_vec_workers
from batch.provenance import git_commit
from physics.presets import DEFAULT_PRESET, RETIRED_PRESETS, preset_names, retired_preset_message

ENV_ID = "FlagellumSteer-v0"
#: One-turn paths: one waypoint 10-16 cm away, 30-150 deg off the initial heading, planar.
ONE_TURN = {"n_waypoints": 1, "segment_length_m": [0.1, 0.16], "min_turn_deg": 30.0, "max_turn_deg": 150.0,
            "planar": True}
#: The run's settings (kept by a resume) and their defaults.
CONFIG_DEFAULTS: dict[str, Any] = {
    "preset": DEFAULT_PRESET, "control_dt": 2.0, "action_type": "continuous", "random_path": ONE_TURN,
    "env_kwargs": {}, "n_envs": 2, "n_steps": 64, "batch_size": 64, "seed": 0, "normalize": True, "ppo_kwargs": {},
}
DEFAULT_TIMESTEPS = 20_000
#: Env arguments with an option of their own (not accepted in env_kwargs).
OWN_ENV_ARGS = ("preset", "control_dt", "action_type", "random_path", "render_mode")
#: PPO arguments with an option of their own (not accepted in ppo_kwargs).
OWN_PPO = ("n_steps", "batch_size")
#: Numeric PPO arguments checked here (PPO does not): (low, high, low excluded).
PPO_RANGES = {"gamma": (0.0, 1.0, True), "gae_lambda": (0.0, 1.0, False), "learning_rate": (0.0, 1.0, True),
              "n_epochs": (1, 1000, False), "clip_range": (0.0, 10.0, True), "ent_coef": (0.0, 10.0, False),
              "vf_coef": (0.0, 10.0, False), "max_grad_norm": (0.0, 1e6, True)}
#: Final-step info entries VecMonitor writes into each episode's row of monitor.csv.
INFO_KEYS = ("is_success", "buckling_events", "waypoint_index", "sim_time_s")
PROGRESS_FILE, MONITOR_FILE = "progress.csv", "monitor.csv"
STEPS_COLUMN = "time/total_timesteps"


@dataclass
class RawRun:
    """A run to train: its settings, folder, the checkpoint it continues from, its target and budget."""

    config: dict[str, Any]
    out: Path
    ckpt: tuple[Path, Path, int] | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    target: int = DEFAULT_TIMESTEPS
    budget_min: float | None = None


@dataclass(frozen=True)
class RawResult:
    """How a session ended: ``status`` (finished, stopped: REASON, aborted), exit ``code``, the run's totals."""

    status: str
    code: int
    env_steps: int
    wall_s: float


def _normalised(value: Any) -> Any:
    return json.loads(json.dumps(value))


def resolve_run(out: Path, resume: bool, given: dict[str, Any], timesteps: int | None = None,
                max_wall_min: float | None = None) -> RawRun:
    """The run in ``out``: fresh (settings from ``given``, None meaning the default) or resumed (the folder's
    settings; a given one that differs is refused). ValueError (one line) for anything not allowed."""
    if timesteps is not None and timesteps < 1:
        raise ValueError(f"--timesteps {timesteps} must be a positive number of env steps")
    if max_wall_min is not None and not (math.isfinite(max_wall_min) and max_wall_min > 0):
        raise ValueError(f"--max-wall-min {max_wall_min} must be a positive number of minutes")
    meta_file = out / "meta.json"
    ckpt = latest_checkpoint(out)
    meta: dict[str, Any] = {}
    if resume:
        if ckpt is None:
            raise ValueError(f"--resume: no checkpoint in {str(out / 'checkpoints')!r} to resume from")
        if not meta_file.is_file():
            raise ValueError(f"--resume: {str(meta_file)!r} is missing; it holds the run's settings")
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
        config = dict(meta["config"])
        for key, value in given.items():
            if value is not None and _normalised(value) != _normalised(config[key]):
                raise ValueError(f"--{key.replace('_', '-')} {json.dumps(value)} differs from this run's "
                                 f"{json.dumps(config[key])} ({meta_file}); --resume keeps the run's settings")
        target = timesteps if timesteps is not None else int(meta.get("timesteps", DEFAULT_TIMESTEPS))
        budget = max_wall_min if max_wall_min is not None else meta.get("max_wall_min")
    else:
        if ckpt is not None:
            raise ValueError(f"--out {str(out)!r} already holds a run ({ckpt[2]} env steps); pass --resume to "
                             "continue it or choose another --out")
        config = {k: _normalised(v if v is not None else CONFIG_DEFAULTS[k]) for k, v in given.items()}
        target = timesteps if timesteps is not None else DEFAULT_TIMESTEPS
        budget = max_wall_min
    validate_config(config)
    return RawRun(config, out, ckpt, meta, int(target), None if budget is None else float(budget))


def validate_config(c: dict[str, Any]) -> None:
    """Every setting; ValueError (one line) naming the bad value and what is allowed. Builds the env and a PPO
    model on it (no physics runs) so that their own checks speak too."""
    if c["preset"] in RETIRED_PRESETS:
        raise ValueError(retired_preset_message(c["preset"]))
    if c["preset"] not in preset_names():
        raise ValueError(f"--preset {c['preset']!r} is not allowed; choose one of {preset_names()}")
    if c["action_type"] not in ("continuous", "discrete"):
        raise ValueError(f"--action-type {c['action_type']!r} is not allowed; choose continuous or discrete")
    bad = sorted(set(c["env_kwargs"]) & set(OWN_ENV_ARGS))
    if bad:
        raise ValueError(f"--env-kwargs: {bad} have options of their own (--preset, --control-dt, --action-type, "
                         "--random-path; no render_mode in training)")
    n_envs, n_steps, batch, seed = c["n_envs"], c["n_steps"], c["batch_size"], c["seed"]
    if not 1 <= n_envs <= 64:
        raise ValueError(f"--n-envs {n_envs} must be from 1 to 64")
    if n_steps < 1:
        raise ValueError(f"--n-steps {n_steps} must be a positive number of env steps per worker")
    if not 2 <= batch <= n_steps * n_envs:
        raise ValueError(f"--batch-size {batch} must be from 2 to n_steps x n_envs = {n_steps * n_envs}")
    if seed < 0 or seed + n_envs - 1 >= HELD_OUT_SEED0:
        raise ValueError(f"--seed {seed} must be >= 0 with seed + n_envs - 1 < {HELD_OUT_SEED0} (seeds from "
                         f"{HELD_OUT_SEED0} on are the held-out evaluation paths)")
    allowed = [k for k in PPO_KEYS if k not in OWN_PPO]
    unknown = sorted(set(c["ppo_kwargs"]) - set(allowed))
    if unknown:
        raise ValueError(f"--ppo-kwargs: unknown or not allowed key(s) {unknown}; allowed: {allowed} (n_steps and "
                         "batch_size have options)")
    for key, (lo, hi, lo_open) in PPO_RANGES.items():
        v = c["ppo_kwargs"].get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                              or v > hi or v < lo or (lo_open and v == lo)):
            raise ValueError(f"--ppo-kwargs: {key}={v!r} must be a number in {'(' if lo_open else '['}{lo:g}, {hi:g}]")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from flagellum_env.steer_env import FlagellumSteerEnv

    try:  # the env checks every argument (and control_dt against the preset's step)
        env = FlagellumSteerEnv(**env_kwargs(c))
    except (ValueError, TypeError) as exc:
        raise ValueError(" ".join(str(exc).split())) from None
    try:  # PPO checks its own arguments; nothing is stepped
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            new_model(c, DummyVecEnv([lambda: env]))
    except (ValueError, TypeError, AssertionError, KeyError) as exc:
        raise ValueError(f"--ppo-kwargs {json.dumps(c['ppo_kwargs'])}: {' '.join(str(exc).split())}") from None
    finally:
        env.close()


def env_kwargs(c: dict[str, Any]) -> dict[str, Any]:
    """The ``FlagellumSteer-v0`` arguments of the run's settings ``c``."""
    return {"path": "random", **c["env_kwargs"], "preset": c["preset"], "control_dt": float(c["control_dt"]),
            "action_type": c["action_type"], "random_path": dict(c["random_path"])}


def new_model(c: dict[str, Any], venv):
    """A fresh PPO ``MlpPolicy`` on ``venv`` (CPU, seeded)."""
    from stable_baselines3 import PPO

    return PPO("MlpPolicy", venv, n_steps=c["n_steps"], batch_size=c["batch_size"], seed=c["seed"], device="cpu",
               verbose=0, **c["ppo_kwargs"])


def vec_env(c: dict[str, Any], monitor_file: Path | None):
    """``n_envs`` workers (SubprocVecEnv with spawn for more than one, started with SIGINT and SIGTERM ignored so
    that only this process handles them) in a ``VecMonitor`` writing ``monitor_file``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    from flagellum_env.steer_env import FlagellumSteerEnv

    fns = [functools.partial(FlagellumSteerEnv, **env_kwargs(c)) for _ in range(c["n_envs"])]
    if c["n_envs"] == 1:
        venv = DummyVecEnv(fns)
    else:
        old = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            venv = SubprocVecEnv(fns, start_method="spawn")
        finally:
            for s, h in old.items():
                signal.signal(s, h)
    return VecMonitor(venv, filename=None if monitor_file is None else str(monitor_file), info_keywords=INFO_KEYS)


def _base_vec(venv):
    while hasattr(venv, "venv"):
        venv = venv.venv
    return venv


def children_cpu_s(venv) -> float:
    """CPU seconds (user + system) of the live env worker processes; 0 without workers, nan where /proc cannot
    be read."""
    procs = getattr(_base_vec(venv), "processes", None) or []
    total, tick = 0.0, os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    for p in procs:
        try:
            fields = Path(f"/proc/{p.pid}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / tick  # utime, stime (fields 14 and 15 of stat)
        except (OSError, IndexError, ValueError):
            return math.nan
    return total


def _env_rng_states(venv) -> list[dict[str, Any]]:
    return [g.bit_generator.state for g in venv.get_attr("np_random")]


def _restore_env_rngs(venv, states: list[dict[str, Any]]) -> None:
    for i, st in enumerate(states):
        g = np.random.Generator(getattr(np.random, st["bit_generator"])())
        g.bit_generator.state = st
        venv.set_attr("np_random", g, indices=[i])


# --- files -------------------------------------------------------------------------------------
def _write_json(file: Path, data: dict[str, Any]) -> None:
    tmp = file.with_suffix(file.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, file)


def state_file(out: Path, steps: int) -> Path:
    """The run state saved with the checkpoint at ``steps`` env steps."""
    return out / "checkpoints" / f"{CHECKPOINT_PREFIX}_state_{steps}_steps.json"


def _kept_progress(file: Path, max_steps: int) -> tuple[list[str], list[str]]:
    """Header keys and the raw lines of ``file`` (SB3's progress.csv) up to ``max_steps`` env steps."""
    import csv

    if not file.is_file():
        return [], []
    lines = file.read_text(encoding="utf-8").splitlines()
    if not lines:
        return [], []
    keys = next(csv.reader([lines[0]]))
    col = keys.index(STEPS_COLUMN) if STEPS_COLUMN in keys else None
    kept = [line for line in lines[1:] if col is not None and float(next(csv.reader([line]))[col]) <= max_steps]
    return keys, kept


def _kept_monitor_rows(file: Path, n: int) -> list[dict[str, str]]:
    """The first ``n`` episode rows of a VecMonitor file (those finished by the checkpoint)."""
    import csv

    if not file.is_file() or n <= 0:
        return []
    with open(file, newline="", encoding="utf-8") as f:
        f.readline()  # VecMonitor's '#{"t_start": ...}' line
        return list(csv.DictReader(f))[:n]


def _logger(out: Path, stdout: bool, progress: tuple[list[str], list[str]]):
    """SB3's logger writing ``out/progress.csv`` (and a table on stdout), holding the kept rows of earlier
    sessions first (SB3's CSV output starts a fresh file)."""
    from stable_baselines3.common.logger import CSVOutputFormat, configure

    logger = configure(str(out), ["stdout", "csv"] if stdout else ["csv"])
    keys, lines = progress
    if keys:
        csv_out = next(f for f in logger.output_formats if isinstance(f, CSVOutputFormat))
        csv_out.keys = list(keys)
        csv_out.file.write(",".join(keys) + "\n" + "".join(line + "\n" for line in lines))
        csv_out.file.flush()
    return logger


def _loadavg() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


# --- training ----------------------------------------------------------------------------------
class _Stop:
    """Why training should stop (None: go on), set by the signal handlers and the budget."""

    def __init__(self, prog: str) -> None:
        self.prog = prog
        self.reason: str | None = None
        self.signum: int | None = None

    def handler(self, signum: int, frame: object) -> None:  # noqa: ARG002
        if self.signum is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt  # second Ctrl-C: abort now
        self.signum, self.reason = signum, signal.Signals(signum).name
        print(f"\n{self.prog}: {self.reason}: stopping after the current env step (the finished updates are "
              "saved; Ctrl-C again aborts)", file=sys.stderr, flush=True)


def _callbacks(run: RawRun, state: dict[str, Any], stop: _Stop, t0: float, cpu0: float):
    """The run's two callbacks: its bookkeeping (run/* rows, the state, the budget, the stop) and SB3's
    CheckpointCallback called after each update."""
    from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

    class Recorder(BaseCallback):
        """Episode counts, the run's wall/CPU time and rollout speed into SB3's log; the state with each
        checkpoint; the wall-time budget; stop on a signal."""

        def __init__(self) -> None:
            super().__init__()
            self.wall_before, self.cpu_before = float(state["wall_s"]), float(state["cpu_s"])
            self.t_rollout = self.rollout_s = 0.0
            self.last_interval_s: float | None = None
            self.t_interval: float | None = None
            self.rollout_episodes = 0

        def wall(self) -> float:
            return self.wall_before + time.perf_counter() - t0

        def cpu(self) -> float:
            return self.cpu_before + time.process_time() - cpu0 + children_cpu_s(self.training_env)

        def update_finished(self) -> None:
            """An update just ended (the next rollout starts, or training ends): the state of its checkpoint."""
            state.update(env_steps=int(self.num_timesteps), updates=int(state["updates"]) + 1,
                         wall_s=round(self.wall(), 2), cpu_s=round(self.cpu(), 2),
                         env_rng=_env_rng_states(self.training_env))
            _write_json(state_file(run.out, int(self.num_timesteps)), state)

        def _on_rollout_start(self) -> None:
            now = time.perf_counter()
            if self.num_timesteps > int(state["env_steps"]):
                self.update_finished()
                self.last_interval_s = now - self.t_interval if self.t_interval is not None else None
            self.t_interval = self.t_rollout = now
            self.rollout_episodes = 0
            b = run.budget_min
            if b is not None and stop.reason is None and self.last_interval_s is not None \
                    and self.wall() + self.last_interval_s > 60.0 * b:
                stop.reason = "wall-time budget"

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", []):
                ep = info.get("episode")
                if ep is not None:
                    self.rollout_episodes += 1
                    state["episodes_total"] = int(state["episodes_total"]) + 1
                    state["successes_total"] = int(state["successes_total"]) + bool(ep.get("is_success"))
            return stop.reason is None

        def _on_rollout_end(self) -> None:
            self.rollout_s = time.perf_counter() - self.t_rollout
            n = self.training_env.num_envs * self.model.n_steps
            rec = self.logger.record
            rec("run/update", int(state["updates"]) + 1)
            rec("run/wall_s", round(self.wall(), 1))
            rec("run/cpu_s", round(self.cpu(), 1))
            rec("run/episodes_total", int(state["episodes_total"]))
            rec("run/successes_total", int(state["successes_total"]))
            load = _loadavg()
            rec("run/load1", load[0] if load else math.nan)
            rec("rollout/episodes", self.rollout_episodes)
            rec("rollout/env_steps_per_s", round(n / self.rollout_s, 4) if self.rollout_s > 0 else math.nan)

        def _on_training_end(self) -> None:
            if stop.reason is None and self.num_timesteps > int(state["env_steps"]):
                self.update_finished()

    class CheckpointAfterUpdate(CheckpointCallback):
        """SB3's CheckpointCallback (model, then VecNormalize statistics), called after every PPO update (at
        the start of the next rollout and when training ends) instead of every ``save_freq`` env steps."""

        def __init__(self) -> None:
            super().__init__(save_freq=1, save_path=str(run.out / "checkpoints"), name_prefix=CHECKPOINT_PREFIX,
                             save_vecnormalize=True)
            self.saved = int(state["env_steps"])

        def _on_step(self) -> bool:
            return True

        def _save(self) -> None:
            if int(state["env_steps"]) == self.num_timesteps > self.saved:  # the recorder saw a finished update
                super()._on_step()  # save_freq 1: saves now
                if self.model.get_vec_normalize_env() is None:  # latest_checkpoint asks for a statistics file
                    Path(self._checkpoint_path("vecnormalize_", extension="pkl")).write_bytes(b"")
                self.saved = self.num_timesteps

        def _on_rollout_start(self) -> None:
            self._save()

        def _on_training_end(self) -> None:
            self._save()

    return Recorder(), CheckpointAfterUpdate()


def train_raw_ppo(run: RawRun, stdout: bool = True, prog: str = "raw_ppo", t0: float | None = None,
                  cpu0: float | None = None) -> RawResult:
    """Train (or resume) ``run``: PPO with SB3's logger, VecMonitor and checkpoints (module docstring). ``t0`` /
    ``cpu0``: perf_counter and process_time when the session started (default: now). ``stdout``: SB3's table
    of each update on stdout as well as progress.csv."""
    import stable_baselines3
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # the env workers use the cores; the small MLP does not need them
    t0 = time.perf_counter() if t0 is None else t0
    cpu0 = time.process_time() if cpu0 is None else cpu0
    c, out, ckpt = run.config, run.out, run.ckpt
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    state: dict[str, Any] = {"env_steps": 0, "updates": 0, "wall_s": 0.0, "cpu_s": 0.0, "episodes_total": 0,
                             "successes_total": 0}
    if ckpt is not None:
        sf = state_file(out, ckpt[2])
        if not sf.is_file():
            raise ValueError(f"{str(sf)!r} is missing; cannot resume that checkpoint")
        state = json.loads(sf.read_text(encoding="utf-8"))
    # what an earlier session logged after the checkpoint is redone: keep what came before it, once
    progress = _kept_progress(out / PROGRESS_FILE, int(state["env_steps"]))
    episodes = _kept_monitor_rows(out / MONITOR_FILE, int(state["episodes_total"]))
    meta = run.meta
    meta.update({"module": "agents.raw_ppo", "env_id": ENV_ID, "policy": "MlpPolicy", "config": c,
                 "env_kwargs": env_kwargs(c), "timesteps": run.target, "max_wall_min": run.budget_min,
                 "commit": meta.get("commit") or git_commit(),
                 "versions": {"python": platform.python_version(), "stable_baselines3": stable_baselines3.__version__,
                              "torch": torch.__version__, "numpy": np.__version__},
                 "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()}})
    session = {"started": _now(), "ended": None, "commit": git_commit(), "loadavg_start": _loadavg(),
               "loadavg_end": None, "steps_from": int(state["env_steps"]), "steps_to": int(state["env_steps"]),
               "wall_s": 0.0, "cpu_s": None, "status": "running", "resumed": ckpt is not None}
    meta.setdefault("sessions", []).append(session)
    meta.setdefault("date", session["started"])
    _write_json(out / "meta.json", meta)

    stop = _Stop(prog)
    old_handlers: dict[int, Any] = {}
    venv = None
    status, code = "running", 0
    try:
        raw = vec_env(c, out / MONITOR_FILE)
        for row in episodes:  # VecMonitor starts a fresh file: the episodes before the checkpoint first
            raw.results_writer.write_row(row)
        if ckpt is not None:
            venv = VecNormalize.load(str(ckpt[1]), raw) if c["normalize"] else raw
            venv.training = True
            model = PPO.load(str(ckpt[0]), env=venv, device="cpu")
            _base_vec(venv)._reset_seeds()  # PPO.load seeded the workers again (seed + rank): keep their generators
            _restore_env_rngs(venv, state["env_rng"])
            set_random_seed(c["seed"] + int(state["env_steps"]))  # torch, numpy, random: the policy's sampling
        else:
            venv = VecNormalize(raw, gamma=float(c["ppo_kwargs"].get("gamma", 0.99))) if c["normalize"] else raw
            model = new_model(c, venv)  # seeds the workers: seed + rank, at their first reset
        model.set_logger(_logger(out, stdout, progress))
        for s in (signal.SIGINT, signal.SIGTERM):
            old_handlers[s] = signal.signal(s, stop.handler)
        remaining = run.target - int(model.num_timesteps)
        if remaining > 0:
            model.learn(remaining, callback=CallbackList(list(_callbacks(run, state, stop, t0, cpu0))),
                        reset_num_timesteps=ckpt is None)
        status = "finished" if stop.reason is None else f"stopped: {stop.reason}"
        code = 128 + stop.signum if stop.signum is not None else 0
    except KeyboardInterrupt:
        status, code = "aborted: second SIGINT", 130
    except BaseException as exc:
        status = f"failed: {type(exc).__name__}: {exc}"
        raise
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)
        cpu_children = children_cpu_s(venv) if venv is not None else 0.0
        if venv is not None:
            if status.startswith("finished") or status.startswith("stopped"):
                try:
                    venv.close()
                except (EOFError, OSError, BrokenPipeError) as exc:
                    print(f"{prog}: closing the env workers: {exc}", file=sys.stderr)
                    stop_vec_workers(venv)
            elif not stop_vec_workers(venv):  # aborted or failed: a worker may be inside a long step
                venv.close()
        session.update(ended=_now(), loadavg_end=_loadavg(), status=status, steps_to=int(state["env_steps"]),
                       wall_s=round(time.perf_counter() - t0, 1),
                       cpu_s=round(time.process_time() - cpu0 + cpu_children, 1))
        meta["total"] = {k: state[k] for k in ("env_steps", "updates", "wall_s", "cpu_s", "episodes_total",
                                               "successes_total")}
        meta["updated"] = session["ended"]
        _write_json(out / "meta.json", meta)
    newest = latest_checkpoint(out)
    if newest is not None:  # the last finished update's policy and statistics
        shutil.copyfile(newest[0], out / "model.zip")
        if c["normalize"]:
            shutil.copyfile(newest[1], out / "vecnormalize.pkl")
    return RawResult(status, code, int(state["env_steps"]), float(state["wall_s"]))
