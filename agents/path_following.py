"""One evaluation loop for every controller: drive ``FlagellumSteer-v0`` along a path, measure it.

Controllers are named by a spec string (``make_controller``): ``rule`` (the turn planner with
the preset's turn map, ``agents.assets.default_turn_map``), ``rule:MAP.json`` (another
map), ``adaptive`` / ``adaptive:MAP.json`` (the turn planner correcting its map online from the
turns it observes, ``agents.adaptive_planner``), ``horizon`` / ``horizon:MAP.json`` (a receding-horizon
search of two moves -- cruise, then burst -- over that corrected map, ``agents.horizon_planner``), ``rule@line=W`` /
``adaptive@line=W`` (either planner also scoring a turn by how far its end lies from the path's line, W m per m:
``PlannerConfig.line_weight``; ``:MAP.json`` may follow), ``ppo`` (the PPO agent shipped in ``agents/pretrained/``: the adaptive planner corrected by a policy trained at ``faithful``) and ``ppo:DIR`` (an agent folder
written by ``flagellum train``, or its ``model.zip``), ``ppo-scratch`` / ``ppo-scratch:DIR`` (an agent trained from
scratch with the burst design, no planner inside: ``agents.burst_pilot``; without ``DIR`` the one shipped in
``agents/pretrained/``), ``rllib:DIR`` (a run folder of ``flagellum train --engine
ray`` or one of its checkpoints: ``agents.rllib_policy``). Each has the stable-baselines3
``predict(obs, state, episode_start, deterministic)`` call, so the loop does not care which.

Metrics (the same names everywhere; ``METRICS``):

- ``success``: every waypoint reached in order within the env's time limit;
- ``waypoints_reached``;
- ``mean_cross_track_m`` / ``max_cross_track_m``: distance from the head to the segment being
  followed, averaged over / maximal over the env steps;
- ``max_out_of_plane_ratio``: for planar paths (all waypoints at z = 0) the largest |z| of the
  head divided by the length of the segment being followed (the paper's Delta z / Delta L);
  None for 3-D paths;
- ``time_s``: simulated time; ``energy_J``: integral of |motor torque x motor speed| dt;
- ``buckling_events``: L'/L dropping below 0.9 (the env's counter);
- ``wall_time_s``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from dataclasses import dataclass
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.assets import default_turn_map, missing_turn_map_message
from agents.controller_spec import CONTROLLER_ENV_DEFAULTS, controller_kind, controller_options
from batch.worker import PointOutcome
from flagellum_env.paths import WaypointPath

METRICS = ("success", "waypoints_reached", "mean_cross_track_m", "max_cross_track_m", "max_out_of_plane_ratio",
           "time_s", "energy_J", "buckling_events", "wall_time_s")


def check_unique_controllers(specs: Sequence[str]) -> None:
    """ValueError naming a controller given twice (its episodes would be counted twice)."""
    seen: set[str] = set()
    for spec in specs:
        if spec in seen:
            raise ValueError(f"--controller {spec!r} is given twice; allowed: each controller once")
        seen.add(spec)


def make_controller(spec: str, env, preset: str):
    """The controller named by ``spec`` for this env (see the module docstring)."""
    kind = controller_kind(spec)
    arg = spec.split(":", 1)[1] if ":" in spec else None
    if kind in ("rule", "adaptive", "horizon"):
        from agents.adaptive_planner import AdaptivePlanner
        from agents.horizon_planner import HorizonPlanner
        from agents.turn_map import TurnMap
        from agents.turn_planner import PlannerConfig, RulePlanner

        path = Path(arg) if arg else default_turn_map(preset)
        if not path.is_file():
            raise ValueError(missing_turn_map_message(path, preset, given=arg is not None))
        planner = {"rule": RulePlanner, "adaptive": AdaptivePlanner, "horizon": HorizonPlanner}[kind]
        options = controller_options(spec)
        return planner.for_env(env, TurnMap.load(path), PlannerConfig.from_options(options))
    if kind == "ppo-scratch":
        from agents.burst_pilot import load_burst_pilot

        return load_burst_pilot(arg, env, preset)
    if kind == "rllib":
        from agents.rllib_policy import load_rllib_controller

        return load_rllib_controller(arg, env, preset)
    from agents.ppo_policy import load_ppo_controller

    return load_ppo_controller(arg, env, preset)


def env_settings(spec: str, preset: str, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Keyword arguments of the env for this controller: its defaults, the preset, then ``overrides``."""
    return {**CONTROLLER_ENV_DEFAULTS[controller_kind(spec)], "preset": preset, **(overrides or {})}


