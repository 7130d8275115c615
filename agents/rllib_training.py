"""Train PPO with Ray RLlib (new API stack, PyTorch on the CPU); env runners spread over a Ray cluster; resumable.

``train(config, out_dir)`` runs RLlib's PPO on ``gymnasium.make(config.env_id, **config.env_kwargs)``: the env
runners (``num_env_runners`` Ray actors, each stepping ``num_envs_per_env_runner`` envs) sample, the learner
(in this process) updates the policy once per iteration of ``train_batch_size`` env steps. The env runners are
other processes, possibly on other machines: they find the ids through ``make_env``, which imports ``agents``
(the package must be installed on every node, in the Python that ``ray start`` ran from). ``out_dir`` receives::

    run.json         the run's identity (``RayTrainConfig.identity``) and its hash; a resume must match it
    config.yml       the configuration trained from (the last run's)
    progress.csv     one row per iteration (PROGRESS_FIELDS; appended, survives resume)
    checkpoints/iter_NNNNNN/   RLlib's checkpoint (``Algorithm.save_to_path``) and flagellum.json (the env, the
                     observation and action shapes, the counters); the newest KEEP_CHECKPOINTS are kept

``resume=True`` restores the newest complete checkpoint (one with flagellum.json) and continues its counters;
Ctrl-C or SIGTERM finish the current iteration, save a checkpoint and raise ``TrainingInterrupted`` (a second
signal stops at once; the newest checkpoint stays). Ray is shut down on the way out, so no worker outlives the run
(a local Ray's processes end with it; on a cluster the actors end, the nodes stay).

Wall s and CPU s in progress.csv accumulate over resumes; CPU s is this process's CPU time (the driver and the
learner) plus each env runner process's (its start included), as they report it after each sample.
"""

from __future__ import annotations

import csv
import json
import logging
import os
import shutil
import socket
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ray.rllib.callbacks.callbacks import RLlibCallback

from agents.rllib_config import CHECKPOINT_PREFIX, INFO_FILE, RESUMABLE_KEYS, RayTrainConfig
from batch.store import drop_rows_after
from physics.errors import is_interrupt

#: RLlib's name of an env of this package: this prefix and the Gymnasium id.
ENV_PREFIX = "flagellum:"
KEEP_CHECKPOINTS = 3
PROGRESS_FIELDS = ("iteration", "env_steps", "wall_s", "cpu_s", "episodes", "episode_return_mean", "success_rate",
                   "env_runners")
#: Seconds to wait for a cluster's head to accept a connection.
CONNECT_TIMEOUT_S = 3.0


@dataclass(frozen=True)
class RayTrainResult:
    out_dir: Path
    iterations: int
    env_steps: int
    wall_time_s: float
    cpu_time_s: float
    stopped_by_budget: bool
    checkpoint: Path | None
    interrupted: bool = False


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped ``train``; ``result.checkpoint`` is the newest checkpoint (``--resume``)."""

    def __init__(self, result: RayTrainResult) -> None:
        super().__init__(f"training interrupted after {result.iterations} iterations; saved in {result.out_dir}")
        self.result = result


def make_env(env_config: dict[str, Any]):
    """RLlib's env creator: ``gymnasium.make(env_id, **env_kwargs)`` after ``import agents`` (which registers the
    FlagellumTurn and FlagellumBurst ids in the env runner's process)."""
    import gymnasium as gym

    import agents  # noqa: F401  (registers the ids in this process)

    return gym.make(env_config["env_id"], **dict(env_config.get("env_kwargs") or {}))


