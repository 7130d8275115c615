"""Turn map of Sec. 3 / Fig. 5d of Huang & Jawed 2020: what a burst of t_c seconds at the high
motor speed omega_h does to a swimmer that was swimming straight at omega_l.

One measurement (``agents.turn_measurement.measure_turn``): the heading, a burst of t_c
at omega_h, and the heading after it has settled: theta, phi, psi, the relaxation time and
the head's displacement over the turn.

A ``TurnMap`` holds many measurements (t_c x phase) with the physical and numerical
parameters they were made for, and answers the planner's questions: the largest reachable
theta, the t_c for a wanted theta (on the rising branch of theta(t_c)) and the psi of that
t_c. It is saved as a versioned JSON file; using it for other physical parameters or other
speeds raises ``TurnMapMismatch`` naming what differs.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from agents.turn_geometry import wrap_angle
from agents.turn_measurement import TurnResult
from physics.params import REMOVED_PARAMETERS, NumericsConfig, SwimmerParams, removed_message

TURN_MAP_FORMAT = "flagellum-turn-map"
TURN_MAP_VERSION = 1
#: Motor speeds of the paper's protocol (Sec. 3), rpm.
PAPER_OMEGA_L_RPM = 10.0
PAPER_OMEGA_H_RPM = 60.0
#: Burst speed used for planning. The default swimmer (flagellum at omega in the lab, head held) buckles
#: at 52 rpm for b = 1.2 cm, so the paper's 60 rpm turns it (R9), but slowly: 39-49 s of burst for 30-90 deg
#: while the head drifts ~17 cm. At 90 and 150 rpm one burst turns it by up to 172 and 138 deg in 13 and
#: 3.75 s; on development paths with swimmers randomised by +-10 % the adaptive planners kept every path at
#: 150 rpm and lost a quarter to a third of them at 90 rpm (docs/planner.md measures all three).
PLANNER_OMEGA_H_RPM = 150.0
#: Burst lengths of a calibration, s: at 150 rpm theta rises from ~1 deg (1.5 s) to ~140 deg (3.75 s),
#: steepest at the end (~200 deg/s), hence the 0.125 s steps there; 4-10 s samples the buckled regime.
DEFAULT_T_C_S = (1.0, 1.5, 2.0, 2.5, 2.75, 3.0, 3.125, 3.25, 3.375, 3.5, 3.625, 3.75, 3.875, 4.0, 4.5, 5.0, 6.0,
                 8.0, 10.0)
DEFAULT_PHASES_DEG = (0.0, 90.0, 180.0, 270.0)


def leading_within(theta_rad: np.ndarray, cap_rad: float) -> int:
    """How many of the candidate turns ``theta_rad`` (rad, in order of burst length) a planner keeps under the cap
    ``cap_rad`` (``PlannerConfig.burst_cap_deg``): those before the first larger one, at least one."""
    over = np.flatnonzero(np.asarray(theta_rad) > cap_rad)
    return max(1, int(over[0])) if over.size else len(theta_rad)


class TurnMapMismatch(ValueError):
    """A turn map used for physical parameters or motor speeds other than its own."""


# --- the map --------------------------------------------------------------------------------

@njit(cache=True)
def branch_theta_deg(t_c: float, t: np.ndarray, theta_deg: np.ndarray) -> float:
    """The turn (deg) of a burst of ``t_c`` s on the rising branch (t (K,) s, theta_deg (K,)), held at its ends
    (``TurnMap.theta_for``): np.interp."""
    return np.interp(t_c, t, theta_deg)


@njit(cache=True)
def psi_deg_at(t_c: float, t: np.ndarray, psi_unwrapped_deg: np.ndarray) -> float:
    """psi (deg, wrapped to (-180, 180]) of a burst of ``t_c`` s from psi unwrapped (deg) at the burst lengths ``t``
    (s), interpolated (``TurnMap.psi_for``)."""
    return math.degrees(wrap_angle(math.radians(np.interp(t_c, t, psi_unwrapped_deg))))


@dataclass(frozen=True)
class TurnMap:
    """Calibrated turns for one swimmer (``params``) and one pair of motor speeds (rpm)."""

    params: SwimmerParams
    numerics: NumericsConfig
    preset: str | None
    omega_l_rpm: float
    omega_h_rpm: float
    phase_node: int
    points: tuple[TurnResult, ...]
    meta: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if not self.points:
            raise ValueError("a turn map needs at least one measured turn")

    # --- summary per burst length ---------------------------------------------------------
    def t_c_values(self) -> np.ndarray:
        """Distinct burst lengths, increasing, s."""
        return np.array(sorted({p.t_c for p in self.points}))

    # The summaries below are computed once per map (a frozen map never changes) and handed out as copies:
    # the planners and the turn-level surrogate ask for them at every decision.
    @functools.cached_property
    def _theta_curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self._compute_theta_curve()

    @functools.cached_property
    def _psi_curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self._compute_psi_curve()

    @functools.cached_property
    def _rising_branch(self) -> dict[float, tuple[np.ndarray, np.ndarray]]:
        return {}

    @functools.cached_property
    def _offset_curve(self) -> tuple[np.ndarray, np.ndarray]:
        tcs = self.t_c_values()
        return tcs, np.array([np.mean([p.offset_m for p in self.points if p.t_c == tc], axis=0) for tc in tcs])

    @functools.cached_property
    def _psi_unwrapped(self) -> tuple[np.ndarray, np.ndarray]:
        tcs, psi, _ = self._psi_curve
        return tcs, np.degrees(np.unwrap(np.radians(psi)))

    def theta_curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t_c, mean theta, theta spread max - min over phases), degrees."""
        return tuple(a.copy() for a in self._theta_curve)  # type: ignore[return-value]

    def _compute_theta_curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tcs = self.t_c_values()
        mean, spread = [], []
        for tc in tcs:
            th = [p.theta_deg for p in self.points if p.t_c == tc]
            mean.append(float(np.mean(th)))
            spread.append(float(np.max(th) - np.min(th)))
        return tcs, np.array(mean), np.array(spread)

    def psi_curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t_c, circular mean of psi, circular spread (deg) over phases)."""
        return tuple(a.copy() for a in self._psi_curve)  # type: ignore[return-value]

    def _compute_psi_curve(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tcs = self.t_c_values()
        mean, spread = [], []
        for tc in tcs:
            ang = np.radians([p.psi_deg for p in self.points if p.t_c == tc])
            m = math.atan2(float(np.mean(np.sin(ang))), float(np.mean(np.cos(ang))))
            mean.append(math.degrees(m))
            spread.append(float(np.max(np.abs(np.degrees([wrap_angle(a - m) for a in ang])))))
        return tcs, np.array(mean), np.array(spread)

    @functools.cached_property
    def period_s(self) -> float:
        """Median wobble period at omega_l, s."""
        return float(np.median([p.period_s for p in self.points]))

    @functools.cached_property
    def relax_s(self) -> float:
        """Median relaxation time after a burst, s."""
        return float(np.median([p.relax_s for p in self.points]))

    def rising_branch(self, drop_deg: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
        """(t_c, theta) from t_c = 0 (theta = 0) up to the first maximum of the mean theta,
        made non-decreasing (wiggles smaller than ``drop_deg`` at tiny turns are noise).

        Beyond the first maximum (the first drop by more than ``drop_deg``) the buckled swimmer
        tumbles on: theta oscillates with t_c and the turn's direction flips, so longer bursts are
        not used and larger turns are made in several bursts.
        """
        t, y = self._branch(drop_deg)
        return t.copy(), y.copy()

    def theta_for(self, t_c: float, drop_deg: float = 5.0) -> float:
        """The turn (deg) of a burst of ``t_c`` s on the rising branch (``rising_branch``), held at its maximum
        beyond it."""
        t, y = self._branch(drop_deg)
        return branch_theta_deg(float(t_c), t, y)

    def _branch(self, drop_deg: float) -> tuple[np.ndarray, np.ndarray]:
        """``rising_branch``'s arrays, computed once (not to be changed)."""
        key = float(drop_deg)
        if key not in self._rising_branch:
            self._rising_branch[key] = self._compute_rising_branch(key)
        return self._rising_branch[key]

    def _compute_rising_branch(self, drop_deg: float) -> tuple[np.ndarray, np.ndarray]:
        tcs, th, _ = self._theta_curve
        k = 0
        while k + 1 < len(th) and th[k + 1] > np.max(th[:k + 1]) - drop_deg:
            k += 1
        y = np.maximum.accumulate(np.concatenate([[0.0], th[:k + 1]]))
        return np.concatenate([[0.0], tcs[:k + 1]]), y

    @property
    def max_theta_deg(self) -> float:
        """The largest turn one burst makes on the rising branch (mean over phases), degrees."""
        return float(self.rising_branch()[1][-1])

    def t_c_for(self, theta_deg: float) -> float:
        """Burst length (s) for a turn of ``theta_deg`` (clipped to [0, max_theta_deg])."""
        t, y = self.rising_branch()
        theta = min(max(float(theta_deg), 0.0), float(y[-1]))
        # first crossing of the (non-decreasing) curve; flat stretches give their start
        k = int(np.searchsorted(y, theta, side="left"))
        if k == 0:
            return 0.0
        y0, y1 = y[k - 1], y[k]
        frac = 1.0 if y1 == y0 else (theta - y0) / (y1 - y0)
        return float(t[k - 1] + frac * (t[k] - t[k - 1]))

    def psi_for(self, t_c: float) -> float:
        """psi (deg) of a burst of ``t_c`` s, interpolated in t_c (angles unwrapped)."""
        tcs, un = self._psi_unwrapped
        return psi_deg_at(float(t_c), tcs, un)

    def turn_curves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t_c s, theta deg) of the rising branch (``rising_branch``) and (t_c s, psi deg unwrapped) of ``psi_for``:
        the curves ``theta_for`` (``branch_theta_deg``) and ``psi_for`` (``psi_deg_at``) read, copies."""
        t, y = self._branch(5.0)
        tcs, un = self._psi_unwrapped
        return t.copy(), y.copy(), tcs.copy(), un.copy()

    def offset_for(self, t_c: float) -> np.ndarray:
        """Mean head displacement over a turn of ``t_c`` s (burst + relaxation), (3,) m, along
        (d0, phase-node direction at the burst, d0 x that); interpolated in t_c."""
        tcs, mean = self._offset_curve
        return np.array([np.interp(t_c, tcs, mean[:, k]) for k in range(3)])

    # --- compatibility --------------------------------------------------------------------
    def check_compatible(self, params: SwimmerParams, omega_l_rpm: float | None = None,
                         omega_h_rpm: float | None = None) -> None:
        """TurnMapMismatch naming every physical parameter or speed that differs from the map's."""
        diffs = [f"{f.name}: map {getattr(self.params, f.name)!r}, here {getattr(params, f.name)!r}"
                 for f in dataclasses.fields(SwimmerParams)
                 if getattr(self.params, f.name) != getattr(params, f.name)]
        if omega_l_rpm is not None and omega_l_rpm != self.omega_l_rpm:
            diffs.append(f"omega_l_rpm: map {self.omega_l_rpm!r}, here {omega_l_rpm!r}")
        if omega_h_rpm is not None and omega_h_rpm != self.omega_h_rpm:
            diffs.append(f"omega_h_rpm: map {self.omega_h_rpm!r}, here {omega_h_rpm!r}")
        if diffs:
            raise TurnMapMismatch("this turn map was calibrated for other parameters (" + "; ".join(diffs)
                                  + "); calibrate one for these with 'flagellum calibrate-turns'")

    # --- file -----------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {"format": TURN_MAP_FORMAT, "version": TURN_MAP_VERSION, "preset": self.preset,
                "omega_l_rpm": self.omega_l_rpm, "omega_h_rpm": self.omega_h_rpm, "phase_node": self.phase_node,
                "params": dataclasses.asdict(self.params), "numerics": dataclasses.asdict(self.numerics),
                "meta": self.meta, "points": [dataclasses.asdict(p) for p in self.points]}

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the JSON file atomically; returns its path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=1) + "\n", encoding="utf-8")
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> TurnMap:
        """Read a file written by ``save``; ValueError naming the file if it is not one."""
        path = Path(path)
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"cannot read the turn map {str(path)!r}: {exc}") from None
        if not isinstance(doc, dict) or doc.get("format") != TURN_MAP_FORMAT:
            raise ValueError(f"{str(path)!r} is not a turn map (no \"format\": \"{TURN_MAP_FORMAT}\")")
        if doc.get("version") != TURN_MAP_VERSION:
            raise ValueError(f"turn map {str(path)!r} has version {doc.get('version')!r}; this code reads version "
                             f"{TURN_MAP_VERSION}: calibrate again with 'flagellum calibrate-turns'")
        removed = [k for k in doc.get("numerics") or () if k in REMOVED_PARAMETERS]
        if removed:
            raise ValueError(f"turn map {str(path)!r} names a removed parameter: {removed_message(removed[0])} (or "
                             "calibrate again with 'flagellum calibrate-turns')")
        try:
            points = tuple(TurnResult(**{**p, "offset_m": tuple(p["offset_m"])}) for p in doc["points"])
            return cls(params=SwimmerParams(**doc["params"]), numerics=NumericsConfig(**doc["numerics"]),
                       preset=doc["preset"], omega_l_rpm=float(doc["omega_l_rpm"]),
                       omega_h_rpm=float(doc["omega_h_rpm"]), phase_node=int(doc["phase_node"]),
                       points=points, meta=dict(doc.get("meta", {})))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"turn map {str(path)!r} is damaged: {exc}") from None
