"""The step-size controller's state between steps (``time_integrator``): one object, owned by the stepped
``Simulator`` (``Simulator.adaptive``), that both step drivers read and write by its public names: the Python one
(``Simulator._adaptive``) and the compiled span of Newton-Krylov steps (``krylov_span.run_krylov_span``), each
through the compiled functions of ``adaptive_step``.

Variable-step BDF of order k (Hairer & Wanner, *Solving ODEs II*, Sec. III.5) takes its base values from the last
k accepted points, and Milne's error estimate from one more, so the accepted points since the last kink of the
motion are kept (at most ``HISTORY_POINTS``: BDF4 and its estimate). A kink (a start, a motor-speed change,
``set_state``) restarts them: no multistep formula, nor the extrapolation of the forces, may cross it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physics.integrate.adaptive_step import HISTORY_POINTS
from physics.integrate.time_integrator import (EXTRAPOLATION_POINTS, StepBase, base_kernel, extrapolate_kernel,
                                              order_after)


@dataclass(eq=False)
class AdaptiveState:
    """What the controller carries from one step to the next (SI units). The points' arrays are filled oldest
    first, ``count`` and ``force_count`` of their rows valid (``adaptive_step.push_point``)."""

    h: float  # the controller's next step, s
    times: np.ndarray  # (HISTORY_POINTS,) s: the accepted points since the restart
    qs: np.ndarray  # (HISTORY_POINTS, ndof) their configurations
    vs: np.ndarray  # (HISTORY_POINTS, ndof) their velocities
    #: the flagellum's node forces at the last accepted points since the restart: times (EXTRAPOLATION_POINTS,) s
    #: and forces (EXTRAPOLATION_POINTS, 3 n) N; the Newton-Krylov step starts its force unknowns from their
    #: extrapolation (``time_integrator.extrapolate_kernel``)
    force_times: np.ndarray
    force_values: np.ndarray
    count: int = 0
    force_count: int = 0
    h_prev: float = -1.0  # the last accepted step, s (-1: none yet)
    #: the velocity (ndof,) before the last accepted step if that step had the length of the one before it, else
    #: None: implicit Euler's constant-acceleration predictor (``Simulator._euler_base``)
    v_prev: np.ndarray | None = None
    restart: bool = True  # the history restarts at the next step (a kink of the motion)
    order_capped: bool = False  # BDF2 until the next motor-speed change (``time_integrator.COLLAPSED_STEPS``)

    @classmethod
    def empty(cls, h: float, ndof: int, n_nodes: int) -> AdaptiveState:
        """No points yet, the next step h (s), for ndof DOFs and n_nodes nodes."""
        return cls(h=h, times=np.zeros(HISTORY_POINTS), qs=np.zeros((HISTORY_POINTS, ndof)),
                   vs=np.zeros((HISTORY_POINTS, ndof)), force_times=np.zeros(EXTRAPOLATION_POINTS),
                   force_values=np.zeros((EXTRAPOLATION_POINTS, 3 * n_nodes)))

    def restart_at(self, t: float, q: np.ndarray, v: np.ndarray) -> None:
        """The points restart from (t s, q, v (ndof,)) alone."""
        self.times[0], self.qs[0], self.vs[0] = t, q, v
        self.count = 1
        self.restart = False

    def base(self, h: float, top: int) -> StepBase:
        """The base of a step of h (s) from the newest point, for a scheme of largest order ``top``
        (``time_integrator.base_kernel``: BDF base, predictor and error ratio)."""
        order = order_after(top, self.count)
        m = min(self.count, order + 1)
        q_hat, v_hat, h_eff, q_pred, ratio = base_kernel(self.times[self.count - m:self.count],
                                                         self.qs[self.count - m:self.count],
                                                         self.vs[self.count - m:self.count], h, order)
        return StepBase(h, h_eff, q_hat, v_hat, q_pred, order, None if ratio < 0.0 else ratio)

    def force_start(self, t_new: float) -> np.ndarray | None:
        """The node forces (3 n,) N extrapolated from the force points to t_new (s) (``extrapolate_kernel``); None
        without force points."""
        k = self.force_count
        if k == 0:
            return None
        return extrapolate_kernel(self.force_times[:k].copy(), self.force_values[:k].copy(), t_new)

    def kink(self) -> None:
        """The motion has a kink here (a motor-speed change): restart the history, lift the order cap and drop the
        force points."""
        self.restart = True
        self.order_capped = False
        self.force_count = 0

    def reset(self, h_start: float) -> None:
        """Forget everything (``Simulator.set_state``): the next step restarts at h_start (s)."""
        self.v_prev = None
        self.h_prev = -1.0
        self.restart = True
        self.order_capped = False
        self.force_count = 0
        self.h = h_start
