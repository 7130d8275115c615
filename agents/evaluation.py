"""``flagellum evaluate``: every controller on every path, in parallel and resumable; a table.

Writes ``DIR/results.jsonl`` (one line per finished episode, the resume file), ``DIR/points/``
(per-episode traces), ``DIR/results.json``::

    {"per_path": [{"path": name, "controller": spec, <METRICS>}, ...],
     "aggregate": {spec: {"success_rate": ..., "mean_cross_track_m": ..., <means of the others>}}}

and ``DIR/results.md`` (controllers side by side).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agents.assets import eval_paths_dir
from agents.path_following import (METRICS, EpisodeTask, check_unique_controllers, controller_kind, env_settings,
                                   make_controller)
from batch.store import RESULTS_FILE, ResultsStore
from batch.pool import pending, run_tasks
from flagellum_env.paths import WaypointPath, load_path, square_path

AGGREGATED = ("waypoints_reached", "mean_cross_track_m", "max_cross_track_m", "max_out_of_plane_ratio", "time_s",
              "energy_J", "buckling_events", "wall_time_s")

#: ``--paths eval``: the evaluation paths shipped with the package (``agents/eval_paths``).
EVAL_PATHS = "eval"


def resolve_paths(specs: Sequence[str], option: str = "--paths") -> list[WaypointPath]:
    """Paths from ``square``, ``eval`` (the 20 evaluation paths shipped with the package), JSON path
    files and folders of them (sorted); ValueError naming a bad one (as the value of ``option``)."""
    out: list[WaypointPath] = []
    for spec in specs:
        if spec == "square":
            out.append(square_path())
            continue
        p = eval_paths_dir() if spec == EVAL_PATHS else Path(spec)
        if p.is_dir():
            files = sorted(f for f in p.glob("*.json") if f.is_file())
            if not files:
                raise ValueError(f"{option} {spec!r}: the folder holds no path files (*.json)")
            out.extend(_load(f, option) for f in files)
        elif p.is_file():
            out.append(_load(p, option))
        else:
            raise ValueError(f"{option} {spec!r} is not allowed; allowed: 'square', 'eval', a path file (JSON) or a "
                             "folder of them")
    names = [w.name for w in out]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ValueError(f"path names must be unique, repeated: {dupes} (set \"name\" in the path files)")
    return out


def _load(file: Path, option: str) -> WaypointPath:
    try:
        return load_path(file)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{option} {str(file)!r}: {exc}") from None


def check_controllers(controllers: Sequence[str], paths: Sequence[WaypointPath], preset: str,
                      env_overrides: dict[str, Any] | None = None) -> None:
    """Build each controller once, as an episode would (env of the first path, the preset's turn map, the agent),
    so a missing or bad turn map or agent is a ValueError before any episode runs."""
    from flagellum_env.steer_env import FlagellumSteerEnv

    for spec in controllers:
        env = FlagellumSteerEnv(path=paths[0], **env_settings(spec, preset, env_overrides))
        try:
            make_controller(spec, env, preset)
        except ValueError as exc:
            raise ValueError(f"--controller {spec!r}: {exc}") from None
        finally:
            env.close()


def evaluate(paths: Sequence[WaypointPath], controllers: Sequence[str], preset: str, out_dir: str | os.PathLike,
             workers: int | None = None, resume: bool = False, env_overrides: dict[str, Any] | None = None,
             progress: bool = True, report_only: bool = False, seed_per_path: bool = False,
             scheduler: Any | None = None, seed0: int = 0) -> dict[str, Any]:
    """Run every (controller, path) episode (parallel, resumable) and write the results files.

    ``report_only``: run nothing; write the results files from the episodes already in
    ``out_dir`` (the others are listed under ``missing``). ``seed_per_path``: the env is reset
    with seed ``seed0 + k`` for the k-th path (every controller meets the same draws; with randomisation,
    each path its own swimmer) instead of ``seed0`` for all. ``scheduler``: a Dask scheduler (address or
    cluster) instead of ``workers`` local processes (``batch.pool.run_tasks``).
    """
    for c in controllers:
        controller_kind(c)
    check_unique_controllers(controllers)
    out = Path(out_dir)
    if report_only and not any(True for _ in _lines(out / RESULTS_FILE)):
        raise ValueError(f"--report-only: {str(out)!r} holds no episodes ({RESULTS_FILE} is missing or empty); "
                         "run the evaluation there first")
    if not report_only:
        check_controllers(controllers, paths, preset, env_overrides)
    env_kw = tuple(sorted((env_overrides or {}).items()))
    if isinstance(seed0, bool) or not isinstance(seed0, int) or seed0 < 0:
        raise ValueError(f"seed0={seed0!r} is not allowed; allowed: an integer >= 0")
    tasks = [EpisodeTask(c, p, preset, env_kw, seed=seed0 + k if seed_per_path else seed0)
             for c in controllers for k, p in enumerate(paths)]
    with ResultsStore(out, resume or report_only) as store:
        lost: list[tuple[Any, str]] = []
        if not report_only:
            todo = pending(tasks, store, retry_failed=False)
            lost = run_tasks(todo, store, workers=workers, scheduler=scheduler, progress=progress, total=len(tasks),
                             desc="evaluate")
        records = [store.records.get(t.point_id) for t in tasks]
    results = summarise([r for r in records if r is not None], controllers)
    results["preset"] = preset
    results["env_overrides"] = dict(env_overrides or {})
    results["seeds"] = {p.name: (seed0 + k if seed_per_path else seed0) for k, p in enumerate(paths)}
    results["missing"] = [t.label() for t, r in zip(tasks, records, strict=True) if r is None]
    (out / "results.json").write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")
    (out / "results.md").write_text(results_markdown(results), encoding="utf-8")
    if lost:
        why = dict((t.point_id, reason) for t, reason in lost)
        first = next(t for t, r in zip(tasks, records, strict=True) if r is None)
        raise EpisodesNotRun(f"{len(results['missing'])} of {len(tasks)} episodes did not run (first: {first.label()}: "
                             f"{why.get(first.point_id, 'not run')}); the finished ones are in {out / RESULTS_FILE} "
                             f"and counted in {out / 'results.json'}; run again with --resume to run the rest", results)
    return results


class EpisodesNotRun(RuntimeError):
    """Some episodes did not run (their worker died); ``results`` summarises the others (written already)."""

    def __init__(self, message: str, results: dict[str, Any]) -> None:
        super().__init__(message)
        self.results = results


def _lines(file: Path) -> list[str]:
    try:
        return [line for line in file.read_text(encoding="utf-8").splitlines() if line.strip()]
    except (OSError, UnicodeDecodeError):
        return []


def summarise(records: Sequence[dict[str, Any]], controllers: Sequence[str]) -> dict[str, Any]:
    """``{"per_path": [...], "aggregate": {...}}`` from episode records."""
    per_path = [{"path": r["path"], "controller": r["controller"], "status": r["status"], "error": r.get("error"),
                 "n_waypoints": r.get("n_waypoints"),
                 **{m: r.get(m) for m in METRICS}, "trace": r.get("trajectory")} for r in records]
    aggregate = {}
    for c in controllers:
        rows = [r for r in per_path if r["controller"] == c]
        agg: dict[str, Any] = {"episodes": len(rows),
                               "success_rate": _mean([float(bool(r["success"])) for r in rows])}
        for m in AGGREGATED:
            agg[m] = _mean([r[m] for r in rows if r.get(m) is not None])
        agg["failed_runs"] = sum(r["status"] != "ok" for r in rows)
        aggregate[c] = agg
    return {"per_path": per_path, "aggregate": aggregate}


def _mean(values: Sequence[float]) -> float | None:
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return sum(vals) / len(vals) if vals else None


def _fmt(v: Any, scale: float = 1.0, digits: int = 2) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    return f"{float(v) * scale:.{digits}f}"


def results_markdown(results: dict[str, Any]) -> str:
    """The aggregate table (controllers side by side) and the per-path table."""
    ctrl = list(results["aggregate"])
    lines = [f"# Path following ({results.get('preset')} preset)", "",
             "| metric | " + " | ".join(ctrl) + " |", "|---|" + "---|" * len(ctrl)]
    rows = [("episodes", "episodes", 1, 0), ("success rate (%)", "success_rate", 100, 0),
            ("waypoints reached (mean)", "waypoints_reached", 1, 2),
            ("mean cross-track (cm)", "mean_cross_track_m", 100, 2),
            ("max cross-track (cm)", "max_cross_track_m", 100, 2),
            ("max out-of-plane Δz/ΔL (%)", "max_out_of_plane_ratio", 100, 2), ("time (s)", "time_s", 1, 0),
            ("energy (mJ)", "energy_J", 1e3, 2), ("buckling events", "buckling_events", 1, 1),
            ("wall time (s)", "wall_time_s", 1, 0), ("failed runs", "failed_runs", 1, 0)]
    for label, key, scale, digits in rows:
        lines.append(f"| {label} | " + " | ".join(_fmt(results["aggregate"][c].get(key), scale, digits)
                                                for c in ctrl) + " |")
    lines += ["", "| path | controller | success | waypoints | mean XTE (cm) | max XTE (cm) | Δz/ΔL (%) | time (s) | "
              "energy (mJ) | buckling | wall (s) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results["per_path"]:
        lines.append(f"| {r['path']} | {r['controller']} | {_fmt(r['success'])} | {r.get('waypoints_reached')} | "
                     f"{_fmt(r['mean_cross_track_m'], 100)} | {_fmt(r['max_cross_track_m'], 100)} | "
                     f"{_fmt(r['max_out_of_plane_ratio'], 100)} | {_fmt(r['time_s'], 1, 0)} | "
                     f"{_fmt(r['energy_J'], 1e3)} | {r.get('buckling_events')} | {_fmt(r['wall_time_s'], 1, 0)} |")
    if results.get("missing"):
        lines += ["", f"Not finished: {', '.join(results['missing'])}."]
    return "\n".join(lines) + "\n"