def check_env(config: RayTrainConfig) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Make the config's env once here (a bad ``env_kwargs`` fails now, with its message, not in an env runner);
    its (observation, action) shapes."""
    try:
        env = make_env({"env_id": config.env_id, "env_kwargs": config.env_kwargs})
    except (TypeError, ValueError) as exc:
        raise ValueError(f"training config {config.source!r}: {config.name}.env_kwargs: "
                         f"{' '.join(str(exc).split())}") from None
    try:
        return tuple(env.observation_space.shape), tuple(env.action_space.shape)
    finally:
        env.close()


def check_address(address: str | None, timeout_s: float = CONNECT_TIMEOUT_S) -> str | None:
    """``address`` as given (None: a local Ray); ValueError naming the address when nothing answers at ``host:port``
    within ``timeout_s``. "auto" (the cluster ``ray start`` started on this machine) is resolved by ``ray.init``,
    whose failure ``start_ray`` reports in one line."""
    if address is None or address == "auto":
        return address
    allowed = ("allowed: the address a running 'ray start --head' printed (host:port), 'auto' for the cluster "
               "started on this machine, or no address for a local Ray")
    resolved = address
    host, _, port = resolved.rpartition(":")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise ValueError(f"--address {address!r}: no Ray head answers at {resolved} within {timeout_s:g} s "
                         f"({exc.strerror or exc}); {allowed}") from None
    return resolved


def algorithm_config(config: RayTrainConfig):
    """RLlib's ``PPOConfig`` for ``config`` (new API stack)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.tune.registry import register_env

    register_env(ENV_PREFIX + config.env_id, make_env)
    runners: dict[str, Any] = {"num_env_runners": config.num_env_runners,
                               "num_envs_per_env_runner": config.num_envs_per_env_runner}
    if config.normalize_obs:
        runners["env_to_module_connector"] = _mean_std_filter
    return (PPOConfig()
            .environment(ENV_PREFIX + config.env_id,
                         env_config={"env_id": config.env_id, "env_kwargs": dict(config.env_kwargs)})
            .framework("torch")
            .env_runners(**runners)
            .learners(num_learners=0)
            .training(train_batch_size_per_learner=config.train_batch_size, minibatch_size=config.minibatch_size,
                      num_epochs=config.num_epochs, lr=config.lr, gamma=config.gamma, lambda_=config.gae_lambda)
            .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(config.net_arch)))
            .callbacks(_Metrics)
            .debugging(seed=config.seed, log_level="ERROR"))


def _mean_std_filter(env=None, spaces=None, device=None):
    from ray.rllib.connectors.env_to_module import MeanStdFilter

    return MeanStdFilter()


class _Metrics(RLlibCallback):
    """Per iteration, summed over the env runners: episodes ended and succeeded (the last ``info["is_success"]``),
    and the env runners' process CPU seconds since their last report (the first one counts from the start)."""

    def on_episode_end(self, *, episode, metrics_logger=None, **kwargs) -> None:
        info = episode.get_infos(-1) or {}
        metrics_logger.log_value("flagellum_episodes", 1, reduce="sum")
        if "is_success" in info:
            metrics_logger.log_value("flagellum_with_success", 1, reduce="sum")
            metrics_logger.log_value("flagellum_successes", int(bool(info["is_success"])), reduce="sum")

    def on_sample_end(self, *, env_runner=None, metrics_logger=None, **kwargs) -> None:
        # one callbacks object per env runner process: its own clock
        now = time.process_time()
        last = getattr(self, "cpu_reported_s", 0.0)
        self.cpu_reported_s = now
        metrics_logger.log_value("flagellum_cpu_s", now - last, reduce="sum")


def checkpoints(out_dir: Path) -> list[Path]:
    """The complete checkpoints in ``out_dir/checkpoints``, oldest first."""
    folder = Path(out_dir) / "checkpoints"
    found = [p for p in folder.glob(f"{CHECKPOINT_PREFIX}*") if (p / INFO_FILE).is_file()]
    return sorted(found, key=lambda p: checkpoint_info(p)["iteration"])


def checkpoint_info(folder: Path) -> dict[str, Any]:
    """What a checkpoint's flagellum.json holds: env_id, env_kwargs, observation_shape, action_shape,
    normalize_obs, config_hash and the counters (iteration, env_steps, wall_s, cpu_s)."""
    return json.loads((Path(folder) / INFO_FILE).read_text(encoding="utf-8"))


def _check_same_run(out: Path, config: RayTrainConfig) -> None:
    """ValueError naming the first differing key when ``out`` holds a run of another config."""
    run_file = out / "run.json"
    old = json.loads(run_file.read_text(encoding="utf-8")) if run_file.is_file() else {}
    if old.get("config_hash") == config.identity_hash():
        return
    ident, prev = config.identity(), old.get("identity", {})
    key = next((k for k in sorted(set(ident) | set(prev)) if ident.get(k) != prev.get(k)), "config_hash")
    raise ValueError(f"--resume: {str(out)!r} holds a run of another config (config hash {old.get('config_hash')} "
                     f"there, {config.identity_hash()} here; {key} is {prev.get(key)!r} there and {ident.get(key)!r} "
                     f"here); allowed: the same config (only {', '.join(RESUMABLE_KEYS)} may change) or another --out")


def start_ray(address: str | None, config: RayTrainConfig) -> None:
    """Start a local Ray or connect to the cluster at ``address``, keeping this process's SIGTERM handler (``ray.init``
    sets one that exits at once)."""
    import signal

    import ray

    sigterm = signal.getsignal(signal.SIGTERM)
    try:
        _connect(ray, address, config)
    finally:
        if sigterm is not None and signal.getsignal(signal.SIGTERM) is not sigterm:
            try:
                signal.signal(signal.SIGTERM, sigterm)
            except ValueError:  # not the main thread: Ray set nothing either
                pass


