"""Where tasks run: a local process pool or a Dask distributed cluster.

Both offer the same four calls, used by ``batch.pool.run_tasks`` (sweeps, turn calibration,
evaluation) and ``flagellum_bench.fidelity.run_fidelity`` (``flagellum bench``): ``submit(task)`` ->
future, ``as_completed(futures)`` -> futures as they finish, ``abort(futures)`` (Ctrl-C:
drop what has not finished) and ``close()``. Futures answer ``result()`` with a
``PointOutcome``, or raise when the infrastructure failed (a worker process died).
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import re
import socket
import uuid
from collections.abc import Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Protocol

from batch.store import SweepError
from batch.worker import execute_task, init_worker


class BackendError(SweepError):
    """The backend cannot be used (Dask missing, scheduler unreachable)."""


#: Seconds to wait for a Dask scheduler that accepts the connection but does not answer.
SCHEDULER_TIMEOUT_S = 10
_ADDRESS = re.compile(r"^(?:(?P<proto>[a-z][a-z0-9+]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+):(?P<port>\d{1,5})$")


def check_scheduler_address(address: str) -> tuple[str, str, int]:
    """``(protocol, host, port)`` of a Dask scheduler address ``[PROTOCOL://]HOST:PORT``; BackendError if malformed."""
    m = _ADDRESS.match(address.strip()) if isinstance(address, str) else None
    if m is None or not 0 < int(m["port"]) < 65536:
        raise BackendError(f"--scheduler {address!r} is not allowed; allowed: a Dask scheduler address "
                           "tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786)")
    return m["proto"] or "tcp", m["host"].strip("[]"), int(m["port"])


def probe_scheduler(address: str) -> None:
    """Fail at once (not after Dask's 30 s of retries) when nothing listens at a TCP address."""
    proto, host, port = check_scheduler_address(address)
    if proto != "tcp":
        return
    try:
        socket.create_connection((host, port), timeout=SCHEDULER_TIMEOUT_S).close()
    except OSError as exc:
        raise BackendError(f"cannot connect to the Dask scheduler {address!r}: {exc.strerror or exc}; start one "
                           "(dask scheduler) or check the address") from None


class Backend(Protocol):
    description: str

    def submit(self, task: Any) -> Any: ...
    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]: ...
    def abort(self, futures: Iterable[Any]) -> None: ...
    def close(self) -> None: ...


#: Most local worker processes (each is a Python process with its own simulation; beyond this a typo such as
#: ``--workers 100000`` would exhaust the machine before any task ran).
MAX_WORKERS = 256


def check_workers(workers: int | None) -> int | None:
    """``workers`` if it is None or an integer from 1 to ``MAX_WORKERS``; ValueError naming it otherwise."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or not 1 <= workers <= MAX_WORKERS):
        raise ValueError(f"workers={workers!r} is not allowed; allowed: an integer >= 1 and <= {MAX_WORKERS} "
                         "(default: all cores)")
    return workers


def default_workers() -> int:
    """Cores this process may use (respects taskset/cgroup affinity where the OS reports it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS, Windows
        return max(1, os.cpu_count() or 1)


class LocalBackend:
    """``workers`` fresh (spawned) processes with one BLAS thread each."""

    def __init__(self, workers: int) -> None:
        # spawn, not fork: a forked child inherits the parent's BLAS thread pool and threads
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=init_worker, initargs=(os.getpid(),))
        self.description = f"{workers} local worker process{'es' if workers != 1 else ''}"

    def submit(self, task: Any) -> concurrent.futures.Future:
        return self._pool.submit(execute_task, task)

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]:
        return concurrent.futures.as_completed(list(futures))

    def abort(self, futures: Iterable[Any]) -> None:
        """Cancel queued points and stop the running ones (their partial work is dropped)."""
        terminate = getattr(self._pool, "terminate_workers", None)  # Python >= 3.14
        if terminate is None:
            self.interrupt(futures)  # SIGTERM: a task that does not handle it stops at once
            return
        for fut in futures:
            fut.cancel()
        terminate()

    def interrupt(self, futures: Iterable[Any]) -> None:
        """Cancel queued tasks and send SIGTERM to the workers: a task that handles it (an episode of
        ``agents.path_following.FollowTask``) returns what it computed; one that does not loses its worker."""
        for fut in futures:
            fut.cancel()
        for proc in list((getattr(self._pool, "_processes", None) or {}).values()):
            if proc.is_alive():
                proc.terminate()

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskBackend:
    """Points as tasks on a Dask distributed cluster.

    ``scheduler``: an address ``"tcp://HOST:PORT"``, a cluster object with
    ``scheduler_address`` (``LocalCluster``, ``SLURMCluster``...) or a ``distributed.Client``
    (left open on ``close``). Workers need this package installed; start them with
    ``--nthreads 1`` so each simulation has a core (Dask's nanny already sets one BLAS thread).
    """

    def __init__(self, scheduler: Any) -> None:
        try:
            import distributed
        except ImportError:
            raise BackendError("a Dask scheduler was given but dask.distributed is not installed; "
                               "pip install 'dask[distributed]' (or the package's [cluster] extra)") from None
        self._distributed = distributed
        self._own_client = not isinstance(scheduler, distributed.Client)
        if self._own_client:
            address = getattr(scheduler, "scheduler_address", scheduler)
            if not isinstance(address, str):
                raise BackendError(f"scheduler={scheduler!r} is not allowed; allowed: an address 'tcp://HOST:PORT', "
                                   "a cluster object or a distributed.Client")
            probe_scheduler(address)
            try:
                self.client = distributed.Client(address, timeout=SCHEDULER_TIMEOUT_S)
            except Exception as exc:  # OSError, TimeoutError, ValueError for a malformed address
                raise BackendError(f"cannot connect to the Dask scheduler {address!r}: {exc}") from None
        else:
            self.client = scheduler
        self._token = uuid.uuid4().hex[:8]  # keys unique to this run
        self.description = f"Dask cluster {self.client.scheduler.address}"

    def submit(self, task: Any) -> Any:
        return self.client.submit(execute_task, task, key=f"flagellum-sweep-{task.point_id}-{self._token}",
                                  pure=False)

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]:
        return iter(self._distributed.as_completed(list(futures)))

    def abort(self, futures: Iterable[Any]) -> None:
        self.client.cancel(list(futures))

    def close(self) -> None:
        if self._own_client:
            self.client.close()


def make_backend(workers: int, scheduler: Any | None) -> Backend:
    """``DaskBackend(scheduler)`` when a scheduler is given, else ``LocalBackend(workers)``."""
    return LocalBackend(workers) if scheduler is None else DaskBackend(scheduler)
