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