def _connect(ray, address: str | None, config: RayTrainConfig) -> None:
    logging.getLogger("ray.rllib").setLevel(logging.ERROR)  # "You are running PPO on the new API stack!"
    quiet = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.ERROR,
             "configure_logging": True}
    if address is None:  # a local Ray: at least one CPU slot per env runner (Ray would wait forever otherwise)
        ray.init(num_cpus=max(os.cpu_count() or 1, config.num_env_runners), **quiet)
        return
    try:
        ray.init(address=address, **quiet)
    except ConnectionError as exc:
        raise ValueError(f"--address {address!r}: {' '.join(str(exc).split())}; allowed: the address a running "
                         "'ray start --head' printed (host:port), or 'auto' on a machine where it runs") from None
    cpus = float(ray.cluster_resources().get("CPU", 0.0))
    if config.num_env_runners > cpus:
        ray.shutdown()
        raise ValueError(f"{config.name}.num_env_runners={config.num_env_runners} is not allowed on the cluster at "
                         f"{address}: it has {cpus:g} CPUs; allowed: at most {cpus:g} env runners (one CPU each)")


def train(config: RayTrainConfig, out_dir: str | Path, resume: bool = False, progress: bool = True,
          config_text: str | None = None) -> RayTrainResult:
    """Train (or resume) ``config`` into ``out_dir`` (module docstring). Every check (the folder, a resume's config,
    the env's arguments, the cluster's address) is done before Ray starts."""
    out = Path(out_dir)
    done = checkpoints(out)
    if resume and not done:
        raise ValueError(f"--resume: no checkpoint in {str(out / 'checkpoints')!r} to resume from")
    if not resume and (out / "checkpoints").exists() and any((out / "checkpoints").iterdir()):
        raise ValueError(f"{str(out)!r} already holds a training run; pass --resume to continue it or choose "
                         "another --out")
    start = checkpoint_info(done[-1]) if resume else {"iteration": 0, "env_steps": 0, "wall_s": 0.0, "cpu_s": 0.0}
    if resume:
        _check_same_run(out, config)
        if config.iterations is not None and start["iteration"] >= config.iterations:
            raise ValueError(f"--resume: the run in {str(out)!r} has done {start['iteration']} iterations, "
                             f"iterations={config.iterations}: nothing to resume; allowed: a config with more "
                             "iterations")
    obs_shape, act_shape = check_env(config)
    address = check_address(config.address)

    import ray
    import torch

    torch.set_num_threads(1)  # the env runners use the cores; the small MLP does not need them
    out.mkdir(parents=True, exist_ok=True)
    (out / "checkpoints").mkdir(exist_ok=True)
    (out / "run.json").write_text(json.dumps({"config_hash": config.identity_hash(), "identity": config.identity()},
                                             indent=1) + "\n", encoding="utf-8")
    if config_text is not None:
        (out / "config.yml").write_text(config_text, encoding="utf-8")
    if resume:
        drop_rows_after(out / "progress.csv", "iteration", start["iteration"], PROGRESS_FIELDS)
    counters = {k: start[k] for k in ("iteration", "env_steps", "wall_s", "cpu_s")}
    info = {"env_id": config.env_id, "env_kwargs": dict(config.env_kwargs), "observation_shape": list(obs_shape),
            "action_shape": list(act_shape), "normalize_obs": config.normalize_obs,
            "config_hash": config.identity_hash(), "name": config.name, "ray_version": ray.__version__,
            "torch_version": torch.__version__}
    algo = None
    interrupted = stopped = False
    saved: Path | None = done[-1] if resume else None
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        start_ray(address, config)
        algo = algorithm_config(config).build_algo()
        if resume:
            algo.restore_from_path(str(done[-1].resolve()))
            _push_weights(algo)
        from physics.run import stop_requests

        with stop_requests() as stop:
            try:
                while not stop.requested:
                    if config.iterations is not None and counters["iteration"] >= config.iterations:
                        break
                    wall0 = counters["wall_s"]
                    if config.max_wall_time_s is not None and wall0 + time.perf_counter() - t0 >= \
                            config.max_wall_time_s:
                        stopped = True
                        break
                    result = algo.train()
                    row = _progress_row(result, counters, start, t0, c0,
                                        algo.env_runner_group.num_healthy_remote_workers())
                    _append_row(out / "progress.csv", row)
                    if progress:
                        _print_row(row, config)
                    if counters["iteration"] % config.checkpoint_every == 0:
                        saved = _save(algo, out, {**info, **counters})
            except BaseException as exc:
                if not is_interrupt(exc):
                    raise
                interrupted = True  # a second signal: stop at once, the newest checkpoint stays
            if stop.requested and not interrupted:
                interrupted = True
                saved = _save(algo, out, {**info, **counters}) if saved is None or \
                    checkpoint_info(saved)["iteration"] != counters["iteration"] else saved
            elif not interrupted and (saved is None or checkpoint_info(saved)["iteration"] != counters["iteration"]):
                saved = _save(algo, out, {**info, **counters})
    finally:
        if algo is not None:
            try:
                algo.stop()
            except Exception:  # noqa: BLE001 -- the actors go with ray.shutdown below anyway
                pass
        ray.shutdown()
    result = RayTrainResult(out, counters["iteration"], counters["env_steps"], counters["wall_s"], counters["cpu_s"],
                            stopped, saved, interrupted)
    if interrupted:
        raise TrainingInterrupted(result)
    return result


