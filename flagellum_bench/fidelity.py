"""Speed versus accuracy: measure each fidelity configuration against the ``paper`` reference.

Every (configuration, metric) pair is one task; finished tasks are appended to a JSONL file at
once (resumable), tasks run in parallel local processes or on a Dask cluster (the backends of
``batch.backends``, as for the sweeps), and the report is built from the file.

Metrics (the same for every configuration):

* ``swim_per_turn_10rpm``: distance swum per motor turn at 10 rpm, b = 1.2 cm (after one turn
  of start-up, averaged over the next two turns), m;
* ``lratio_100s``: L'/L after t_bar = 1.02 (100 s) from rest at ``OMEGA_HIGH_RPM``;
* ``theta_tc{10,20,40}`` / ``phi_tc{...}``: turning and out-of-plane angles (deg) after a burst
  of t_c s at ``OMEGA_HIGH_RPM`` from steady 10 rpm swimming (``agents.turn_map``);
* ``omega_b``: buckling threshold for b = 1.2 cm (rpm), by bisection on L'/L(100 s) < 0.98
  in [50, 130] rpm (3 halvings: bracket width 10 rpm).

The turning metrics use 90 rpm, not the paper's 60 rpm: the ladder's rows were measured with the head
torque-free (``head_rotation=torque_free``, eqn 13), under which 60 rpm is below this model's buckling
threshold and produces no turn at all.

Errors are relative to ``paper``: |x - x_paper| / max(|x_paper|, floor) with floors 10 deg for
angles and 0 elsewhere. Costs are real-time factors (simulated s per wall s) on one core.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

OMEGA_HIGH_RPM = 90.0
TC_VALUES = (10.0, 20.0, 40.0)
BUCKLED_RATIO = 0.98


@dataclass(frozen=True)
class FidelityConfig:
    """A named point on the speed/accuracy ladder: a preset plus parameter overrides."""

    name: str
    preset: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    numerics: dict[str, Any] = field(default_factory=dict)

    def build(self):
        from physics import configure

        return configure(self.preset, {**self.params, **self.numerics})

    def setup(self) -> dict[str, Any]:
        """The resolved parameters and numerics (JSON types): a record measured with another setup
        (e.g. before a preset was redefined) is stale for this configuration."""
        from dataclasses import asdict

        p, n = self.build()
        return json.loads(json.dumps({"params": asdict(p), "numerics": asdict(n)}))


LADDER: tuple[FidelityConfig, ...] = (
    FidelityConfig("paper", "paper"),
    FidelityConfig("paper, h = 5 ms", "paper", numerics={"dt": 5e-3}),
    FidelityConfig("paper, h = 5 ms, refresh 0.3 r0", "paper", numerics={"dt": 5e-3, "hydro_refresh_tol": 0.3}),
    FidelityConfig("paper, h = 5 ms, Stokes head", "paper", numerics={"dt": 5e-3, "head_model": "stokes"}),
    FidelityConfig("faithful", "faithful"),
    # the retired preset `balanced`, as its configuration (implicit Euler at 20 ms turns 14 % less than paper)
    FidelityConfig("balanced", "paper", numerics={"dt": 2e-2, "newton_tol": 1e-5}),
    FidelityConfig("LSBT N = 60, h = 5 ms, refresh 0.1 r0", "paper",
                   params={"n_nodes": 60}, numerics={"dt": 5e-3, "hydro_refresh_tol": 0.1}),
    FidelityConfig("fast", "fast"),
    # the retired preset coarse (docs/bench_quick.md), as its configuration
    FidelityConfig("LSBT N = 45, h = 10 ms, refresh 0.1 r0", None, params={"n_nodes": 45},
                   numerics={"dt": 1e-2, "hydro_refresh_tol": 0.1, "newton_tol": 1e-5}),
    FidelityConfig("LSBT N = 30, h = 50 ms, one iteration", "paper",
                   params={"n_nodes": 30}, numerics={"dt": 0.05, "single_iteration": True, "hydro_refresh_tol": 0.3}),
    FidelityConfig("RFT N = 122, h = 5 ms", "paper", numerics={"dt": 5e-3, "hydro_model": "rft"}),
    FidelityConfig("RFT N = 30, h = 50 ms, one iteration", "paper",
                   params={"n_nodes": 30}, numerics={"dt": 0.05, "hydro_model": "rft", "single_iteration": True}),
)

QUICK_METRICS = ("swim_per_turn_10rpm", "lratio_100s")

# --- flagellum bench --quick: one row per preset ------------------------------------------------
#: The burst of the quick protocol: from steady 10 rpm, BURST_TC s at BURST_RPM, then 10 rpm until the
#: heading settles (``agents.turn_measurement``); the ``turns`` metric repeats it for the shorter TURN_TCS, so the
#: turn is measured on the rising branch (4 s), past its peak (6 s) and tumbling (8 s).
BURST_RPM = 150.0
BURST_TC = 8.0
TURN_TCS = (4.0, 6.0)
#: The held-out path of the episode metric (a start and 3 waypoints, from the committed eval set).
EPISODE_PATH = "planar_1000.json"
QUICK_PRESET_METRICS = ("swim_per_turn_10rpm", "burst", "turns", "episode", "env_random")
#: the quick protocol's row of the turn-level surrogate (``surrogate_tier``), measured in the same run
SURROGATE_CONFIG = "surrogate"
#: the steady cruise is measured after this many seconds more at 10 rpm (6 s start + 20 s: the helix has settled)
SETTLE_S = 20.0
#: env steps of the quick protocol: ``FlagellumSteer-v0`` at its default control step, random actions (seed 0)
ENV_CONTROL_DT = 2.0
ENV_RANDOM_STEPS = 40
#: the configuration every quick row's errors are measured against (``physics.presets``)
QUICK_REFERENCE = "reference"
#: value -> name of the error in the quick rows
QUICK_ERRORS = {"swim_per_turn_10rpm": "swim_per_turn", "theta_tc4": "theta_tc4", "theta_tc6": "theta_tc6",
                "theta_tc8": "theta_tc8", "phi_tc4": "phi_tc4", "phi_tc6": "phi_tc6", "phi_tc8": "phi_tc8",
                "lratio_burst": "lratio_end_of_burst"}


def quick_configs() -> tuple[FidelityConfig, ...]:
    """Every preset, and the turn-level surrogate (of the default preset: its map and calibration)."""
    from physics.presets import DEFAULT_PRESET, preset_names

    return tuple(FidelityConfig(p, p) for p in preset_names()) + (FidelityConfig(SURROGATE_CONFIG, DEFAULT_PRESET),)


def quick_tasks(configs: tuple[FidelityConfig, ...]) -> list[tuple[FidelityConfig, str]]:
    """(config, metric) of the quick protocol: every metric for every preset, but the episode and the random-policy
    env only for the presets users swim with (not ``paper`` and ``reference``: minutes each); the surrogate's own
    metrics (``surrogate_tier.SURROGATE_METRICS``) for the surrogate."""
    from flagellum_bench.surrogate_tier import SURROGATE_METRICS

    slow = ("paper", QUICK_REFERENCE)
    tasks = [(c, m) for m in QUICK_PRESET_METRICS for c in configs if c.name != SURROGATE_CONFIG
             and not (c.name in slow and m in ("episode", "env_random"))]
    return tasks + [(c, m) for m in SURROGATE_METRICS for c in configs if c.name == SURROGATE_CONFIG]


def quick_rows(done: dict[tuple[str, str], dict], configs: tuple[FidelityConfig, ...]) -> list[dict[str, Any]]:
    """The rows of ``bench --quick``: config, preset, real_time_factor (steady 10 rpm), burst_real_time_factor
    (the 150 rpm burst), episode_wall_s, their CPU-time versions, the episode's simulated s per CPU s, values, and
    errors against ``QUICK_REFERENCE`` (the surrogate's: its map's leave-one-out error, ``surrogate_tier``)."""
    from flagellum_bench.surrogate_tier import SURROGATE_METRICS

    values: dict[str, dict[str, Any]] = {}
    rows = []
    for c in configs:
        vals, rtf, failures = {}, {}, []
        for m in QUICK_PRESET_METRICS + SURROGATE_METRICS:
            rec = done.get((c.name, m))
            if rec is None:
                continue
            if rec["error"]:
                failures.append(f"{m}: {rec['error']}")
                continue
            r = rec["result"]
            rtf[m] = (r.get("rtf"), r.get("rtf_cpu"))
            vals.update({k: v for k, v in r.items() if k not in ("rtf", "rtf_cpu", "wall_s")})
        values[c.name] = vals
        rows.append({"config": c.name, "preset": c.preset,
                     "real_time_factor": rtf.get("swim_per_turn_10rpm", (None, None))[0],
                     "real_time_factor_cpu": rtf.get("swim_per_turn_10rpm", (None, None))[1],
                     "burst_real_time_factor": rtf.get("burst", (None, None))[0],
                     "burst_real_time_factor_cpu": rtf.get("burst", (None, None))[1],
                     "relax_real_time_factor_cpu": vals.get("relax_rtf_cpu"),
                     "episode_wall_s": vals.get("episode_wall_s"), "episode_cpu_s": vals.get("episode_cpu_s"),
                     "episode_real_time_factor_cpu": (vals["episode_time_s"] / vals["episode_cpu_s"]
                                                      if vals.get("episode_cpu_s") else None),
                     "decisions_per_cpu_s": vals.get("decisions_per_cpu_s"),
                     "env_steps_per_s_rule": vals.get("env_steps_per_s_rule"),
                     "env_steps_per_s_random": vals.get("env_steps_per_s_random"),
                     "values": vals, "failures": failures,
                     "measured": sorted({rec.get("measured") or "undated" for (name, _), rec in done.items()
                                         if name == c.name})})
    ref = values.get(QUICK_REFERENCE, {})
    for row in rows:
        row["errors"] = {QUICK_ERRORS[k]: relative_error(k, v, ref[k])
                         for k, v in row["values"].items()
                         if k in QUICK_ERRORS and isinstance(v, (int, float)) and isinstance(ref.get(k), (int, float))}
        if "map_loo_rising_relative_max" in row["values"]:  # the surrogate: its error between the map's samples
            row["errors"]["theta_between_samples"] = row["values"]["map_loo_rising_relative_max"]
    return rows
FULL_METRICS = QUICK_METRICS + tuple(f"turn_tc{int(t)}" for t in TC_VALUES) + ("omega_b",)


def _sim(cfg: FidelityConfig, **param_changes):
    from physics.simulator import Simulator

    p, n = cfg.build()
    return Simulator(p.replace(**param_changes), n)


def _steady(cfg: FidelityConfig):
    from physics import advance
    from physics.params import RPM_TO_RAD_S

    sim = _sim(cfg)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, 6.0)
    return sim


def _lratio(cfg: FidelityConfig, rpm: float) -> tuple[float, float]:
    from physics import advance
    from physics.params import RPM_TO_RAD_S

    sim = _sim(cfg)
    sim.set_motor_speed(rpm * RPM_TO_RAD_S)
    t0 = time.perf_counter()
    advance(sim, 100.0)
    return sim.end_to_end_ratio(), 100.0 / (time.perf_counter() - t0)


def run_metric(cfg: FidelityConfig, metric: str) -> dict[str, Any]:
    """Compute one metric for one configuration. Returns {metric values..., rtf, wall_s}."""
    t_start = time.perf_counter()
    out: dict[str, Any] = {}
    if metric == "swim_per_turn_10rpm":
        from physics import advance

        sim = _steady(cfg)
        advance(sim, SETTLE_S)  # the helix settles: the steady cruise is measured after it
        x0 = sim.head_position
        t0, c0 = time.perf_counter(), time.process_time()
        advance(sim, 12.0)
        out["rtf"] = 12.0 / (time.perf_counter() - t0)
        out["rtf_cpu"] = 12.0 / max(time.process_time() - c0, 1e-9)
        out["swim_per_turn_10rpm"] = float(math.dist(sim.head_position, x0) / 2.0)
    elif metric == "lratio_100s":
        ratio, rtf = _lratio(cfg, OMEGA_HIGH_RPM)
        out["lratio_100s"], out["rtf"] = ratio, rtf
    elif metric.startswith("turn_tc"):
        from agents.turn_measurement import measure_turn

        tc = float(metric[len("turn_tc"):])
        sim = _steady(cfg)
        t0, sim_t0 = time.perf_counter(), sim.time
        res = measure_turn(sim, 10.0, OMEGA_HIGH_RPM, tc, relax_max_s=90.0)
        out["rtf"] = (sim.time - sim_t0) / (time.perf_counter() - t0)
        out[f"theta_tc{int(tc)}"], out[f"phi_tc{int(tc)}"] = res.theta_deg, res.phi_deg
        out["straight"] = res.straight
    elif metric == "burst":
        from agents.turn_measurement import measure_turn

        sim = _steady(cfg)
        res = measure_turn(sim, 10.0, BURST_RPM, BURST_TC, relax_max_s=90.0)
        out.update({f"theta_tc{BURST_TC:g}": res.theta_deg, f"phi_tc{BURST_TC:g}": res.phi_deg,
                    "lratio_burst": res.burst_end_ratio, "straight": res.straight})
        out["rtf"] = BURST_TC / res.burst_wall_s
        out["rtf_cpu"] = BURST_TC / max(res.burst_cpu_s, 1e-9)
        out["relax_s"] = res.relax_s
        out["relax_rtf_cpu"] = res.relax_s / max(res.relax_cpu_s, 1e-9)
    elif metric == "turns":
        from agents.turn_measurement import measure_turn

        for tc in TURN_TCS:  # each from the burst's start: the same phase
            res = measure_turn(_steady(cfg), 10.0, BURST_RPM, tc, relax_max_s=90.0)
            out.update({f"theta_tc{tc:g}": res.theta_deg, f"phi_tc{tc:g}": res.phi_deg,
                        f"straight_tc{tc:g}": res.straight})
    elif metric.startswith("surrogate_"):
        from agents.assets import eval_paths_dir
        from flagellum_bench.surrogate_tier import run_surrogate_metric

        out.update(run_surrogate_metric(metric, str(eval_paths_dir() / EPISODE_PATH), ANGLE_FLOOR_DEG))
    elif metric == "episode":
        from agents.assets import eval_paths_dir
        from agents.path_following import EpisodeTask
        from flagellum_env.paths import load_path

        path = load_path(eval_paths_dir() / EPISODE_PATH)
        c0 = time.process_time()
        rec = EpisodeTask("rule", path, cfg.preset).execute().record
        if rec["status"] != "ok":
            raise RuntimeError(f"episode failed: {rec['error']}")
        cpu = time.process_time() - c0
        out.update(episode_wall_s=rec["wall_time_s"], episode_cpu_s=cpu,
                   episode_success=rec["success"], episode_mean_cross_track_m=rec["mean_cross_track_m"],
                   episode_time_s=rec["time_s"])
        out["rtf"] = rec["time_s"] / rec["wall_time_s"]
        # the same swimming as env steps of the default control_dt (2 s) per CPU second
        out["env_steps_per_s_rule"] = rec["time_s"] / ENV_CONTROL_DT / cpu
    elif metric == "env_random":
        import gymnasium as gym

        import flagellum_env  # noqa: F401  (registers the ids)

        env = gym.make("FlagellumSteer-v0", preset=cfg.preset, control_dt=ENV_CONTROL_DT)
        env.reset(seed=0)
        env.action_space.seed(0)
        buckled = 0
        c0 = time.process_time()
        for _ in range(ENV_RANDOM_STEPS):
            _, _, terminated, truncated, info = env.step(env.action_space.sample())
            buckled += int(env.unwrapped.simulator.end_to_end_ratio() < 0.9)
            if terminated or truncated:
                env.reset()
        cpu = time.process_time() - c0
        env.close()
        out.update(env_steps_per_s_random=ENV_RANDOM_STEPS / cpu, env_random_buckled_steps=buckled)
        out["rtf_cpu"] = ENV_RANDOM_STEPS * ENV_CONTROL_DT / cpu
    elif metric == "omega_b":
        lo, hi = 50.0, 130.0
        evals = []
        for _ in range(3):
            mid = 0.5 * (lo + hi)
            ratio, _ = _lratio(cfg, mid)
            evals.append([mid, ratio])
            if ratio < BUCKLED_RATIO:
                hi = mid
            else:
                lo = mid
        out["omega_b"] = 0.5 * (lo + hi)
        out["omega_b_bracket"] = [lo, hi]
        out["omega_b_evaluations"] = evals
    else:
        raise ValueError(f"unknown metric {metric!r}; known: {FULL_METRICS}")
    out["wall_s"] = time.perf_counter() - t_start
    return out


def _task(cfg: FidelityConfig, metric: str, commit: str | None = None) -> dict[str, Any]:
    stamp = {"measured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "commit": commit,
             "setup": cfg.setup()}
    try:
        return {"config": cfg.name, "metric": metric, "result": run_metric(cfg, metric), "error": None, **stamp}
    except Exception as exc:  # a diverging configuration is a result too
        return {"config": cfg.name, "metric": metric, "result": None, "error": f"{type(exc).__name__}: {exc}",
                **stamp}


def load_done(path: Path, configs=None) -> dict[tuple[str, str], dict]:
    """The latest record per (config, metric) in ``path``. With ``configs``, records whose stored
    ``setup`` differs from the configuration's current one are stale and skipped (records from
    before setups were stored are kept)."""
    setups = {c.name: c.setup() for c in configs} if configs is not None else {}
    done: dict[tuple[str, str], dict] = {}
    if path.exists():
        for line in path.read_text().splitlines():
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue  # torn last line of an interrupted run
            if rec.get("setup") is not None and rec["config"] in setups and rec["setup"] != setups[rec["config"]]:
                continue
            done[(rec["config"], rec["metric"])] = rec
    return done


@dataclass(frozen=True)
class FidelityTask:
    """One (configuration, metric) measurement as a task of ``batch.backends`` (local worker
    processes or a Dask cluster): ``point_id`` and ``label()`` name it, ``execute()`` runs it
    in the worker and returns the record of :func:`_task` as a ``batch.worker.PointOutcome``."""

    config: FidelityConfig
    metric: str
    commit: str | None = None

    @property
    def point_id(self) -> str:
        return f"{self.config.name}: {self.metric}"

    def label(self) -> str:
        return self.point_id

    def execute(self):
        from batch.worker import PointOutcome

        return PointOutcome(_task(self.config, self.metric, self.commit), None)


def run_fidelity(path: Path, configs=LADDER, metrics=FULL_METRICS, workers: int | None = None,
                 progress: bool = True, scheduler: Any | None = None,
                 tasks: list[tuple[FidelityConfig, str]] | None = None) -> dict[tuple[str, str], dict]:
    """Run every missing (config, metric) task (``tasks``, default every config with every metric), appending each result to ``path`` as it arrives.

    The tasks run on ``workers`` local processes (default: one per core) or, with ``scheduler``
    (an address ``"tcp://HOST:PORT"``, a cluster object or a ``distributed.Client``), on that Dask
    cluster; ``batch.backends.BackendError`` if it cannot be used. Ctrl-C stops the running tasks
    (the finished ones are in ``path``) and is raised again."""
    from tqdm import tqdm

    from batch.backends import default_workers, make_backend
    from batch.provenance import git_commit

    path.parent.mkdir(parents=True, exist_ok=True)
    done = load_done(path, configs)
    # cheap metrics of every configuration first, so a partial run still compares all of them
    grid = tasks if tasks is not None else [(c, m) for m in metrics for c in configs]
    todo = [(c, m) for c, m in grid if (c.name, m) not in done]
    if not todo:
        return done
    commit = git_commit()
    backend = make_backend(min(workers or default_workers(), len(todo)), scheduler)
    futures: dict[Any, FidelityTask] = {}
    try:
        with open(path, "a") as fh:
            for c, m in todo:
                task = FidelityTask(c, m, commit)
                futures[backend.submit(task)] = task
            for fut in tqdm(backend.as_completed(futures), total=len(futures), disable=not progress,
                            desc="fidelity", unit="task"):
                rec = fut.result().record
                fh.write(json.dumps(rec) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
                done[(rec["config"], rec["metric"])] = rec
    except KeyboardInterrupt:
        backend.abort(futures)
        raise
    finally:
        backend.close()
    return done


ANGLE_FLOOR_DEG = 10.0


def relative_error(metric: str, value: float, reference: float) -> float:
    """|value - reference| / max(|reference|, floor): the floor is ``ANGLE_FLOOR_DEG`` for angle metrics
    (names starting with theta or phi; phi is often near 0) and 0 otherwise (0 if both are 0)."""
    floor = ANGLE_FLOOR_DEG if metric.startswith(("theta", "phi")) else 0.0
    denom = max(abs(reference), floor)
    return abs(value - reference) / denom if denom > 0 else 0.0

REPORT_NOTES = (
    "Every task is one configuration on one metric, on one core (two tasks at a time on this 2-core machine). "
    f"The turning metrics burst at {OMEGA_HIGH_RPM:g} rpm, not the paper's 60 rpm: with the torque-free head "
    "(eqn 13, `head_rotation=torque_free`) 60 rpm is below this model's buckling threshold and makes no turn. "
    f"Relative errors are |x - x_paper| / max(|x_paper|, floor), floor {ANGLE_FLOOR_DEG:g}° for angles (φ is often "
    "near 0) and 0 otherwise. RTF = simulated seconds per wall second; RTF (10 rpm) is from the swim-speed task, "
    f"RTF ({OMEGA_HIGH_RPM:g} rpm) from the L'/L task. ω_b is the midpoint of its final 10-rpm bracket (L'/L(100 s) < "
    "0.98 by bisection on [50, 130] rpm), so configurations in the same bracket show 0 % and a neighbouring bracket "
    "13 %. Configurations: `paper` N = 122, implicit Euler at h = 1 ms, refresh 0.03 r0, Newton 1e-6; `balanced` "
    "N = 122, implicit Euler at h = 20 ms, refresh 0.03 r0, Newton 1e-5 (not a preset); the other presets as in "
    "physics/presets.py; the rest as named. Why the coarse grids turn less: docs/node_convergence.md.")


def missing_tasks(done: dict[tuple[str, str], dict], configs=LADDER, metrics=FULL_METRICS) -> list[str]:
    """``"config: metric"`` for every task of the grid without a result."""
    return [f"{c.name}: {m}" for m in metrics for c in configs if (c.name, m) not in done]


def rows_from(done: dict[tuple[str, str], dict], configs=LADDER) -> list[dict[str, Any]]:
    """One row per configuration: values, real-time factors and relative errors against paper."""
    rows = []
    values: dict[str, dict[str, Any]] = {}
    for c in configs:
        vals: dict[str, Any] = {}
        rtfs: dict[str, float] = {}
        errors: list[str] = []
        for (name, metric), rec in done.items():
            if name != c.name:
                continue
            if rec["error"]:
                errors.append(f"{metric}: {rec['error']}")
                continue
            r = rec["result"]
            rtfs[metric] = r.get("rtf")
            vals.update({k: v for k, v in r.items() if k not in ("rtf", "wall_s", "straight")})
        values[c.name] = vals
        rows.append({"config": c.name, "preset": c.preset if not c.params and not c.numerics else None,
                     "values": vals, "rtf_by_metric": rtfs,
                     "measured": sorted({rec.get("measured") or "undated" for (name, _), rec in done.items()
                                         if name == c.name}),
                     "real_time_factor": rtfs.get("swim_per_turn_10rpm"),
                     "real_time_factor_buckled": rtfs.get("lratio_100s"), "failures": errors})
    ref = values.get("paper", {})
    for row in rows:
        errs = {}
        for k, v in row["values"].items():
            if k not in ref or not isinstance(v, (int, float)) or k.endswith("bracket"):
                continue
            errs[k] = relative_error(k, v, ref[k])
        row["errors"] = errs
    return rows