@dataclass
class EpisodeTrace:
    """Per env step (and the reset): time (s), head (m, start frame), motor speed (rpm), L'/L,
    cross-track error (m), current waypoint index."""

    t: np.ndarray
    head: np.ndarray
    omega_rpm: np.ndarray
    end_to_end_ratio: np.ndarray
    cross_track_m: np.ndarray
    waypoint_index: np.ndarray
    waypoints: np.ndarray

    def save_npz(self, path: str | Path) -> None:
        with open(path, "wb") as f:
            np.savez_compressed(f, **dataclasses.asdict(self))

    @classmethod
    def load(cls, path: str | Path) -> EpisodeTrace:
        with np.load(path) as data:
            return cls(**{f.name: np.array(data[f.name]) for f in dataclasses.fields(cls)})


def is_planar(path: WaypointPath) -> bool:
    return bool(np.all(np.abs(path.waypoints[:, 2]) < 1e-12))


def run_episode(env, controller, path: WaypointPath, seed: int = 0, progress: bool = False,
                position: int | None = None) -> tuple[dict[str, Any], EpisodeTrace]:
    """Run one episode of ``controller`` on ``path``; (metrics, trace). ``env``: a FlagellumSteer-v0;
    ``progress``: a tqdm bar on stderr, on line ``position`` (None: the next free one).

    Ctrl-C or SIGTERM (in the main thread, where they interrupt) end the episode after the current env step
    (``physics.run.stop_requests``: a flag, never an exception inside a compiled kernel); a second signal stops
    at once. The metrics and trace then hold the steps taken so far and ``metrics["interrupted"]`` is True.
    """
    from tqdm import tqdm

    from physics.errors import is_interrupt
    from physics.run import stop_requests

    t0 = time.perf_counter()
    rows: list[tuple] = []
    info: dict[str, Any] | None = None
    interrupted = False
    bar = None
    with stop_requests() as stop:
        try:
            obs, info = env.reset(seed=seed, options={"path": path})
            if hasattr(controller, "reset"):
                controller.reset()
            rows.append(_row(info))
            start = True
            bar = tqdm(total=round(info["max_sim_time_s"]), unit="sim s", desc=f"{path.name}",
                       disable=not progress, dynamic_ncols=True, position=position)
            done = False
            while not done and not stop.requested:
                action, _ = controller.predict(obs, episode_start=np.array([start]), deterministic=True)
                start = False
                obs, _, terminated, truncated, step_info = env.step(action)
                info = step_info
                rows.append(_row(info))
                bar.update(round(info["sim_time_s"]) - bar.n)
                bar.set_postfix_str(f"waypoint {info['waypoint_index']}/{info['n_waypoints']}, "
                                    f"{info['motor_speed_rpm']:.0f} rpm", refresh=False)
                done = terminated or truncated
            interrupted = not done
        except BaseException as exc:  # a second signal, possibly surfacing from a compiled kernel
            if not is_interrupt(exc):
                raise
            if info is None:  # stopped before the episode started: nothing to report
                raise KeyboardInterrupt from None
            interrupted = True
        finally:
            if bar is not None:
                bar.close()
    trace = EpisodeTrace(*(np.array(c) for c in zip(*rows, strict=True)), waypoints=np.array(path.waypoints))
    metrics = episode_metrics(trace, path, info)
    metrics["wall_time_s"] = time.perf_counter() - t0
    if info.get("error"):
        metrics["error"] = info["error"]
    if interrupted:
        metrics["interrupted"] = True
    return metrics, trace


def _row(info: dict[str, Any]) -> tuple:
    return (info["sim_time_s"], np.asarray(info["head_position_m"], float), info["motor_speed_rpm"],
            info["end_to_end_ratio"], info["cross_track_error_m"], info["waypoint_index"])


def episode_metrics(trace: EpisodeTrace, path: WaypointPath, last_info: dict[str, Any]) -> dict[str, Any]:
    """The ``METRICS`` of one episode (without wall time) from its trace and final info."""
    seg = np.minimum(trace.waypoint_index, path.n_waypoints - 1)
    out_of_plane = None
    if is_planar(path):
        out_of_plane = float(np.max(np.abs(trace.head[:, 2]) / path.segment_lengths[seg]))
    return {"success": bool(last_info["is_success"]), "waypoints_reached": int(last_info["waypoint_index"]),
            "n_waypoints": path.n_waypoints,
            "mean_cross_track_m": float(np.mean(trace.cross_track_m[1:])) if len(trace.t) > 1 else 0.0,
            "max_cross_track_m": float(np.max(trace.cross_track_m)),
            "max_out_of_plane_ratio": out_of_plane, "time_s": float(trace.t[-1]),
            "energy_J": float(last_info["energy_used_j"]), "buckling_events": int(last_info["buckling_events"])}


