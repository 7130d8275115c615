"""From-scratch PPO on the raw FlagellumSteer-v0 (issue #17, item 4): learning curve, env steps/s, wall time.

stable-baselines3 PPO with ``MlpPolicy`` and a fresh network, ``VecNormalize`` on observations and rewards, on
the raw env: one action = the motor speed for ``control_dt`` simulated seconds (default 2 s), continuous by
default; no planner, no turn map. Default task, "one-turn paths": one waypoint 10-16 cm from the start, 30-150
deg off the initial heading, in the x-y plane, reach radius 1.5 cm. The library is ``experiments.raw_ppo``.

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

    progress.csv        stable-baselines3's logger (CSV output; the same table on stdout unless --quiet): one
                        row per PPO update, SB3's time/, rollout/ and train/ columns and this run's run/ columns
                        (update, wall and CPU seconds of the whole run, episodes and successes, 1-min load)
    monitor.csv         VecMonitor: one row per finished training episode (return r, length l, t, and
                        is_success, buckling_events, waypoint_index, sim_time_s)
    checkpoints/        CheckpointCallback after every update: rl_model_<n>_steps.zip and
                        rl_model_vecnormalize_<n>_steps.pkl, beside rl_model_state_<n>_steps.json (wall/CPU
                        time, episode counts and the env workers' path generators)
    model.zip, vecnormalize.pkl   the newest checkpoint's policy and statistics (at the end of a session)
    meta.json           settings, git commit, versions, machine, one entry per session
    learning_curve.png  return and success rate against env steps and against training wall hours

``--resume`` continues from the newest checkpoint (rows of progress.csv and monitor.csv past it are dropped, so
no step is counted twice) and refuses settings that differ from the run's, naming the first. Ctrl-C or SIGTERM
stops after the current env step, keeps the finished updates and exits 130 / 143; a second Ctrl-C aborts at
once. ``--timesteps`` is rounded up to whole updates (n_steps x n_envs). ``--max-wall-min`` stops before an
update that would end past the budget (judged by the last one).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, NoReturn

from agents.ppo_config import HELD_OUT_SEED0, PPO_KEYS
from experiments.raw_ppo import (CONFIG_DEFAULTS, DEFAULT_TIMESTEPS, ENV_ID, ONE_TURN, OWN_PPO, resolve_run,
                            train_raw_ppo)
from physics.presets import DEFAULT_PRESET, preset_names

PROG = "train_raw_ppo.py"


class _Parser(argparse.ArgumentParser):
    """Errors are one line ``train_raw_ppo.py: error: ...``, status 2 (as the ``flagellum`` CLI's)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{PROG}: error: {' '.join(message.split())} (see '{PROG} --help')\n")


def _parser() -> argparse.ArgumentParser:
    d = CONFIG_DEFAULTS
    ap = _Parser(prog=PROG, description=__doc__.splitlines()[0], epilog="\n".join(__doc__.splitlines()[6:]),
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=None, help="run folder (default: results/agents/raw_ppo_PRESET)")
    ap.add_argument("--resume", action="store_true", help="continue the run in --out from its newest checkpoint")
    ap.add_argument("--plot", action="store_true", help="only draw OUT/learning_curve.png from OUT/progress.csv")
    ap.add_argument("--timesteps", type=int, default=None,
                    help=f"env steps to train in all (all workers; default {DEFAULT_TIMESTEPS}, rounded up to "
                         "whole updates)")
    ap.add_argument("--max-wall-min", type=float, default=None,
                    help="stop before an update that would take the run's training wall time past this (minutes)")
    ap.add_argument("--quiet", action="store_true", help="no table per update on stdout (progress.csv only)")
    g = ap.add_argument_group("run settings (kept by --resume)")
    g.add_argument("--preset", default=None, help=f"physics preset, one of {preset_names()} (default {d['preset']})")
    g.add_argument("--control-dt", type=float, default=None,
                   help=f"simulated seconds per env step (default {d['control_dt']})")
    g.add_argument("--action-type", default=None, help="continuous (default) or discrete")
    g.add_argument("--random-path", default=None, metavar="JSON",
                   help=f"RandomPathConfig fields of the training paths (default {json.dumps(ONE_TURN)})")
    g.add_argument("--env-kwargs", default=None, metavar="JSON",
                   help=f"further {ENV_ID} arguments, e.g. '{{\"randomize\": true}}' (default {{}})")
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
                   help=f"further PPO arguments, keys from {[k for k in PPO_KEYS if k not in OWN_PPO]}")
    return ap


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


