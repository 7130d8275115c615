"""What the turn-level surrogate needs beyond the turn map: the cruise speed and the motor's energy.

The turn map (``agents.turn_map``) holds each burst's turn and the head's displacement over it, not the
straight-swimming speed at omega_l nor the motor work |T omega| dt that ``FlagellumSteer-v0`` charges
(``flagellum_env.rewards``, term ``energy``), nor how a randomised swimmer's turn differs from the map's.
``scripts/calibrate_surrogate.py`` measures the first two and ``scripts/calibrate_surrogate_shift.py`` the last on
the preset's physics (seconds of CPU each), into ``agents/turn_maps/<preset>_surrogate.json``; this module reads
it.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from agents.assets import package_file

CALIBRATION_FORMAT = "flagellum-surrogate-calibration"


def calibration_file(preset: str) -> Path:
    """The shipped calibration of ``preset`` (it may not exist)."""
    return package_file("turn_maps", f"{preset}_surrogate.json")


@dataclass(frozen=True)
class SurrogateCalibration:
    """cruise_speed_m_s: steady speed at omega_l, m/s (the physics env's time budget uses it); cruise_power_w:
    mean motor power at omega_l, W; cruise_end_to_end_ratio: L'/L while cruising (the observation's entry the turn
    features read); burst_t_s, burst_energy_j: (K,) burst length (s, from 0, increasing) and the
    cumulative motor energy of a burst that long at omega_h (J), linear in between, extrapolated at the last
    slope beyond; omega_l_rpm, omega_h_rpm: the speeds measured at, rpm; burst_time_exponents: e_k of the burst
    time law t_map = t_c prod(f_k^e_k) per randomised factor f_k (``youngs_modulus``, ``viscosity``,
    ``head_radius``, ``pitch``, ``helix_radius``: the swimmer's value over the map's), from
    ``scripts/calibrate_surrogate_shift.py``."""

    preset: str
    omega_l_rpm: float
    omega_h_rpm: float
    cruise_speed_m_s: float
    cruise_power_w: float
    cruise_end_to_end_ratio: float
    burst_t_s: np.ndarray
    burst_energy_j: np.ndarray
    burst_time_exponents: dict[str, float]

    @functools.cached_property
    def burst_table(self) -> np.ndarray:
        """``burst_t_s`` and ``burst_energy_j`` stacked, (2, K) (``burst_energy_at``'s arrays; not to be changed)."""
        return np.stack([self.burst_t_s, self.burst_energy_j])

    def burst_energy(self, t_c: float) -> float:
        """Motor energy (J) of a burst of ``t_c`` s at omega_h."""
        return burst_energy_at(float(t_c), self.burst_t_s, self.burst_energy_j)

    @classmethod
    def load(cls, path: str | Path) -> SurrogateCalibration:
        """Read a file of ``scripts/calibrate_surrogate.py``; ValueError naming the file if it is not one."""
        path = Path(path)
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"cannot read the surrogate calibration {str(path)!r}: {exc}") from None
        if not isinstance(doc, dict) or doc.get("format") != CALIBRATION_FORMAT:
            raise ValueError(f"{str(path)!r} is not a surrogate calibration (no \"format\": \"{CALIBRATION_FORMAT}\")")
        try:
            burst = np.asarray(doc["burst_energy_j"], dtype=np.float64).reshape(-1, 2)
            return cls(preset=str(doc["preset"]), omega_l_rpm=float(doc["omega_l_rpm"]),
                       omega_h_rpm=float(doc["omega_h_rpm"]), cruise_speed_m_s=float(doc["cruise_speed_m_s"]),
                       cruise_power_w=float(doc["cruise_power_w"]),
                       cruise_end_to_end_ratio=float(doc["cruise_end_to_end_ratio"]), burst_t_s=burst[:, 0].copy(),
                       burst_energy_j=burst[:, 1].copy(),
                       burst_time_exponents={str(k): float(v) for k, v in doc["burst_time_exponents"].items()})
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"surrogate calibration {str(path)!r} is damaged: {exc}") from None


@njit(cache=True)
def burst_energy_at(t_c: float, t: np.ndarray, e: np.ndarray) -> float:
    """Motor energy (J) of a burst of ``t_c`` s from the cumulative energies ``e`` (K,) J at the burst lengths ``t``
    (K,) s (``SurrogateCalibration.burst_energy``): linear in between, at the last slope beyond."""
    k = t.shape[0] - 1
    if t_c <= t[k]:
        return np.interp(t_c, t, e)
    slope = (e[k] - e[k - 1]) / (t[k] - t[k - 1])
    return e[k] + slope * (t_c - t[k])