def _push_weights(algo) -> None:
    """Give every remote env runner the learner's (restored) weights and wait for them. ``restore_from_path`` of
    RLlib 2.60 sends them fire-and-forget, and env runners still busy starting up drop them: the first iteration
    after a resume then sampled with freshly initialised weights, and the update on those samples undid the
    training (success rate 0.99 before the resume, 0.67 after, on FlagellumTurn-surrogate-v0)."""
    if algo.env_runner_group.num_remote_env_runners() == 0:
        return
    state = algo.learner_group.get_state(components="learner/rl_module", inference_only=True)["learner"]
    state = {k: v for k, v in state.items() if k == "rl_module"}
    algo.env_runner_group.foreach_env_runner(lambda runner: runner.set_state(state), local_env_runner=False,
                                             timeout_seconds=None)


def _progress_row(result: dict[str, Any], counters: dict[str, Any], start: dict[str, Any], t0: float,
                  c0: float, env_runners: int) -> dict[str, Any]:
    """Advance ``counters`` by one iteration's ``result`` and return its progress.csv row."""
    er = result.get("env_runners", {})
    runner_cpu = float(er.get("flagellum_cpu_s", 0.0))
    counters["iteration"] += 1
    counters["env_steps"] += int(er.get("num_env_steps_sampled", 0))
    counters["wall_s"] = start["wall_s"] + time.perf_counter() - t0
    counters["runner_cpu_s"] = counters.get("runner_cpu_s", 0.0) + runner_cpu
    counters["cpu_s"] = start["cpu_s"] + time.process_time() - c0 + counters["runner_cpu_s"]
    n_success = int(er.get("flagellum_with_success", 0))
    ret = er.get("episode_return_mean")
    return {"iteration": counters["iteration"], "env_steps": counters["env_steps"],
            "wall_s": round(counters["wall_s"], 2), "cpu_s": round(counters["cpu_s"], 2),
            "episodes": int(er.get("flagellum_episodes", 0)),
            "episode_return_mean": "" if ret is None else round(float(ret), 4),
            "success_rate": round(int(er.get("flagellum_successes", 0)) / n_success, 4) if n_success else "",
            "env_runners": env_runners}


def _append_row(file: Path, row: dict[str, Any]) -> None:
    new = not file.is_file()
    with open(file, "a", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=PROGRESS_FIELDS)
        if new:
            w.writeheader()
        w.writerow(row)


def _print_row(row: dict[str, Any], config: RayTrainConfig) -> None:
    total = f"/{config.iterations}" if config.iterations is not None else ""
    success = f", success {row['success_rate']:.2f}" if row["success_rate"] != "" else ""
    ret = f", return {row['episode_return_mean']:.3g}" if row["episode_return_mean"] != "" else ""
    print(f"iteration {row['iteration']}{total}: {row['env_steps']} env steps, {row['wall_s']:.0f} s wall, "
          f"{row['cpu_s']:.0f} CPU s, {row['episodes']} episodes{ret}{success}", file=sys.stderr, flush=True)


def _save(algo, out: Path, info: dict[str, Any]) -> Path:
    """``algo``'s checkpoint at ``info["iteration"]`` with its flagellum.json (written last: it marks the
    checkpoint complete); the older ones beyond KEEP_CHECKPOINTS removed. Called under ``train``'s
    ``stop_requests``: a first signal waits for the files."""
    folder = out / "checkpoints" / f"{CHECKPOINT_PREFIX}{info['iteration']:06d}"
    if folder.exists():
        shutil.rmtree(folder)
    algo.save_to_path(str(folder.resolve()))
    data = {k: v for k, v in info.items() if k != "runner_cpu_s"}
    (folder / INFO_FILE).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    for old in checkpoints(out)[:-KEEP_CHECKPOINTS]:
        shutil.rmtree(old, ignore_errors=True)
    return folder
