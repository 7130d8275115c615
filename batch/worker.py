"""What a worker process runs: the one-thread set-up and any task with an ``execute()`` method.

Importing this module loads no NumPy, so ``init_worker`` (the process pool's initializer)
sets the BLAS/OpenMP thread limits before the first point imports the physics.
"""

from __future__ import annotations

import os
import signal
from dataclasses import dataclass
from typing import Any

THREAD_LIMITS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                 "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1"}
"""Environment of a worker process: one thread per simulation; the pool supplies the parallelism."""


def init_worker() -> None:
    """Process-pool initializer: one BLAS thread, and leave Ctrl-C to the parent process."""
    os.environ.update(THREAD_LIMITS)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


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
