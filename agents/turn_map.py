"""Turn map of Sec. 3 / Fig. 5d of Huang & Jawed 2020: turning angle theta and out-of-plane
angle phi produced by a burst of t_c seconds at the high motor speed omega_h, starting from
steady straight swimming at omega_l.

Definitions (Fig. 5a): the world frame is the body frame at the start of the turn; d0 is the
swimming direction before the burst, t1 the direction after the swimmer has relaxed back to
straight swimming at omega_l. theta = angle(d0, t1); phi = angle between t1 and the x-y plane
of that frame (signed, positive towards +Z_b). The paper's world axes are (-X_b, -Y_b, Z_b);
theta and phi do not depend on that choice of sign of x and y.

Directions are measured from the head's displacement over whole motor turns (which cancels
the wobble of the head at the motor frequency).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from physics.params import RPM_TO_RAD_S
from physics.simulator import Simulator


@dataclass(frozen=True)
class TurnResult:
    """One calibration point. Angles in degrees; times in seconds."""

    t_c: float
    phase_deg: float  # motor phase (relative to the start of hovering) at which the burst began
    theta_deg: float
    phi_deg: float
    relax_s: float  # time at omega_l until the path was straight again
    straight: bool  # False if it did not straighten within the allowed time


def turn_angles(d0: np.ndarray, t1: np.ndarray, frame: np.ndarray) -> tuple[float, float]:
    """(theta, phi) in degrees for unit directions d0, t1 (lab) in the body frame ``frame`` (3,3)."""
    t = frame.T @ (t1 / np.linalg.norm(t1))
    d = frame.T @ (d0 / np.linalg.norm(d0))
    theta = math.degrees(math.acos(float(np.clip(d @ t, -1.0, 1.0))))
    phi = math.degrees(math.asin(float(np.clip(t[2], -1.0, 1.0))))
    return theta, phi


def heading_over_turns(sim: Simulator, omega_rad_s: float, turns: float = 1.0) -> np.ndarray:
    """Advance ``turns`` motor turns at omega and return the unit head displacement (3,)."""
    sim.set_motor_speed(omega_rad_s)
    x0 = sim.head_position
    sim.advance(turns * 2.0 * math.pi / abs(omega_rad_s))
    d = sim.head_position - x0
    return d / np.linalg.norm(d)


def measure_turn(sim: Simulator, omega_l_rpm: float, omega_h_rpm: float, t_c: float, hover_s: float = 0.0,
                 relax_max_s: float = 120.0, straight_tol_deg: float = 1.0) -> TurnResult:
    """Run one turn from the simulator's current (steady, omega_l) state; mutates ``sim``.

    hover_s: time at omega_l before the burst (selects the motor phase). Relaxation ends when two
    consecutive one-turn headings differ by less than ``straight_tol_deg``.
    """
    wl, wh = omega_l_rpm * RPM_TO_RAD_S, omega_h_rpm * RPM_TO_RAD_S
    d0 = heading_over_turns(sim, wl, 1.0)
    if hover_s > 0:
        sim.set_motor_speed(wl)
        sim.advance(hover_s)
    frame = sim.head_orientation
    phase = math.degrees((hover_s * wl) % (2 * math.pi))
    if t_c > 0:
        sim.set_motor_speed(wh)
        sim.advance(t_c)
    t_relax0 = sim.time
    prev = heading_over_turns(sim, wl, 1.0)
    straight = False
    while sim.time - t_relax0 < relax_max_s:
        cur = heading_over_turns(sim, wl, 1.0)
        if math.degrees(math.acos(float(np.clip(prev @ cur, -1, 1)))) < straight_tol_deg:
            straight = True
            prev = cur
            break
        prev = cur
    theta, phi = turn_angles(d0, prev, frame)
    return TurnResult(t_c=t_c, phase_deg=phase, theta_deg=theta, phi_deg=phi,
                      relax_s=sim.time - t_relax0, straight=straight)
