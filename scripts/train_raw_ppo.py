"""From-scratch PPO on the raw ``FlagellumSteer-v0`` (issue #17, item 4): learning curve, env steps/s, wall time.

stable-baselines3 PPO with ``MlpPolicy`` and a fresh network (SB3's defaults except ``n_steps``),
``VecNormalize`` on observations and rewards, on the raw env: one action = the motor speed for
``control_dt`` simulated seconds (default 2 s, as the env benchmark), continuous by default. No
planner, no turn map. Default task, "one-turn paths": one waypoint 10-16 cm from the start,
30-150 deg off the initial heading, in the x-y plane (the first curriculum stage of
``agents/configs/ppo_residual_coarse.yml``, planar only), reach radius 1.5 cm: the swimmer has to
turn once, then swim straight. ``--random-path`` takes other ``RandomPathConfig`` fields.

Usage::

    # the baseline: faithful preset, 2 workers, stop cleanly before 45 min of wall time
    python scripts/train_raw_ppo.py --out results/agents/raw_ppo_faithful --n-envs 2 --timesteps 100000 \\
        --max-wall-min 45
    # continue it (the run's settings are kept; --timesteps and --max-wall-min may change; the
    # budget counts the run's whole training wall time, so give a larger one to go on)
    python scripts/train_raw_ppo.py --out results/agents/raw_ppo_faithful --resume --max-wall-min 90
    # redraw OUT/learning_curve.png from OUT/progress.csv (no training)
    python scripts/train_raw_ppo.py --out results/agents/raw_ppo_faithful --plot

``--out`` receives, as training goes::

    progress.csv        one row per PPO update (rollout + optimisation): env steps, wall and CPU seconds
                        (parent + env workers), env steps/s, the episodes that ended in that rollout
                        (mean return and length, success rate = info['is_success'], buckling events,
                        waypoints reached), PPO's training statistics, the 1-min load average
    episodes.csv        one row per finished training episode
    checkpoints/        after every update: rl_model_<steps>_steps.zip, rl_model_vecnormalize_<steps>_steps.pkl
                        and rl_model_state_<steps>_steps.json (wall/CPU time so far, the env workers'
                        path generators), named as agents.ppo_training's checkpoints
    model.zip, vecnormalize.pkl   the newest policy and its statistics (copied at the end of a session)
    meta.json           config, git commit, versions, machine, and one entry per session (dates, load
                        averages at start and end, steps, wall and CPU time, how it ended)
    learning_curve.png  return and success rate against env steps and against wall hours

Training paths are drawn by the env workers' generators, seeded ``seed`` .. ``seed + n_envs - 1``
(all below 1000: seeds from 1000 on are the held-out evaluation paths, scripts/make_eval_paths.py);
``--resume`` restores those generators from the checkpoint, so the path sequence continues.
``--resume`` continues from the newest checkpoint: rows of progress.csv and episodes.csv beyond its
step count (an update that did not finish) are dropped, so none is lost or written twice; the
interrupted rollout is run again. Ctrl-C or SIGTERM stops after the current env step (the finished
updates are already saved; a second Ctrl-C aborts at once); the env workers ignore both signals
and are closed by this process. ``--timesteps`` is rounded up to whole updates (n_steps x n_envs).
``--max-wall-min`` stops before an update that would end past the budget (judged by the last one).
Wall and CPU seconds in progress.csv are the run's up to each update, start-up of every session
included, the work lost to an interruption (the unfinished rollout) not; meta.json's sessions hold
each session's whole wall and CPU time. CPU = this process (PPO, and the env with one worker) plus
the live env workers (read from /proc).

Cost: every env step is a physics run of ``control_dt`` simulated seconds (buckled steps cost
several times straight ones); an episode of a one-turn path lasts up to 170-270 steps (its time
limit, 1.5 x path length / the 10 rpm speed), fewer when it leaves the path. First measurement
(2026-12-02, this 2-core machine while two evaluations used both cores, load average 3.2-3.4):
faithful, control_dt 2 s, one worker, the untrained policy: 0.28 env steps/s (16 steps in 57 s). There is no periodic evaluation on fixed paths: at the
faithful preset one evaluation episode costs minutes, so the curve is the training episodes'
(stochastic policy).
"""

from __future__ import annotations

import argparse
import csv
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
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from agents.ppo_config import HELD_OUT_SEED0, PPO_KEYS
from agents.ppo_training import CHECKPOINT_PREFIX, latest_checkpoint
from batch.provenance import git_commit
from physics.presets import DEFAULT_PRESET, preset_names

