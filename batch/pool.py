"""Run independent, picklable tasks in parallel and save each outcome the moment it arrives.

The engine under ``flagellum sweep``, ``flagellum calibrate-turns`` and ``flagellum evaluate``.
A task is any picklable object with ``point_id`` (str, unique and stable: the resume key),
``label()`` (str, for the progress bar) and ``execute() -> PointOutcome`` (run in a worker
process; it must not raise for a failed simulation but record it). Outcomes go to a
``ResultsStore`` (one fsync'ed JSON line each), so a crash loses only the tasks in flight and a
resumed run skips what is done.
"""

from __future__ import annotations

import asyncio
from collections.abc import Sequence
from typing import Any

from batch.backends import check_workers, default_workers, make_backend
from batch.store import ResultsStore


class TasksInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped ``run_tasks``; what finished is saved in the store."""


def pending(tasks: Sequence[Any], store: ResultsStore, retry_failed: bool = False) -> list[Any]:
    """The tasks without a record in ``store`` (or with a failed one when ``retry_failed``)."""
    out = []
    for t in tasks:
        rec = store.records.get(t.point_id)
        if rec is None or (retry_failed and rec.get("status") != "ok"):
            out.append(t)
    return out


def run_tasks(todo: Sequence[Any], store: ResultsStore, workers: int | None = None, scheduler: Any | None = None,
              progress: bool = True, total: int | None = None, desc: str = "tasks") -> list[tuple[Any, str]]:
    """Execute ``todo`` on ``workers`` local processes (default: all cores) or a Dask ``scheduler``.

    Each outcome's record is appended to ``store`` as it arrives. Returns the tasks that did not
    finish (worker died, or the task reported itself interrupted) with the reason. ``total``:
    the progress bar's total (default ``len(todo)``; larger when resuming). Ctrl-C cancels what is
    still running and raises ``TasksInterrupted``.
    """
    from tqdm import tqdm

    check_workers(workers)
    if not todo:
        return []
    total = len(todo) if total is None else total
    n_workers = None if scheduler is not None else min(workers or default_workers(), len(todo))
    backend = make_backend(n_workers or 1, scheduler)
    bar = tqdm(total=total, initial=total - len(todo), unit="task", desc=desc, disable=not progress,
               dynamic_ncols=True, smoothing=0.0)
    futures: dict[Any, Any] = {}
    failed: list[tuple[Any, str]] = []
    try:
        for task in todo:
            futures[backend.submit(task)] = task
        for fut in backend.as_completed(futures):
            task = futures[fut]
            try:
                outcome = fut.result()
            except (Exception, asyncio.CancelledError) as exc:  # worker died or task lost: it did not run
                failed.append((task, f"{type(exc).__name__}: {exc}"))
                continue
            if outcome.interrupted:  # partial run: not a result
                failed.append((task, "interrupted"))
                continue
            store.append(outcome.record, outcome.trajectory)
            bar.set_postfix_str(task.label(), refresh=False)
            bar.update(1)
    except KeyboardInterrupt:
        backend.abort(futures)
        raise TasksInterrupted(f"interrupted; finished tasks are saved in {store.path}") from None
    finally:
        bar.close()
        backend.close()
    return failed
