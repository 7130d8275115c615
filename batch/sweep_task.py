"""One point of a parameter sweep: the task a worker runs (``batch.sweep``)."""

from __future__ import annotations

import os
import re
import socket
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

from batch.worker import PointOutcome
from physics.params import NumericsConfig, SwimmerParams

_ANSI = re.compile(r"\x1b\[[0-9;]*m")  # colour codes in some library errors (Numba)


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
        from batch.sweep_config import format_values

        return format_values(self.values)


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