PROG = "train_raw_ppo.py"
ENV_ID = "FlagellumSteer-v0"
#: One-turn paths: one waypoint 10-16 cm away, 30-150 deg off the initial heading, planar.
ONE_TURN = {"n_waypoints": 1, "segment_length_m": [0.1, 0.16], "min_turn_deg": 30.0, "max_turn_deg": 150.0,
            "planar": True}
#: The run's settings (kept by --resume) and their defaults.
CONFIG_DEFAULTS: dict[str, Any] = {
    "preset": DEFAULT_PRESET, "control_dt": 2.0, "action_type": "continuous", "random_path": ONE_TURN,
    "env_kwargs": {}, "n_envs": 2, "n_steps": 64, "batch_size": 64, "seed": 0, "normalize": True, "ppo_kwargs": {},
}
DEFAULT_TIMESTEPS = 20_000
#: Arguments with an option of their own (not accepted in --env-kwargs).
OWN_ENV_ARGS = ("preset", "control_dt", "action_type", "random_path", "render_mode")
PROGRESS_FIELDS = ("update", "env_steps", "wall_s", "cpu_s", "rollout_s", "update_s", "steps_per_s",
                   "env_steps_per_s", "episodes", "ep_return_mean", "ep_length_mean", "success_rate",
                   "buckling_events_mean", "waypoints_reached_mean", "episodes_total", "successes_total",
                   "approx_kl", "entropy_loss", "explained_variance", "policy_std", "load1")
EPISODE_FIELDS = ("env_steps", "wall_s", "env", "return", "length", "is_success", "buckling_events",
                  "waypoints_reached", "sim_time_s")
#: Final-step info entries copied into each episode's record (VecMonitor).
INFO_KEYS = ("is_success", "buckling_events", "waypoint_index", "sim_time_s")
TRAIN_STATS = {"approx_kl": "train/approx_kl", "entropy_loss": "train/entropy_loss",
               "explained_variance": "train/explained_variance", "policy_std": "train/std"}


