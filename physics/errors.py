"""Errors raised by the physics core."""

from __future__ import annotations


class SimulationError(RuntimeError):
    """The simulation cannot continue; the message names the step, time and quantity.

    Attributes: step (int), time_s (float), quantity (str).
    """

    def __init__(self, message: str, step: int, time_s: float, quantity: str) -> None:
        super().__init__(f"step {step} (t = {time_s:.6g} s): {message}")
        self.step = step
        self.time_s = time_s
        self.quantity = quantity


class StepFailed(Exception):
    """A step could not be completed (the simulator halves the step, retries it shorter or raises
    SimulationError); ``quantity`` names what failed."""

    def __init__(self, quantity: str, message: str) -> None:
        super().__init__(message)
        self.quantity = quantity


def is_interrupt(exc: BaseException | None) -> bool:
    """True for a ``KeyboardInterrupt`` (Ctrl-C, or SIGTERM turned into one), also when it surfaced from inside a
    compiled (Numba) call as ``SystemError: ... returned a result with an exception set``: the signal's handler
    raised while the kernel ran, and Python reports the kernel, not the interrupt."""
    seen = 0
    while exc is not None and seen < 10:
        if isinstance(exc, KeyboardInterrupt):
            return True
        if not isinstance(exc, SystemError):
            return False
        exc = exc.__cause__ or exc.__context__
        seen += 1
    return False