# --- many episodes in parallel (the shared task pool) -------------------------------------------
@dataclass(frozen=True)
class EpisodeTask:
    """One (controller, path) episode; picklable, ``execute`` runs in a worker process. Its record is the
    episode's metrics, with the planner's ``turns`` where it keeps them."""

    controller: str
    path: WaypointPath
    preset: str
    env_kwargs: tuple[tuple[str, Any], ...] = ()
    seed: int = 0

    @property
    def point_id(self) -> str:
        payload = json.dumps({"c": self.controller, "p": self.path.to_dict(), "preset": self.preset,
                              "env": [list(kv) for kv in self.env_kwargs], "seed": self.seed}, sort_keys=True,
                             default=str)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def label(self) -> str:
        return f"{self.controller} on {self.path.name}"

    def execute(self) -> PointOutcome:
        from flagellum_env.steer_env import FlagellumSteerEnv

        record: dict[str, Any] = {"point_id": self.point_id, "values": {"path": self.path.name,
                                                                         "controller": self.controller},
                                  "path": self.path.name, "controller": self.controller, "preset": self.preset,
                                  "status": "ok", "error": None}
        trace = None
        t0 = time.perf_counter()
        try:
            env = FlagellumSteerEnv(path=self.path, **env_settings(self.controller, self.preset,
                                                                    dict(self.env_kwargs)))
            controller = make_controller(self.controller, env, self.preset)
            metrics, trace = run_episode(env, controller, self.path, seed=self.seed)
            if metrics.get("interrupted"):  # a partial episode is not a result
                return PointOutcome(record, None, interrupted=True)
            record.update(metrics)
            if hasattr(controller, "turns"):  # the planners' turns (burst length, phase error, ...) for diagnosis
                record["turns"] = controller.turns
            if metrics.get("error"):
                record["status"] = "error"
        except Exception as exc:  # recorded, not raised: one bad episode must not stop the others
            record["status"], record["error"] = "error", f"{type(exc).__name__}: {exc}"
            record["wall_time_s"] = time.perf_counter() - t0
        return PointOutcome(record, trace)


@dataclass(frozen=True)
class FollowTask:
    """One controller's episode of ``flagellum follow``: ``run`` here, or ``execute`` in a worker process
    (``follow_controllers``; picklable). ``execute`` returns
    a ``PointOutcome`` whose record is the metrics (with the planner's ``turns`` where it keeps them) and whose
    trajectory is the ``EpisodeTrace``, also of an episode cut short: SIGTERM from the parent (a worker ignores
    Ctrl-C) ends the episode after the current env step, as Ctrl-C does in ``run_episode``."""

    controller: str
    path: WaypointPath
    preset: str
    env_kwargs: tuple[tuple[str, Any], ...] = ()
    seed: int = 0
    progress: bool = False
    position: int | None = None

    def run(self) -> tuple[dict[str, Any], EpisodeTrace]:
        """The episode in this process: (metrics with the planner's ``turns`` where it keeps them, trace)."""
        from flagellum_env.steer_env import FlagellumSteerEnv

        env = FlagellumSteerEnv(path=self.path, **env_settings(self.controller, self.preset, dict(self.env_kwargs)))
        controller = make_controller(self.controller, env, self.preset)
        metrics, trace = run_episode(env, controller, self.path, seed=self.seed, progress=self.progress,
                                     position=self.position)
        if hasattr(controller, "turns"):
            metrics["turns"] = controller.turns
        return metrics, trace

    def execute(self) -> PointOutcome:
        import signal

        signal.signal(signal.SIGTERM, _raise_interrupt)  # a Python handler: run_episode's stop_requests takes it over
        metrics, trace = self.run()
        return PointOutcome(metrics, trace, interrupted=bool(metrics.get("interrupted")))


def _raise_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def follow_controllers(tasks: Sequence[FollowTask], workers: int) -> tuple[dict[str, tuple[dict, EpisodeTrace]], bool]:
    """Run each task's episode on ``workers`` local processes at once (``batch.backends.LocalBackend``: one BLAS
    thread each; they exit if this process dies). Returns ({controller: (metrics, trace)} of the episodes that
    ran, in ``tasks``' order, whether interrupted). Ctrl-C or SIGTERM asks every running episode to stop after
    its current step (``LocalBackend.interrupt``) and returns what they computed, flagged ``interrupted``; a
    second signal stops at once (KeyboardInterrupt, the episodes lost). An episode that raised raises here."""
    import concurrent.futures

    from batch.backends import LocalBackend
    from physics.run import stop_requests

    backend = LocalBackend(workers)
    interrupted = False
    got: dict[str, tuple[dict, EpisodeTrace]] = {}
    futures: dict[Any, FollowTask] = {}
    try:
        futures.update((backend.submit(t), t) for t in tasks)
        with stop_requests() as stop:
            pending = set(futures)
            while pending:
                finished, pending = concurrent.futures.wait(pending, timeout=0.2)
                for fut in finished:
                    if fut.cancelled():
                        continue
                    if fut.exception() is not None:
                        if interrupted:  # stopped before its episode began: nothing to report
                            continue
                        raise fut.exception()
                    outcome = fut.result()
                    got[futures[fut].controller] = (outcome.record, outcome.trajectory)
                if stop.requested and not interrupted:
                    interrupted = True
                    backend.interrupt(pending)
    except BaseException:
        backend.abort(futures)
        raise
    finally:
        backend.close()
    return {t.controller: got[t.controller] for t in tasks if t.controller in got}, interrupted

