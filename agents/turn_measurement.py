"""The turn measurement of Sec. 3 / Fig. 5d of Huang & Jawed 2020 (used by ``agents.turn_map``,
``agents.turn_calibration`` and the fidelity benchmark).

From steady swimming at omega_l, measure the heading d0 (head displacement over one wobble
period, see ``agents.turn_geometry``), hover at omega_l for a chosen fraction of a
flagellum rotation (this selects the rotation phase at which the burst starts), run omega_h for
t_c, then omega_l again until the heading stops changing (two consecutive one-period headings
within ``straight_tol_deg``): that heading is t1. Recorded: theta, phi (paper's definitions, in
the head's body frame at the burst), psi (azimuth of t1 about d0 relative to the phase node),
the relaxation time and the head's displacement over the turn.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.turn_geometry import angle_between, azimuth, turn_angles, unit, wrap_angle
from physics.params import RPM_TO_RAD_S
from physics.run import advance

#: Observation shape nodes of the default environment; the phase node is the second of them.
DEFAULT_SHAPE_NODES = 8


def phase_node_index(n_nodes: int, n_shape_nodes: int = DEFAULT_SHAPE_NODES) -> int:
    """The node whose azimuth defines the flagellum's rotation phase: the environment's second
    observed shape node (``flagellum_env.observations``), a node near the base of the helix."""
    return int(np.round(np.linspace(1, n_nodes - 1, n_shape_nodes))[1])


@dataclass(frozen=True)
class TurnResult:
    """One calibration point. Angles in degrees, times in s, lengths in m."""

    t_c: float
    phase_deg: float     # hover, as a fraction of one flagellum rotation (deg), before the burst
    theta_deg: float
    phi_deg: float
    psi_deg: float       # azimuth of t1 about d0 relative to the phase node at the burst's start
    relax_s: float       # time at omega_l after the burst until the heading was steady
    straight: bool       # False if the heading did not settle within relax_max_s
    period_s: float      # wobble period (one flagellum rotation in the lab) at omega_l
    offset_m: tuple[float, float, float]  # head displacement burst start -> end of relaxation,
    #                                     # along (d0, phase-node direction, d0 x that)
    burst_end_ratio: float | None = None  # L'/L at the end of the burst
    # wall and CPU seconds the burst took (benchmarks; not part of the result's identity)
    burst_wall_s: float | None = field(default=None, compare=False)
    burst_cpu_s: float | None = field(default=None, compare=False)
    relax_cpu_s: float | None = field(default=None, compare=False)  # CPU seconds of the relaxation


def rotation_rate(sim: Any, phase_node: int, duration_s: float = 1.0) -> float:
    """Lab-frame rotation rate of the flagellum (rad/s, signed about the head's X_b); advances ``sim``."""
    axis = sim.head_orientation[:, 0]
    a0 = azimuth(sim.nodes[phase_node] - sim.head_position, axis)
    advance(sim, duration_s)
    a1 = azimuth(sim.nodes[phase_node] - sim.head_position, axis)
    return wrap_angle(a1 - a0) / duration_s


@dataclass(frozen=True)
class CruiseObservables:
    """What a controller sees of the swimmer while it cruises at omega_l (before any turn).

    strain: mean end-to-end strain L'/L - 1 (the flagellum is stretched by the load it carries,
    about mu omega L^4 / EI); strain_sem: its standard error. rotation_rate: lab rotation rate of
    the phase node about the head's initial axis, rad/s (least-squares slope of the unwrapped
    azimuth; it moves with the head's rotational drag mu b^3); rotation_rate_std: its standard
    error. samples: how many. Both readings feed ``agents.online_turn_map``.
    """

    strain: float
    strain_sem: float
    rotation_rate: float
    rotation_rate_std: float
    samples: int


def summarise_cruise(strains: np.ndarray, azimuths: np.ndarray, sample_s: float) -> CruiseObservables:
    """``CruiseObservables`` from samples every ``sample_s`` s: strains L'/L - 1 (n,) and azimuths
    (n,) rad of the phase node about a fixed axis; n >= 3 (ValueError otherwise)."""
    x = np.asarray(strains, dtype=np.float64)
    a = np.unwrap(np.asarray(azimuths, dtype=np.float64))
    n = x.size
    if n < 3 or a.size != n:
        raise ValueError(f"need at least 3 strain and azimuth samples of the same count; got {x.size} and {a.size}")
    t = np.arange(n) * sample_s
    tc = t - t.mean()
    slope = float(tc @ (a - a.mean()) / (tc @ tc))
    resid = a - a.mean() - slope * tc
    slope_std = float(np.sqrt(resid @ resid / (n - 2) / (tc @ tc)))
    return CruiseObservables(float(x.mean()), float(x.std(ddof=1) / math.sqrt(n)), slope, slope_std, n)


def cruise_observables(sim: Any, phase_node: int, duration_s: float = 6.0, sample_s: float = 0.1
                       ) -> CruiseObservables:
    """Cruise at the current motor speed for ``duration_s``, sampling every ``sample_s`` as a
    controller would; advances ``sim``."""
    axis = sim.head_orientation[:, 0]
    strains, azimuths = [], []
    for _ in range(max(3, round(duration_s / sample_s))):
        strains.append(sim.end_to_end_ratio() - 1.0)
        azimuths.append(azimuth(sim.nodes[phase_node] - sim.head_position, axis))
        advance(sim, sample_s)
    return summarise_cruise(np.array(strains), np.array(azimuths), sample_s)


def heading(sim: Any, period_s: float) -> np.ndarray:
    """Advance one wobble period at the current motor speed; the unit head displacement (3,)."""
    x0 = sim.head_position
    advance(sim, period_s)
    return unit(sim.head_position - x0)


def measure_turn(sim: Any, omega_l_rpm: float, omega_h_rpm: float, t_c: float, phase_deg: float = 0.0,
                 phase_node: int | None = None, relax_max_s: float = 150.0,
                 straight_tol_deg: float = 1.0) -> TurnResult:
    """One turn from the simulator's current steady state at omega_l; mutates ``sim``."""
    if phase_node is None:
        phase_node = phase_node_index(sim.nodes.shape[0])
    sim.set_motor_speed(omega_l_rpm * RPM_TO_RAD_S)
    rate = rotation_rate(sim, phase_node)
    if abs(rate) < 1e-3:
        raise ValueError(f"the flagellum hardly rotates at omega_l={omega_l_rpm} rpm ({rate:.2e} rad/s)")
    period = 2.0 * math.pi / abs(rate)
    d0 = heading(sim, period)
    if phase_deg % 360.0:
        advance(sim, period * (phase_deg % 360.0) / 360.0)
    frame = sim.head_orientation
    start = sim.head_position
    ref = sim.nodes[phase_node] - start
    ref_az = azimuth(ref, d0)
    burst_end_ratio = burst_wall = burst_cpu = None
    if t_c > 0.0:
        sim.set_motor_speed(omega_h_rpm * RPM_TO_RAD_S)
        w0, c0 = time.perf_counter(), time.process_time()
        advance(sim, t_c)
        burst_wall, burst_cpu = time.perf_counter() - w0, time.process_time() - c0
        burst_end_ratio = float(sim.end_to_end_ratio())
        sim.set_motor_speed(omega_l_rpm * RPM_TO_RAD_S)
    t_relax0, c_relax0 = sim.time, time.process_time()
    prev = heading(sim, period)
    straight = False
    while sim.time - t_relax0 < relax_max_s:
        cur = heading(sim, period)
        settled = math.degrees(angle_between(prev, cur)) < straight_tol_deg
        prev = cur
        if settled:
            straight = True
            break
    theta, phi = turn_angles(d0, prev, frame)
    psi = math.degrees(wrap_angle(azimuth(prev, d0) - ref_az))
    e_ref = unit(ref - (ref @ d0) * d0)
    disp = sim.head_position - start
    offset = (float(disp @ d0), float(disp @ e_ref), float(disp @ np.cross(d0, e_ref)))
    return TurnResult(t_c=float(t_c), phase_deg=float(phase_deg), theta_deg=theta, phi_deg=phi, psi_deg=psi,
                      relax_s=sim.time - t_relax0, straight=straight, period_s=period, offset_m=offset,
                      burst_end_ratio=burst_end_ratio, burst_wall_s=burst_wall, burst_cpu_s=burst_cpu,
                      relax_cpu_s=time.process_time() - c_relax0)
