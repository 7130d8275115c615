"""Where an episode's cross-track error is made: before the turns, while turning, after them.

A controller that steers by buckling reaches a waypoint when the head is within the reach radius of it, so the
next segment starts off its line; the turn itself moves the head sideways (the flagellum's excursion while
buckled and relaxing); then the swimmer cruises towards the next waypoint, and its heading error decides how the
error falls. ``cross_track_split`` splits the time integral of the cross-track error of one episode (its
``EpisodeTrace``) into those parts, and estimates what the episode would have cost had the first turn of every
segment come out exactly (``ideal_first_turn``): the same error until that turn has relaxed, then a straight line
from where the head is to the waypoint (the cross-track falls linearly to zero), with no corrective turns. A
correction of each planned turn (burst length and phase, ``agents.residual_planner``) acts on the last part only,
so the estimate bounds what such a correction can gain.

Intervals (the trace's control steps, t_i to t_i+1, trapezoidal) are "turning" while the motor runs above the
cruise speed or the flagellum is still buckled (L'/L below ``straight_ratio``), "before" in a segment's cruise
before its first turn, "between" after a turn that another follows in the same segment, and "after" after its
last turn.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: L'/L at or above which the flagellum counts as relaxed (straight: ~1.005; buckled: well below 0.9)
STRAIGHT_RATIO = 0.98
PARTS = ("before", "turning", "between", "after")


def cross_track_split(t: np.ndarray, cross_track_m: np.ndarray, omega_rpm: np.ndarray, end_to_end_ratio: np.ndarray,
                      waypoint_index: np.ndarray, cruise_rpm: float = 10.0,
                      straight_ratio: float = STRAIGHT_RATIO) -> dict[str, Any]:
    """The parts of ∫ cross-track dt (m s) of one episode (arrays (S,) per trace step: time s, cross-track m,
    motor speed rpm, L'/L, waypoint index), their sum ``total_m_s``, the duration ``duration_s`` and
    ``ideal_first_turn_m_s`` (module docstring). ValueError for arrays of different lengths or fewer than 2
    steps."""
    arrays = [np.asarray(a, dtype=np.float64) for a in (t, cross_track_m, omega_rpm, end_to_end_ratio, waypoint_index)]
    n = len(arrays[0])
    if n < 2 or any(len(a) != n for a in arrays):
        raise ValueError(f"trace arrays of lengths {[len(a) for a in arrays]}: need equal lengths of at least 2")
    t, x, om, ee, wi = arrays
    area = 0.5 * (x[:-1] + x[1:]) * np.diff(t)
    turning = (om[:-1] > cruise_rpm + 0.5) | (ee[:-1] < straight_ratio)
    parts = dict.fromkeys(PARTS, 0.0)
    ideal = 0.0
    seg = wi[:-1]
    for k in np.unique(seg):
        idx = np.flatnonzero(seg == k)
        turn_idx = idx[turning[idx]]
        if turn_idx.size == 0:
            parts["before"] += float(area[idx].sum())
            ideal += float(area[idx].sum())
            continue
        first, last = turn_idx[0], turn_idx[-1]
        parts["before"] += float(area[idx[idx < first]].sum())
        parts["turning"] += float(area[turn_idx].sum())
        cruise_after = idx[(idx > first) & ~turning[idx]]
        parts["between"] += float(area[cruise_after[cruise_after < last]].sum())
        parts["after"] += float(area[cruise_after[cruise_after > last]].sum())
        # the first turn done exactly: its own error until it has relaxed, then straight at the waypoint
        run = turn_idx[: np.argmax(np.diff(np.append(turn_idx, turn_idx[-1] + 2)) > 1) + 1]
        end = run[-1] + 1  # the trace step at which the first turn has relaxed
        ideal += float(area[idx[idx < first]].sum() + area[run].sum())
        rest = t[idx[-1] + 1] - t[end]
        ideal += 0.5 * x[end] * rest
    total = float(area.sum())
    return {**parts, "total_m_s": total, "duration_s": float(t[-1] - t[0]), "ideal_first_turn_m_s": ideal}


def budget_of_episodes(splits: list[dict[str, Any]]) -> dict[str, float]:
    """Episode-mean cross-track (m) and each part's share of it, over the ``cross_track_split`` of several
    episodes (each episode's mean = its integral / its duration; the means averaged, as ``summarise`` does):
    ``mean_m``, ``<part>_m`` (the part's contribution to the mean) and ``ideal_first_turn_m``."""
    if not splits:
        raise ValueError("no episodes")
    out = {"mean_m": float(np.mean([s["total_m_s"] / s["duration_s"] for s in splits]))}
    for p in PARTS:
        out[f"{p}_m"] = float(np.mean([s[p] / s["duration_s"] for s in splits]))
    out["ideal_first_turn_m"] = float(np.mean([s["ideal_first_turn_m_s"] / s["duration_s"] for s in splits]))
    return out


def folder_budgets(folder: str | Path, controllers: Sequence[str] | None = None) -> dict[str, dict[str, float]]:
    """``budget_of_episodes`` (plus ``episodes``) per controller of a ``flagellum evaluate`` folder, from the traces
    under its points/ (controllers without traces are left out)."""
    from agents.evaluation_report import controllers_of, load_results
    from agents.path_following import EpisodeTrace

    folder = Path(folder)
    res = load_results(folder)
    out: dict[str, dict[str, float]] = {}
    for c in controllers or controllers_of(res):
        splits = []
        for row in res["per_path"]:
            if row["controller"] != c or not row.get("trace") or not (folder / row["trace"]).is_file():
                continue
            tr = EpisodeTrace.load(folder / row["trace"])
            splits.append(cross_track_split(tr.t, tr.cross_track_m, tr.omega_rpm, tr.end_to_end_ratio,
                                            tr.waypoint_index))
        if splits:
            out[c] = {**budget_of_episodes(splits), "episodes": len(splits)}
    return out


def budget_table(budgets: dict[str, dict[str, dict[str, float]]]) -> list[str]:
    """Markdown lines: one row per (folder, controller) of ``{folder: folder_budgets(folder)}``, cm."""
    lines = ["| folder | controller | episodes | mean cross-track (cm) | " + " | ".join(PARTS) +
             " | first turns exact (cm) | ratio |", "|---" * (6 + len(PARTS)) + "|"]
    for folder, by in budgets.items():
        for c, b in by.items():
            lines.append(f"| {folder} | `{c}` | {b['episodes']} | {100 * b['mean_m']:.2f} | " +
                         " | ".join(f"{100 * b[f'{p}_m']:.2f}" for p in PARTS) +
                         f" | {100 * b['ideal_first_turn_m']:.2f} | {b['ideal_first_turn_m'] / b['mean_m']:.2f} |")
    return lines