# --- options ---------------------------------------------------------------------------------
class _Parser(argparse.ArgumentParser):
    """Errors are one line ``train_raw_ppo.py: error: ...``, status 2 (as the ``flagellum`` CLI's)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{PROG}: error: {' '.join(message.split())} (see '{PROG} --help')\n")


def _parser() -> argparse.ArgumentParser:
    d = CONFIG_DEFAULTS
    ap = _Parser(prog=PROG, description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=None,
                    help="run folder (default: results/agents/raw_ppo_PRESET)")
    ap.add_argument("--resume", action="store_true", help="continue the run in --out from its newest checkpoint")
    ap.add_argument("--plot", action="store_true", help="only draw OUT/learning_curve.png from OUT/progress.csv")
    ap.add_argument("--timesteps", type=int, default=None,
                    help=f"env steps to train in all (all workers; default {DEFAULT_TIMESTEPS}, rounded up to "
                         "whole updates)")
    ap.add_argument("--max-wall-min", type=float, default=None,
                    help="stop before an update that would take the run's training wall time past this (minutes)")
    g = ap.add_argument_group("run settings (kept by --resume)")
    g.add_argument("--preset", default=None, help=f"physics preset, one of {preset_names()} (default {d['preset']})")
    g.add_argument("--control-dt", type=float, default=None,
                   help=f"simulated seconds per env step (default {d['control_dt']})")
    g.add_argument("--action-type", default=None, help="continuous (default) or discrete")
    g.add_argument("--random-path", default=None, metavar="JSON",
                   help=f"RandomPathConfig fields of the training paths (default {json.dumps(ONE_TURN)})")
    g.add_argument("--env-kwargs", default=None, metavar="JSON",
                   help="further FlagellumSteer-v0 arguments, e.g. '{\"randomize\": true}' (default {})")
    g.add_argument("--n-envs", type=int, default=None,
                   help=f"env workers (SubprocVecEnv, spawn; one process each; default {d['n_envs']})")
    g.add_argument("--n-steps", type=int, default=None,
                   help=f"env steps per worker and update (default {d['n_steps']})")
    g.add_argument("--batch-size", type=int, default=None, help=f"PPO minibatch size (default {d['batch_size']})")
    g.add_argument("--seed", type=int, default=None,
                   help=f"seed of PPO and the workers' paths: seed + n_envs - 1 < {HELD_OUT_SEED0} (default "
                        f"{d['seed']})")
    g.add_argument("--no-normalize", dest="normalize", action="store_false", default=None,
                   help="no VecNormalize (default: observations and rewards normalised)")
    g.add_argument("--ppo-kwargs", default=None, metavar="JSON",
                   help=f"further PPO arguments, keys from {list(k for k in PPO_KEYS if k not in _OWN_PPO)}")
    return ap


_OWN_PPO = ("n_steps", "batch_size")
#: Numeric PPO arguments checked here: (low, high, low excluded).
PPO_RANGES = {"gamma": (0.0, 1.0, True), "gae_lambda": (0.0, 1.0, False), "learning_rate": (0.0, 1.0, True),
              "n_epochs": (1, 1000, False), "clip_range": (0.0, 10.0, True), "ent_coef": (0.0, 10.0, False),
              "vf_coef": (0.0, 10.0, False), "max_grad_norm": (0.0, 1e6, True)}


def _json_option(ap: argparse.ArgumentParser, text: str | None, option: str) -> dict[str, Any] | None:
    if text is None:
        return None
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        ap.error(f"{option} {text!r} is not valid JSON ({exc.msg} at column {exc.colno}); give a JSON object")
    if not isinstance(value, dict):
        ap.error(f"{option} {text!r} must be a JSON object ({{...}})")
    return value


def _normalised(value: Any) -> Any:
    return json.loads(json.dumps(value))


def _resolve(ap: argparse.ArgumentParser, args: argparse.Namespace) -> dict[str, Any]:
    """The run: its settings (fresh, or the resumed run's), folder, checkpoint, target and budget."""
    given = {"preset": args.preset, "control_dt": args.control_dt, "action_type": args.action_type,
             "random_path": _json_option(ap, args.random_path, "--random-path"),
             "env_kwargs": _json_option(ap, args.env_kwargs, "--env-kwargs"), "n_envs": args.n_envs,
             "n_steps": args.n_steps, "batch_size": args.batch_size, "seed": args.seed, "normalize": args.normalize,
             "ppo_kwargs": _json_option(ap, args.ppo_kwargs, "--ppo-kwargs")}
    out = args.out or Path("results/agents") / f"raw_ppo_{given['preset'] or CONFIG_DEFAULTS['preset']}"
    if args.timesteps is not None and args.timesteps < 1:
        ap.error(f"--timesteps {args.timesteps} must be a positive number of env steps")
    if args.max_wall_min is not None and not (math.isfinite(args.max_wall_min) and args.max_wall_min > 0):
        ap.error(f"--max-wall-min {args.max_wall_min} must be a positive number of minutes")
    meta_file = out / "meta.json"
    ckpt = latest_checkpoint(out)
    meta: dict[str, Any] = {}
    if args.resume:
        if ckpt is None:
            ap.error(f"--resume: no checkpoint in {str(out / 'checkpoints')!r} to resume from")
        if not meta_file.is_file():
            ap.error(f"--resume: {str(meta_file)!r} is missing; it holds the run's settings")
        meta = json.loads(meta_file.read_text(encoding="utf-8"))
        config = dict(meta["config"])
        for key, value in given.items():
            if value is not None and _normalised(value) != _normalised(config[key]):
                ap.error(f"--{key.replace('_', '-')} {json.dumps(value)} differs from this run's "
                         f"{json.dumps(config[key])} ({meta_file}); --resume keeps the run's settings")
        target = args.timesteps if args.timesteps is not None else int(meta.get("timesteps", DEFAULT_TIMESTEPS))
        budget = args.max_wall_min if args.max_wall_min is not None else meta.get("max_wall_min")
    else:
        if ckpt is not None:
            ap.error(f"--out {str(out)!r} already holds a run ({ckpt[2]} env steps); pass --resume to continue it "
                     "or choose another --out")
        config = {k: _normalised(v if v is not None else CONFIG_DEFAULTS[k]) for k, v in given.items()}
        target = args.timesteps if args.timesteps is not None else DEFAULT_TIMESTEPS
        budget = args.max_wall_min
    _validate(ap, config)
    return {"config": config, "out": out, "ckpt": ckpt, "meta": meta, "target": int(target),
            "budget_min": None if budget is None else float(budget)}


def _validate(ap: argparse.ArgumentParser, c: dict[str, Any]) -> None:
    """Every setting, with ap.error (exit 2, one line) naming the bad value and what is allowed."""
    if c["preset"] not in preset_names():
        ap.error(f"--preset {c['preset']!r} is not allowed; choose one of {preset_names()}")
    if c["action_type"] not in ("continuous", "discrete"):
        ap.error(f"--action-type {c['action_type']!r} is not allowed; choose continuous or discrete")
    bad = sorted(set(c["env_kwargs"]) & set(OWN_ENV_ARGS))
    if bad:
        ap.error(f"--env-kwargs: {bad} have options of their own (--preset, --control-dt, --action-type, "
                 "--random-path; no render_mode in training)")
    n_envs, n_steps, batch, seed = c["n_envs"], c["n_steps"], c["batch_size"], c["seed"]
    if not 1 <= n_envs <= 64:
        ap.error(f"--n-envs {n_envs} must be from 1 to 64")
    if n_steps < 1:
        ap.error(f"--n-steps {n_steps} must be a positive number of env steps per worker")
    if not 2 <= batch <= n_steps * n_envs:
        ap.error(f"--batch-size {batch} must be from 2 to n_steps x n_envs = {n_steps * n_envs}")
    if seed < 0 or seed + n_envs - 1 >= HELD_OUT_SEED0:
        ap.error(f"--seed {seed} must be >= 0 with seed + n_envs - 1 < {HELD_OUT_SEED0} (seeds from "
                 f"{HELD_OUT_SEED0} on are the held-out evaluation paths)")
    unknown = sorted(set(c["ppo_kwargs"]) - (set(PPO_KEYS) - set(_OWN_PPO)))
    if unknown:
        ap.error(f"--ppo-kwargs: unknown or not allowed key(s) {unknown}; allowed: "
                 f"{[k for k in PPO_KEYS if k not in _OWN_PPO]} (n_steps and batch_size have options)")
    for key, (lo, hi, lo_open) in PPO_RANGES.items():  # PPO itself does not check these
        v = c["ppo_kwargs"].get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                              or v > hi or v < lo or (lo_open and v == lo)):
            ap.error(f"--ppo-kwargs: {key}={v!r} must be a number in {'(' if lo_open else '['}{lo:g}, {hi:g}]")
    from flagellum_env.steer_env import FlagellumSteerEnv

    try:  # the env checks every argument (and control_dt against the preset's step); no physics runs here
        env = FlagellumSteerEnv(**_env_kwargs(c))
    except (ValueError, TypeError) as exc:
        ap.error(" ".join(str(exc).split()))
    try:  # PPO checks its own arguments; built on one env, nothing is stepped
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _new_model(c, _dummy_vec(env))
    except (ValueError, TypeError, AssertionError, KeyError) as exc:
        ap.error(f"--ppo-kwargs {json.dumps(c['ppo_kwargs'])}: {' '.join(str(exc).split())}")
    finally:
        env.close()


