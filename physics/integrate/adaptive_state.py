"""The step-size controller's state between steps (``time_integrator``): one object, owned by the stepped
``Simulator`` (``Simulator.adaptive``), that both step paths read and write by its public names: the Python step
(``Simulator._adaptive``, ``_commit``, ``_after_accept``) and the compiled span of Newton-Krylov steps
(``krylov_span.run_krylov_span``).

Variable-step BDF of order k (Hairer & Wanner, *Solving ODEs II*, Sec. III.5) takes its base values from the last
k accepted points, and Milne's error estimate from one more, so the accepted points since the last kink of the
motion are kept (``history``, at most five: BDF4 and its estimate). A kink (a start, a motor-speed change,
``set_state``) restarts them: no multistep formula, nor the extrapolation of the forces, may cross it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from physics.integrate.time_integrator import History


@dataclass(eq=False)
class AdaptiveState:
    """What the controller carries from one step to the next (SI units)."""

    h: float  # the controller's next step, s
    history: History = field(default_factory=History)  # accepted points (t s, q, v (ndof,)) since the restart
    h_prev: float = -1.0  # the last accepted step, s (-1: none yet)
    #: the velocity (ndof,) before the last accepted step if that step had the length of the one before it, else
    #: None: implicit Euler's constant-acceleration predictor (``Simulator._euler_base``)
    v_prev: np.ndarray | None = None
    restart: bool = True  # the history restarts at the next step (a kink of the motion)
    order_capped: bool = False  # BDF2 until the next motor-speed change (``time_integrator.COLLAPSED_STEPS``)
    #: the flagellum's node forces at the last accepted points since the restart (t s, (n, 3) N), oldest first, at
    #: most ``EXTRAPOLATION_POINTS``: the Newton-Krylov step starts its force unknowns from their extrapolation
    force_points: list[tuple[float, np.ndarray]] = field(default_factory=list)

    def kink(self) -> None:
        """The motion has a kink here (a motor-speed change): restart the history, lift the order cap and drop the
        force points."""
        self.restart = True
        self.order_capped = False
        self.force_points = []

    def reset(self, h_start: float) -> None:
        """Forget everything but the history (``Simulator.set_state``): the next step restarts at h_start (s)."""
        self.v_prev = None
        self.h_prev = -1.0
        self.restart = True
        self.order_capped = False
        self.force_points = []
        self.h = h_start
