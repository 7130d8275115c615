"""Parallel, resumable parameter sweeps: the library entry point.

    from batch.sweep import load_sweep_config, run_sweep

    if __name__ == "__main__":  # needed in scripts: workers are spawned processes
        config = load_sweep_config("examples/sweep_small.yaml")
        records = run_sweep(config, "out/sweep_small")   # all cores; one record per point
        records = run_sweep(config, "out/sweep_small", resume=True)   # runs only what is missing

The sweep file format is in ``batch.sweep_config``, the output files in
``batch.store``, the local and Dask workers in ``batch.backends``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from batch.backends import BackendError, check_workers, default_workers
from batch.pool import TasksInterrupted, run_tasks
from batch.sweep_config import (CONFIG_KEYS, MODES, SweepConfig, SweepConfigError, SweepPoint,
                                load_sweep_config, parameter_names, point_id)
from batch.store import (RESULTS_FILE, ResultsStore, SweepError, check_records_belong, check_same_run,
                         read_results)
from batch.sweep_task import PointTask

CONFIG_FILE = "sweep_config.json"

__all__ = ["SweepConfig", "SweepConfigError", "SweepPoint", "SweepError", "SweepIncomplete", "SweepInterrupted",
           "BackendError", "load_sweep_config", "run_sweep", "load_results", "parameter_names", "point_id",
           "MODES", "CONFIG_KEYS", "RESULTS_FILE", "CONFIG_FILE"]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped ``run_sweep``. Finished points are saved; ``results`` lists them by index."""

    def __init__(self, results: list[dict[str, Any]], total: int) -> None:
        super().__init__(f"sweep interrupted with {len(results)} of {total} points done")
        self.results, self.total = results, total


class SweepIncomplete(SweepError):
    """Points lost to a worker that died; ``results`` holds the finished ones, ``failed`` the rest."""

    def __init__(self, message: str, results: list[dict[str, Any]], failed: list[tuple[SweepPoint, str]]) -> None:
        super().__init__(message)
        self.results, self.failed = results, failed


def run_sweep(config: SweepConfig, out_dir: str | os.PathLike[str], workers: int | None = None,
              resume: bool = False, progress: bool = True, scheduler: Any | None = None,
              retry_failed: bool = False, on_start: Callable[[], None] | None = None) -> list[dict[str, Any]]:
    """Run every point of ``config`` into ``out_dir``; return one record per point, by point index.

    ``workers``: local processes (default: every available core; one BLAS thread each). They
    are spawned, so a script calling this needs the ``if __name__ == "__main__":`` guard.
    ``resume``: keep the results already in ``out_dir/results.jsonl`` and run only the other
    points (without it, an existing non-empty results file is a SweepError). Points that
    ended in a simulation error count as done unless ``retry_failed``. ``scheduler``: a Dask
    address ``"tcp://HOST:PORT"``, cluster or ``distributed.Client`` instead of local
    processes. ``progress``: a tqdm bar over points on stderr. ``on_start``: called once the folder and the
    scheduler were checked, before anything runs (the command line prints its status line there).

    ``resume`` refuses (SweepError naming the first difference) a folder whose ``sweep_config.json`` holds
    another configuration, or whose results are not points of this one.

    Records are the JSON lines of ``results.jsonl`` (see ``batch.store``), with
    ``index`` and ``values`` from this config. Raises SweepInterrupted (a KeyboardInterrupt)
    on Ctrl-C after saving what finished, SweepIncomplete when a worker died.
    """
    if scheduler is not None and workers is not None:
        raise ValueError("workers applies to local processes only; with a scheduler the cluster's workers "
                         "run the points")
    check_workers(workers)
    points = config.points()
    with ResultsStore(out_dir, resume) as store:
        if resume:
            check_same_run(store.out_dir, CONFIG_FILE, {"config": config.to_dict()}, "sweep")
            check_records_belong(store.records, {p.point_id for p in points}, store.out_dir, "sweep")
        if isinstance(scheduler, str):
            from batch.backends import probe_scheduler

            probe_scheduler(scheduler)  # nobody listening: BackendError now, not after the status line
        if on_start is not None:
            on_start()
        _write_config(store.out_dir, config, points)
        todo = [p for p in points if not _is_done(store.records.get(p.point_id), retry_failed)]
        if todo:
            n_workers = min(workers or default_workers(), len(todo))
            _run_points(todo, points, config, store, n_workers, scheduler, progress)
        return _collect(points, store.records)


def load_results(out_dir: str | os.PathLike[str], config: SweepConfig | None = None) -> list[dict[str, Any]]:
    """Records in ``out_dir/results.jsonl`` sorted by point index (only ``config``'s points if given)."""
    records = read_results(Path(out_dir) / RESULTS_FILE)[0]
    if config is not None:
        return _collect(config.points(), records)
    return sorted(records.values(), key=lambda r: (r.get("index", 0), r.get("finished_at", "")))


# --- internals ------------------------------------------------------------------------
def _is_done(record: dict[str, Any] | None, retry_failed: bool) -> bool:
    return record is not None and (record.get("status") == "ok" or not retry_failed)


def _collect(points: Sequence[SweepPoint], records: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The records of ``points`` in point order, numbered and labelled as in this config."""
    return [{**records[p.point_id], "index": p.index, "values": dict(p.values)}
            for p in points if p.point_id in records]


def _task(point: SweepPoint, config: SweepConfig) -> PointTask:
    return PointTask(point.index, point.point_id, dict(point.values), point.omega_rpm, point.params,
                     point.numerics, config.duration_s, config.record_interval_s, config.node_record_interval_s,
                     config.save_trajectories)


def _write_config(out_dir: Path, config: SweepConfig, points: Sequence[SweepPoint]) -> None:
    """``sweep_config.json``: the configuration and each point's id, written atomically."""
    doc = {"config": config.to_dict(),
           "points": [{"index": p.index, "point_id": p.point_id, "values": p.values} for p in points]}
    tmp = out_dir / (CONFIG_FILE + ".tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, out_dir / CONFIG_FILE)


def _run_points(todo: Sequence[SweepPoint], points: Sequence[SweepPoint], config: SweepConfig,
                store: ResultsStore, workers: int, scheduler: Any | None, progress: bool) -> None:
    """Submit ``todo``, save each outcome as it arrives; Ctrl-C aborts, dead workers are reported."""
    by_id = {p.point_id: p for p in todo}
    try:
        failed_tasks = run_tasks([_task(p, config) for p in todo], store, workers=workers, scheduler=scheduler,
                                 progress=progress, total=len(points), desc="sweep")
    except TasksInterrupted:
        raise SweepInterrupted(_collect(points, store.reload()), len(points)) from None
    failed = [(by_id[t.point_id], why) for t, why in failed_tasks]
    if failed:
        point, why = min(failed, key=lambda f: f[0].index)
        raise SweepIncomplete(f"{len(failed)} of {len(points)} points did not finish (point {point.index}, "
                              f"{point.label()}: {why}); the finished ones are in {store.path}; run again with "
                              "--resume (resume=True) to run the rest", _collect(points, store.records), failed)