def _env_kwargs(c: dict[str, Any]) -> dict[str, Any]:
    return {"path": "random", **c["env_kwargs"], "preset": c["preset"], "control_dt": float(c["control_dt"]),
            "action_type": c["action_type"], "random_path": dict(c["random_path"])}


def _dummy_vec(env):
    from stable_baselines3.common.vec_env import DummyVecEnv

    return DummyVecEnv([lambda: env])


def _new_model(c: dict[str, Any], venv):
    from stable_baselines3 import PPO

    return PPO("MlpPolicy", venv, n_steps=c["n_steps"], batch_size=c["batch_size"], seed=c["seed"], device="cpu",
               verbose=0, **c["ppo_kwargs"])


# --- vector env --------------------------------------------------------------------------------
def _vec_env(c: dict[str, Any]):
    """n_envs FlagellumSteer-v0 workers (a SubprocVecEnv, spawn, for more than one), VecMonitor. The
    workers start with SIGINT and SIGTERM ignored (inherited), so only this process handles them."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    from flagellum_env.steer_env import FlagellumSteerEnv

    fns = [functools.partial(FlagellumSteerEnv, **_env_kwargs(c)) for _ in range(c["n_envs"])]
    if c["n_envs"] == 1:
        venv = DummyVecEnv(fns)
    else:
        old = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            venv = SubprocVecEnv(fns, start_method="spawn")
        finally:
            for s, h in old.items():
                signal.signal(s, h)
    return VecMonitor(venv, info_keywords=INFO_KEYS)


def _base_vec(venv):
    while hasattr(venv, "venv"):
        venv = venv.venv
    return venv


def _children_cpu_s(venv) -> float:
    """CPU seconds (user + system) of the live env worker processes; 0 without workers, nan where
    /proc cannot be read."""
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
def _append_rows(file: Path, fields: tuple[str, ...], rows: list[dict[str, Any]]) -> None:
    if not rows:
        return
    new = not file.is_file() or file.stat().st_size == 0
    with open(file, "a", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        if new:
            w.writeheader()
        w.writerows(rows)


def _truncate_rows(file: Path, column: str, max_steps: int) -> int:
    """Drop the rows of ``file`` whose ``column`` exceeds ``max_steps``; the number dropped."""
    if not file.is_file():
        return 0
    with open(file, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        fields = reader.fieldnames
        rows = list(reader)
    keep = [r for r in rows if int(r[column]) <= max_steps]
    if len(keep) != len(rows):
        tmp = file.with_suffix(file.suffix + ".tmp")
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=fields)
            w.writeheader()
            w.writerows(keep)
        os.replace(tmp, file)
    return len(rows) - len(keep)


def _write_json(file: Path, data: dict[str, Any]) -> None:
    tmp = file.with_suffix(file.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, file)


def _state_file(out: Path, steps: int) -> Path:
    return out / "checkpoints" / f"{CHECKPOINT_PREFIX}_state_{steps}_steps.json"


def _save_checkpoint(model, venv, out: Path, state: dict[str, Any]) -> None:
    """Statistics and state first, the model last (written aside, then renamed): a checkpoint whose
    model file exists is complete (``agents.ppo_training.latest_checkpoint``)."""
    steps = int(state["env_steps"])
    folder = out / "checkpoints"
    if hasattr(venv, "obs_rms"):
        venv.save(str(folder / f"{CHECKPOINT_PREFIX}_vecnormalize_{steps}_steps.pkl"))
    else:  # latest_checkpoint asks for a statistics file: without VecNormalize, an empty marker
        (folder / f"{CHECKPOINT_PREFIX}_vecnormalize_{steps}_steps.pkl").write_bytes(b"")
    _write_json(_state_file(out, steps), state)
    tmp = folder / f"tmp_{CHECKPOINT_PREFIX}_{steps}.zip"
    model.save(str(tmp))
    os.replace(tmp, folder / f"{CHECKPOINT_PREFIX}_{steps}_steps.zip")


def _loadavg() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _mean(values: list[float]) -> float:
    return float(np.mean(values)) if values else math.nan


def _r(x: float, nd: int = 3) -> float | str:
    return "" if x is None or not math.isfinite(x) else round(float(x), nd)


# --- training ----------------------------------------------------------------------------------
class _Stop:
    """Why training should stop (None: go on), set by the signal handlers and the budget."""

    def __init__(self) -> None:
        self.reason: str | None = None
        self.signum: int | None = None

    def handler(self, signum, frame) -> None:  # noqa: ARG002
        if self.signum is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt  # second Ctrl-C: abort now
        self.signum, self.reason = signum, signal.Signals(signum).name
        print(f"\n{PROG}: {self.reason}: stopping after the current env step (the finished updates are saved; "
              "Ctrl-C again aborts)", file=sys.stderr, flush=True)


def _recorder_class():
    from stable_baselines3.common.callbacks import BaseCallback

    class Recorder(BaseCallback):
        """Episodes as they end; after each update a progress row, then a checkpoint; the budget."""

        def __init__(self, run: dict[str, Any], state: dict[str, Any], stop: _Stop, bar, t0: float,
                     cpu0: float) -> None:
            super().__init__()
            self.run, self.state, self.stop, self.bar = run, state, stop, bar
            self.t0, self.cpu0 = t0, cpu0
            self.wall_before, self.cpu_before = float(state["wall_s"]), float(state["cpu_s"])
            self.pending = False
            self.episodes: list[dict[str, Any]] = []
            self.t_rollout = self.t_update = self.rollout_s = 0.0
            self.last_interval_s: float | None = None

        def wall(self) -> float:
            return self.wall_before + time.perf_counter() - self.t0

        def cpu(self) -> float:
            return self.cpu_before + time.process_time() - self.cpu0 + _children_cpu_s(self.training_env)

        def _on_rollout_start(self) -> None:
            self._flush()
            budget = self.run["budget_min"]
            if budget is not None and self.stop.reason is None and self.last_interval_s is not None \
                    and self.wall() + self.last_interval_s > 60.0 * budget:
                self.stop.reason = "wall-time budget"
            self.t_rollout = time.perf_counter()
            self.episodes = []

        def _on_step(self) -> bool:
            rows = []
            for i, info in enumerate(self.locals.get("infos", [])):
                ep = info.get("episode")
                if ep is None:
                    continue
                rec = {"env_steps": int(self.num_timesteps), "wall_s": round(self.wall(), 1), "env": i,
                       "return": round(float(ep["r"]), 4), "length": int(ep["l"]),
                       "is_success": bool(ep.get("is_success")), "buckling_events": ep.get("buckling_events"),
                       "waypoints_reached": ep.get("waypoint_index"), "sim_time_s": ep.get("sim_time_s")}
                rows.append(rec)
            if rows:
                self.episodes.extend(rows)
                _append_rows(self.run["out"] / "episodes.csv", EPISODE_FIELDS, rows)
            self.bar.update(self.training_env.num_envs)
            return self.stop.reason is None

        def _on_rollout_end(self) -> None:
            self.rollout_s = time.perf_counter() - self.t_rollout
            self.t_update = time.perf_counter()
            self.pending = True

        def _on_training_end(self) -> None:
            self._flush()

        def _flush(self) -> None:
            """The update that just finished: its row, then its checkpoint."""
            if not self.pending:
                return
            self.pending = False
            st, eps = self.state, self.episodes
            update_s = time.perf_counter() - self.t_update
            steps = int(self.num_timesteps)
            done = steps - int(st["env_steps"])
            wall, cpu = self.wall(), self.cpu()
            st.update(env_steps=steps, updates=int(st["updates"]) + 1, wall_s=round(wall, 2), cpu_s=round(cpu, 2),
                      episodes_total=int(st["episodes_total"]) + len(eps),
                      successes_total=int(st["successes_total"]) + sum(e["is_success"] for e in eps))
            logged = getattr(self.model.logger, "name_to_value", {})
            load = _loadavg()
            row = {"update": st["updates"], "env_steps": steps, "wall_s": _r(wall, 1), "cpu_s": _r(cpu, 1),
                   "rollout_s": _r(self.rollout_s, 2), "update_s": _r(update_s, 2),
                   "steps_per_s": _r(done / (self.rollout_s + update_s), 4),
                   "env_steps_per_s": _r(done / self.rollout_s, 4) if self.rollout_s > 0 else "",
                   "episodes": len(eps), "ep_return_mean": _r(_mean([e["return"] for e in eps])),
                   "ep_length_mean": _r(_mean([e["length"] for e in eps]), 1),
                   "success_rate": _r(_mean([float(e["is_success"]) for e in eps])),
                   "buckling_events_mean": _r(_mean([e["buckling_events"] for e in eps
                                                     if e["buckling_events"] is not None])),
                   "waypoints_reached_mean": _r(_mean([e["waypoints_reached"] for e in eps
                                                       if e["waypoints_reached"] is not None])),
                   "episodes_total": st["episodes_total"], "successes_total": st["successes_total"],
                   **{k: _r(logged[v], 5) if v in logged else "" for k, v in TRAIN_STATS.items()},
                   "load1": load[0] if load else ""}
            _append_rows(self.run["out"] / "progress.csv", PROGRESS_FIELDS, [row])  # row first: see --resume
            st["env_rng"] = _env_rng_states(self.training_env)
            _save_checkpoint(self.model, self.training_env, self.run["out"], st)
            self.last_interval_s = self.rollout_s + update_s
            self.run["session"].update(steps_to=steps, wall_s=round(time.perf_counter() - self.t0, 1))
            _write_meta(self.run)
            ret = row["ep_return_mean"]
            self.bar.set_postfix_str(f"upd {st['updates']}, {row['steps_per_s']} steps/s"
                                     + (f", return {ret}, success {row['success_rate']}" if eps else ""))

    return Recorder


def _write_meta(run: dict[str, Any]) -> None:
    _write_json(run["out"] / "meta.json", run["meta"])


def train(run: dict[str, Any], progress: bool = True, t0: float | None = None, cpu0: float | None = None) -> int:
    """Train (or resume) the run of ``_resolve``; the exit status. ``t0`` / ``cpu0``: perf_counter and
    process_time when the session started (default: now)."""
    import stable_baselines3
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecNormalize
    from tqdm import tqdm

    torch.set_num_threads(1)  # the env workers use the cores; the small MLP does not need them
    t0 = time.perf_counter() if t0 is None else t0
    cpu0 = time.process_time() if cpu0 is None else cpu0
    c, out, ckpt = run["config"], run["out"], run["ckpt"]
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    state = {"env_steps": 0, "updates": 0, "wall_s": 0.0, "cpu_s": 0.0, "episodes_total": 0, "successes_total": 0}
    if ckpt is not None:
        state_file = _state_file(out, ckpt[2])
        if not state_file.is_file():
            raise SystemExit(f"{PROG}: error: {str(state_file)!r} is missing; cannot resume that checkpoint")
        state = json.loads(state_file.read_text(encoding="utf-8"))
    # rows past the checkpoint (an update that did not finish, or a fresh run's leftovers) are dropped
    dropped = {name: _truncate_rows(out / name, "env_steps", int(state["env_steps"]))
               for name in ("progress.csv", "episodes.csv")}
    if any(dropped.values()):
        print(f"{PROG}: starting at {state['env_steps']} env steps; dropped rows past it: {dropped}", file=sys.stderr)
    meta = run["meta"]
    meta.update({"script": "scripts/train_raw_ppo.py", "env_id": ENV_ID, "policy": "MlpPolicy", "config": c,
                 "env_kwargs": _env_kwargs(c), "timesteps": run["target"], "max_wall_min": run["budget_min"],
                 "commit": meta.get("commit") or git_commit(),
                 "versions": {"python": platform.python_version(), "stable_baselines3": stable_baselines3.__version__,
                              "torch": torch.__version__, "numpy": np.__version__},
                 "machine": {"cpu_count": os.cpu_count(), "platform": platform.platform()}})
    session = {"started": _now(), "ended": None, "commit": git_commit(), "loadavg_start": _loadavg(),
               "loadavg_end": None, "steps_from": int(state["env_steps"]), "steps_to": int(state["env_steps"]),
               "wall_s": 0.0, "cpu_s": None, "status": "running", "resumed": ckpt is not None}
    meta.setdefault("sessions", []).append(session)
    meta.setdefault("date", session["started"])
    run["session"] = session
    _write_meta(run)

    stop = _Stop()
    old_handlers: dict[int, Any] = {}
    venv = model = None
    bar = tqdm(total=run["target"], initial=int(state["env_steps"]), unit="step", desc="env steps",
               disable=not progress, dynamic_ncols=True)
    status, code = "running", 0
    try:
        raw = _vec_env(c)
        if ckpt is not None:
            venv = VecNormalize.load(str(ckpt[1]), raw) if c["normalize"] else raw
            venv.training = True
            model = PPO.load(str(ckpt[0]), env=venv, device="cpu")
            _base_vec(venv)._reset_seeds()  # PPO.load seeded the workers again (seed + rank): keep their generators
            _restore_env_rngs(venv, state["env_rng"])
            set_random_seed(c["seed"] + int(state["env_steps"]))  # torch, numpy, random: the policy's sampling
        else:
            venv = VecNormalize(raw, gamma=float(c["ppo_kwargs"].get("gamma", 0.99))) if c["normalize"] else raw
            model = _new_model(c, venv)  # seeds the workers: seed + rank, at their first reset
        for s in (signal.SIGINT, signal.SIGTERM):
            old_handlers[s] = signal.signal(s, stop.handler)
        recorder = _recorder_class()(run, state, stop, bar, t0, cpu0)
        remaining = run["target"] - int(model.num_timesteps)
        if remaining > 0:
            model.learn(remaining, callback=recorder, reset_num_timesteps=ckpt is None)
        if stop.reason is None:
            status = "finished"
        else:
            status = f"stopped: {stop.reason}"
            code = 128 + stop.signum if stop.signum is not None else 0
    except KeyboardInterrupt:
        status, code = "aborted: second SIGINT", 130
    except BaseException as exc:
        status = f"failed: {type(exc).__name__}: {exc}"
        raise
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)
        bar.close()
        cpu_children = _children_cpu_s(venv) if venv is not None else 0.0
        if venv is not None:
            try:
                venv.close()
            except (EOFError, OSError, BrokenPipeError) as exc:
                print(f"{PROG}: closing the env workers: {exc}", file=sys.stderr)
        session.update(ended=_now(), loadavg_end=_loadavg(), status=status,
                       wall_s=round(time.perf_counter() - t0, 1),
                       cpu_s=round(time.process_time() - cpu0 + cpu_children, 1))
        meta["total"] = {"env_steps": int(state["env_steps"]), "updates": int(state["updates"]),
                         "wall_s": state["wall_s"], "cpu_s": state["cpu_s"],
                         "episodes": int(state["episodes_total"]), "successes": int(state["successes_total"])}
        meta["updated"] = session["ended"]
        _write_meta(run)
    newest = latest_checkpoint(out)
    if newest is not None and c["normalize"]:
        shutil.copyfile(newest[0], out / "model.zip")
        shutil.copyfile(newest[1], out / "vecnormalize.pkl")
    elif newest is not None:
        shutil.copyfile(newest[0], out / "model.zip")
    if (out / "progress.csv").is_file():
        plot_learning_curve(out)
    steps, wall = int(state["env_steps"]), float(state["wall_s"])
    print(f"{PROG}: {status} at {steps} env steps, {wall / 60:.1f} min of training wall time"
          + (f", {steps / wall:.3f} env steps/s overall" if wall > 0 and steps else "") + f"; {out}")
    if status != "finished":
        print(f"{PROG}: continue with: python scripts/train_raw_ppo.py --out {out} --resume", file=sys.stderr)
    return code


# --- learning curve ----------------------------------------------------------------------------
def _read_progress(file: Path) -> dict[str, np.ndarray]:
    if not file.is_file():
        raise FileNotFoundError(f"{str(file)!r} does not exist; train first")
    with open(file, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{str(file)!r} holds no update yet")
    return {k: np.array([float(r[k]) if r[k] not in ("", None) else np.nan for r in rows]) for k in rows[0]}


def _windowed(values: np.ndarray, weights: np.ndarray, window: int) -> np.ndarray:
    """Mean of ``values`` weighted by ``weights`` (episodes) over the last ``window`` updates."""
    v = np.where(weights > 0, np.nan_to_num(values), 0.0) * weights
    out = np.full(len(values), np.nan)
    for i in range(len(values)):
        lo = max(0, i - window + 1)
        n = weights[lo:i + 1].sum()
        if n > 0:
            out[i] = v[lo:i + 1].sum() / n
    return out


def plot_learning_curve(out: Path | str, window: int = 5) -> Path:
    """``out/learning_curve.png``: mean episode return and success rate of each update (markers sized
    by its episodes) and their mean over the last ``window`` updates, against env steps and wall hours."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    d = _read_progress(out / "progress.csv")
    meta_file = out / "meta.json"
    meta = json.loads(meta_file.read_text(encoding="utf-8")) if meta_file.is_file() else {}
    n = d["episodes"]
    has = n > 0
    xs = {"env steps": d["env_steps"], "training wall time (h)": d["wall_s"] / 3600.0}
    ys = {"mean episode return": d["ep_return_mean"], "success rate": d["success_rate"]}
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharey="row", constrained_layout=True)
    for j, (xl, x) in enumerate(xs.items()):
        for i, (yl, y) in enumerate(ys.items()):
            ax = axes[i, j]
            ax.scatter(x[has], y[has], s=12 + 8 * n[has], alpha=0.45, color="tab:blue", label="per update")
            ax.plot(x, _windowed(y, n, window), color="tab:red", lw=1.5, label=f"last {window} updates")
            ax.set_xlabel(xl)
            ax.grid(alpha=0.3)
            if j == 0:
                ax.set_ylabel(yl)
    axes[1, 0].set_ylim(-0.05, 1.05)
    axes[0, 0].legend(loc="best", fontsize=8)
    c = meta.get("config", {})
    steps, wall = d["env_steps"][-1], d["wall_s"][-1]
    fig.suptitle(f"PPO from scratch on {ENV_ID}, preset {c.get('preset', '?')}, control_dt {c.get('control_dt', '?')} s,"
                 f" {c.get('n_envs', '?')} envs: {int(steps)} env steps in {wall / 3600:.2f} h "
                 f"({steps / wall:.2f} steps/s), {int(np.nansum(n))} episodes", fontsize=10)
    file = out / "learning_curve.png"
    fig.savefig(file, dpi=110)
    plt.close(fig)
    return file


# --- entry point -------------------------------------------------------------------------------
def main(argv: list[str] | None = None, progress: bool = True) -> int:
    t0, cpu0 = time.perf_counter(), time.process_time()  # the session's wall and CPU time count from here
    ap = _parser()
    args = ap.parse_args(argv)
    if args.plot:
        others = [f"--{k.replace('_', '-')}" for k, v in vars(args).items()
                  if k not in ("out", "plot") and v not in (None, False)]
        if others:
            ap.error(f"--plot only draws the curve of --out; it takes no {others}")
        out = args.out or Path("results/agents") / f"raw_ppo_{DEFAULT_PRESET}"
        try:
            file = plot_learning_curve(out)
        except (FileNotFoundError, ValueError) as exc:
            ap.error(f"--plot: {exc}")
        print(f"wrote {file}")
        return 0
    run = _resolve(ap, args)
    done = run["ckpt"][2] if run["ckpt"] is not None else 0
    if run["ckpt"] is not None and done >= run["target"]:
        print(f"{PROG}: {run['out']} already holds {done} env steps (--timesteps {run['target']}); nothing to do")
        return 0
    return train(run, progress=progress, t0=t0, cpu0=cpu0)


if __name__ == "__main__":
    raise SystemExit(main())
