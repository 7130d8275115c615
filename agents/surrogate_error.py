"""How well the turn-level surrogate's interpolation of the turn map predicts a turn it was not given.

Leave one out (``leave_one_out_theta``): drop every measurement at one burst length t_c_k from the map, rebuild the
surrogate's table (``agents.surrogate_swimmer.TurnMapTable``) from the rest and predict theta at (t_c_k, each
measured phase) with the swimmer's bilinear read; the error is predicted - measured theta, degrees. Dropping the
shortest or the longest burst length makes the read an extrapolation (theta falls linearly to 0 below the shortest;
the longest is held beyond it), reported as such. The map's own sampling (0.125 s steps on the steep end of the
rising branch, 1-2 s in the tumbling regime beyond) is what sets the error: a dropped sample leaves a gap twice as
wide, so the leave-one-out error bounds the error between samples from above.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from agents.surrogate_calibration import SurrogateCalibration
from agents.surrogate_swimmer import SurrogateSwimmer, TurnMapTable
from agents.turn_map import TurnMap


def leave_one_out_theta(turn_map: TurnMap, calibration: SurrogateCalibration) -> list[dict]:
    """One row per burst length of the map: ``t_c`` (s), ``extrapolated`` (the first or last), ``on_rising_branch``
    (t_c below the branch's peak), ``peak`` (the peak itself: dropped, it is read across the peak), ``errors_deg``
    (predicted - measured theta per measured phase) and ``mean_abs_deg``,
    ``max_abs_deg``."""
    tcs = turn_map.t_c_values()
    peak = turn_map.rising_branch()[0][-1]
    d = np.array([1.0, 0.0, 0.0])
    rows = []
    for k, tc in enumerate(tcs):
        rest = dataclasses.replace(turn_map, points=tuple(p for p in turn_map.points if p.t_c != tc))
        swimmer = SurrogateSwimmer(rest, calibration, TurnMapTable(rest))
        errors = [math.degrees(swimmer.turn(d, float(tc), math.radians(p.phase_deg)).theta_rad) - p.theta_deg
                  for p in sorted(turn_map.points, key=lambda p: p.phase_deg) if p.t_c == tc]
        err = np.abs(errors)
        rows.append({"t_c": float(tc), "extrapolated": k in (0, len(tcs) - 1), "on_rising_branch": bool(tc < peak),
                     "peak": bool(tc == peak),
                     "errors_deg": [float(e) for e in errors], "mean_abs_deg": float(err.mean()),
                     "max_abs_deg": float(err.max())})
    return rows


def summarise_leave_one_out(rows: list[dict]) -> dict:
    """RMS and largest |error| (deg) over the interpolated rows: all of them, those on the rising branch below its
    peak, the peak, and those beyond it (the tumbling regime)."""
    def stats(sel: list[dict]) -> dict:
        e = np.array([x for r in sel for x in r["errors_deg"]])
        return {"n": int(e.size), "rms_deg": float(np.sqrt(np.mean(e ** 2))) if e.size else math.nan,
                "max_abs_deg": float(np.max(np.abs(e))) if e.size else math.nan}
    inner = [r for r in rows if not r["extrapolated"]]
    return {"interpolated": stats(inner), "rising_branch": stats([r for r in inner if r["on_rising_branch"]]),
            "peak": stats([r for r in inner if r["peak"]]),
            "beyond_peak": stats([r for r in inner if not r["on_rising_branch"] and not r["peak"]])}
