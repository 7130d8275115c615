"""What a worker process runs: the one-thread set-up and any task with an ``execute()`` method.

Importing this module loads no NumPy, so ``init_worker`` (the process pool's initializer)
sets the BLAS/OpenMP thread limits before the first point imports the physics.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from dataclasses import dataclass
from typing import Any

THREAD_LIMITS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                 "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1"}
"""Environment of a worker process: one thread per simulation; the pool supplies the parallelism."""


#: How often a worker checks that the process that started it is still alive, s.
PARENT_CHECK_INTERVAL_S = 1.0


def init_worker(parent_pid: int | None = None) -> None:
    """Process-pool initializer: one BLAS thread, leave Ctrl-C to the parent process, and exit when the
    parent (``parent_pid``, passed by the pool's creator) dies (``watch_parent``)."""
    os.environ.update(THREAD_LIMITS)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent_pid is not None:
        watch_parent(parent_pid)


def watch_parent(parent_pid: int, interval_s: float = PARENT_CHECK_INTERVAL_S) -> None:
    """Exit this process as soon as its parent ``parent_pid`` is gone (killed with SIGKILL, say), instead of
    finishing its task for nobody while holding the caller's terminal: a daemon thread compares
    ``os.getppid()`` with it every ``PARENT_CHECK_INTERVAL_S``. The pid comes from the parent itself, so a
    parent that died before this worker started is noticed too (the worker's parent is then another)."""
    if os.getppid() != parent_pid:
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(interval_s)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


@dataclass
class PointOutcome:
    """A worker's answer: the JSON-ready record, the trajectory (or None) and whether Ctrl-C cut it short."""

    record: dict[str, Any]
    trajectory: Any | None
    interrupted: bool = False


def execute_task(task: Any) -> PointOutcome:
    """What a worker process runs for any task with an ``execute() -> PointOutcome`` method
    (sweep points, turn calibrations, path-following episodes)."""
    return task.execute()
