"""What a sweep worker runs: the one-thread set-up and the simulation of one point.

Importing this module loads no NumPy, so ``init_worker`` (the process pool's initializer)
sets the BLAS/OpenMP thread limits before the first point imports the physics.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

from physics.params import NumericsConfig, SwimmerParams

THREAD_LIMITS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                 "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1"}
"""Environment of a worker process: one thread per simulation; the pool supplies the parallelism."""

_ANSI = re.compile(r"\x1b\[[0-9;]*m")  # colour codes in some library errors (Numba)


def init_worker() -> None:
    """Process-pool initializer: one BLAS thread, and leave Ctrl-C to the parent process."""
    os.environ.update(THREAD_LIMITS)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@dataclass(frozen=True)
class PointTask:
    """Everything a worker needs for one point (picklable). Times in s, speed in rpm."""

    index: int
    point_id: str
    values: dict[str, Any]
    omega_rpm: float
    params: SwimmerParams
    numerics: NumericsConfig
    duration_s: float
    record_interval_s: float
    node_record_interval_s: float
    keep_trajectory: bool

    def execute(self) -> PointOutcome:
        return run_point(self)

    def label(self) -> str:
        from flagellum.sweep_config import format_values

        return format_values(self.values)


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


def run_point(task: PointTask) -> PointOutcome:
    """Simulate one point at constant speed; never raises for a failed simulation.

    A ``SimulationError`` keeps the partial summary; any other exception gives ``summary``
    None. Both set ``status`` "error" and ``error`` to the message.
    """
    from physics.run import run_simulation  # NumPy/Numba load here, after init_worker
    from physics.schedule import MotorSchedule

    t0 = time.perf_counter()
    summary: dict[str, Any] | None = None
    trajectory = None
    interrupted = False
    try:
        result = run_simulation(task.params, task.numerics, MotorSchedule.constant(task.omega_rpm),
                                task.duration_s, record_interval_s=task.record_interval_s,
                                node_record_interval_s=task.node_record_interval_s, progress=False)
    except Exception as exc:  # a point that cannot run must not stop the sweep
        error: str | None = _ANSI.sub("", f"{type(exc).__name__}: {exc}")
    else:
        summary, error, interrupted = result.summary, result.error, result.interrupted
        trajectory = result.trajectory if task.keep_trajectory else None
    record = {
        "index": task.index,
        "point_id": task.point_id,
        "values": dict(task.values),
        "status": "ok" if error is None else "error",
        "error": error,
        "wall_time_s": time.perf_counter() - t0,
        "summary": summary,
        "trajectory": None,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
        "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    return PointOutcome(record, trajectory, interrupted)
