"""BLAS threads while the simulator runs: one, set with threadpoolctl around the run loop.

The dense linear algebra of a step is on ~500 x 500 matrices, where multi-threaded BLAS only adds
overhead and oversubscribes the cores when simulations run side by side (sweeps, vectorised
environments). ``Simulator.step`` / ``Simulator.advance`` and ``physics.run.advance`` (the run loop under the
environment, the CLI and ``run_simulation``) therefore hold BLAS at ``BLAS_THREADS`` threads while they
step and give the caller's setting back afterwards (a step also gives the same numbers whoever calls it). Nothing here touches environment variables: importing the
package leaves ``OPENBLAS_NUM_THREADS`` and friends as the user set them (the batch worker
processes, which are ours, set them for themselves: ``batch.worker``).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

#: BLAS threads while the run loop steps (None: leave the caller's setting alone).
BLAS_THREADS: int | None = 1

_controller: Any = None
_blas_libraries: list[Any] | None = None
_depth = threading.local()  # blocks entered in this thread: only the outermost one sets and restores
F = TypeVar("F", bound=Callable[..., Any])


def _blas_controller() -> Any:
    """One ``threadpoolctl.ThreadpoolController`` per process (building one costs milliseconds; using it,
    some 20 microseconds), made after the BLAS libraries of NumPy and SciPy are loaded."""
    global _controller
    if _controller is None:
        import numpy  # noqa: F401
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    return _controller


def _blas_libs() -> list[Any]:
    """The BLAS libraries' threadpoolctl controllers (``LibController``: ``num_threads``, ``set_num_threads``)."""
    global _blas_libraries
    if _blas_libraries is None:
        _blas_libraries = list(_blas_controller().select(user_api="blas").lib_controllers)
    return _blas_libraries


@contextmanager
def simulation_threads() -> Iterator[None]:
    """Within the block, BLAS uses ``BLAS_THREADS`` threads; afterwards, what it used before. Nested blocks
    cost nothing (the outermost one holds the limit). The outermost block reads each BLAS library's thread
    count and sets only those that differ (what ``ThreadpoolController.limit`` does, without building the info
    of every library on each entry: ~2 us instead of ~19 us per block, paid at every env step)."""
    depth = getattr(_depth, "n", 0)
    if BLAS_THREADS is None or depth:
        _depth.n = depth + 1
        try:
            yield
        finally:
            _depth.n = depth
        return
    libs = _blas_libs()
    before = [lib.num_threads for lib in libs]
    for lib, n in zip(libs, before):
        if n != BLAS_THREADS:
            lib.set_num_threads(BLAS_THREADS)
    _depth.n = 1
    try:
        yield
    finally:
        _depth.n = 0
        for lib, n in zip(libs, before):
            if n != BLAS_THREADS:
                lib.set_num_threads(n)


def one_blas_thread(func: F) -> F:
    """Decorator: ``func`` runs inside ``simulation_threads()`` (``Simulator.step`` and ``advance``, so a step
    gives the same numbers whoever calls it: BLAS sums in another order with more threads)."""
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with simulation_threads():
            return func(*args, **kwargs)
    return wrapper  # type: ignore[return-value]