def draw_learning_curve(out: Path) -> Path:
    """``out/learning_curve.png`` from ``out/progress.csv``; FileNotFoundError / ValueError when there is none."""
    from experiments.raw_ppo_plots import raw_ppo_figure

    meta_file = out / "meta.json"
    c = json.loads(meta_file.read_text(encoding="utf-8")).get("config", {}) if meta_file.is_file() else {}
    fig = raw_ppo_figure(out, f"PPO from scratch on {ENV_ID}, preset {c.get('preset', '?')}, control_dt "
                              f"{c.get('control_dt', '?')} s, {c.get('n_envs', '?')} envs")
    fig.savefig(out / "learning_curve.png", dpi=110)
    return out / "learning_curve.png"


def _plot(ap: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    others = [f"--{k.replace('_', '-')}" for k, v in vars(args).items()
              if k not in ("out", "plot") and v not in (None, False)]
    if others:
        ap.error(f"--plot only draws the curve of --out; it takes no {others}")
    try:
        file = draw_learning_curve(args.out or Path("results/agents") / f"raw_ppo_{DEFAULT_PRESET}")
    except (FileNotFoundError, ValueError) as exc:
        ap.error(f"--plot: {exc}")
    print(f"wrote {file}")
    return 0


def main(argv: list[str] | None = None, progress: bool = True) -> int:
    """Train, resume or plot (module docstring); the exit status. ``progress=False`` is ``--quiet``."""
    t0, cpu0 = time.perf_counter(), time.process_time()  # the session's wall and CPU time count from here
    ap = _parser()
    args = ap.parse_args(argv)
    if args.plot:
        return _plot(ap, args)
    given = {"preset": args.preset, "control_dt": args.control_dt, "action_type": args.action_type,
             "random_path": _json_option(ap, args.random_path, "--random-path"),
             "env_kwargs": _json_option(ap, args.env_kwargs, "--env-kwargs"), "n_envs": args.n_envs,
             "n_steps": args.n_steps, "batch_size": args.batch_size, "seed": args.seed, "normalize": args.normalize,
             "ppo_kwargs": _json_option(ap, args.ppo_kwargs, "--ppo-kwargs")}
    out = args.out or Path("results/agents") / f"raw_ppo_{args.preset or DEFAULT_PRESET}"
    try:
        run = resolve_run(out, args.resume, given, args.timesteps, args.max_wall_min)
    except ValueError as exc:
        ap.error(str(exc))
    done = run.ckpt[2] if run.ckpt is not None else 0
    if run.ckpt is not None and done >= run.target:
        print(f"{PROG}: {out} already holds {done} env steps (--timesteps {run.target}); nothing to do")
        return 0
    try:
        result = train_raw_ppo(run, stdout=progress and not args.quiet, prog=PROG, t0=t0, cpu0=cpu0)
    except ValueError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    try:
        draw_learning_curve(out)
    except (FileNotFoundError, ValueError):  # no update finished yet: nothing to draw
        pass
    wall = result.wall_s
    print(f"{PROG}: {result.status} at {result.env_steps} env steps, {wall / 60:.1f} min of training wall time"
          + (f", {result.env_steps / wall:.3f} env steps/s overall" if wall > 0 and result.env_steps else "")
          + f"; {out}")
    if result.status != "finished":
        print(f"{PROG}: continue with: python scripts/train_raw_ppo.py --out {out} --resume", file=sys.stderr)
    return result.code


if __name__ == "__main__":
    raise SystemExit(main())
