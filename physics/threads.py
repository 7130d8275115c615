"""BLAS threads while the simulator runs: one, set with threadpoolctl around the run loop.

The dense linear algebra of a step is on ~500 x 500 matrices, where multi-threaded BLAS only adds
overhead and oversubscribes the cores when simulations run side by side (sweeps, vectorised
environments). ``physics.run.advance`` (the run loop under the environment, the CLI and
``run_simulation``) therefore holds BLAS at ``BLAS_THREADS`` threads while it steps and gives the
caller's setting back afterwards. Nothing here touches environment variables: importing the
package leaves ``OPENBLAS_NUM_THREADS`` and friends as the user set them (the batch worker
processes, which are ours, set them for themselves: ``batch.worker``).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

#: BLAS threads while the run loop steps (None: leave the caller's setting alone).
BLAS_THREADS: int | None = 1

_controller: Any = None


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


@contextmanager
def simulation_threads() -> Iterator[None]:
    """Within the block, BLAS uses ``BLAS_THREADS`` threads; afterwards, what it used before."""
    if BLAS_THREADS is None:
        yield
        return
    with _blas_controller().limit(limits=BLAS_THREADS, user_api="blas"):
        yield
