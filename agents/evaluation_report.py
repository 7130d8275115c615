"""Paired per-path tables (markdown) and head-path figures for ``flagellum evaluate`` results folders.

A folder written by ``flagellum evaluate`` holds ``results.json`` (``agents.evaluation``) and the
per-episode traces under ``points/`` (named in each row's ``trace``). ``folder_report`` turns one
into: the aggregate table (controllers side by side), the paired per-path table (one row per path,
one cell per controller: reached, mean / max cross-track, Δz/ΔL on planar paths, buckling events,
time, error) and a figure of every controller's head path on every path (x-y and x-z, start frame).
``scripts/report_evaluation.py`` is its command line.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

AGGREGATE_ROWS = (("episodes", "episodes", 1, 0), ("success rate (%)", "success_rate", 100, 0),
                  ("waypoints reached (mean)", "waypoints_reached", 1, 2),
                  ("mean cross-track (cm)", "mean_cross_track_m", 100, 2),
                  ("max cross-track (cm)", "max_cross_track_m", 100, 2),
                  ("max Δz/ΔL, mean over planar paths (%)", "max_out_of_plane_ratio", 100, 2), ("time (s)", "time_s", 1, 0),
                  ("energy (mJ)", "energy_J", 1e3, 2), ("buckling events", "buckling_events", 1, 1),
                  ("wall time per path (s)", "wall_time_s", 1, 0), ("episodes ending in an error", "failed_runs", 1, 0))


def _fmt(v: Any, scale: float = 1.0, digits: int = 2) -> str:
    return "-" if v is None else f"{float(v) * scale:.{digits}f}"


def load_results(folder: str | Path) -> dict[str, Any]:
    """``results.json`` of an evaluate folder; ValueError naming the folder if it has none."""
    f = Path(folder) / "results.json"
    if not f.is_file():
        raise ValueError(f"{str(folder)!r} holds no results.json (run 'flagellum evaluate --out {folder}' first)")
    return json.loads(f.read_text(encoding="utf-8"))


def controllers_of(results: dict[str, Any]) -> list[str]:
    return list(results.get("aggregate", {}))


def aggregate_table(results: dict[str, Any], controllers: Sequence[str] | None = None) -> list[str]:
    """Markdown lines: one row per metric, one column per controller."""
    ctrl = list(controllers or controllers_of(results))
    agg = results["aggregate"]
    out = ["| metric | " + " | ".join(f"`{c}`" for c in ctrl) + " |", "|---" * (len(ctrl) + 1) + "|"]
    for label, key, scale, digits in AGGREGATE_ROWS:
        out.append(f"| {label} | " + " | ".join(_fmt(agg[c].get(key), scale, digits) for c in ctrl) + " |")
    return out


def best_planner(results: dict[str, Any], planners: Sequence[str] = ("rule", "adaptive")) -> str:
    """The planner of ``planners`` with the higher success rate in ``results``; on a tie the lower mean
    cross-track error (a missing one counts as infinite). ValueError if none of them ran."""
    agg = results.get("aggregate", {})
    ran = [p for p in planners if p in agg]
    if not ran:
        raise ValueError(f"none of the planners {list(planners)} ran here; controllers: {list(agg)}")

    def key(p: str) -> tuple[float, float]:
        x = agg[p].get("mean_cross_track_m")
        return -agg[p]["success_rate"], float("inf") if x is None else x

    return min(ran, key=key)


def _cell(r: dict[str, Any] | None) -> str:
    if r is None:
        return "-"
    n = r.get("n_waypoints")
    reached = f"{r.get('waypoints_reached')}/{n}" if n else f"{r.get('waypoints_reached')}"
    text = (f"{'yes' if r.get('success') else 'no'} ({reached}), {_fmt(r.get('mean_cross_track_m'), 100)} / "
            f"{_fmt(r.get('max_cross_track_m'), 100, 1)} cm")
    if r.get("max_out_of_plane_ratio") is not None:
        text += f", Δz/ΔL {_fmt(r['max_out_of_plane_ratio'], 100, 1)} %"
    text += f", {r.get('buckling_events')} b, {_fmt(r.get('time_s'), 1, 0)} s"
    if r.get("error"):
        text += f", error: {r['error']}"
    return text


def paired_table(results: dict[str, Any], controllers: Sequence[str] | None = None) -> list[str]:
    """Markdown lines: one row per path, each controller's episode on it side by side (with its env seed)."""
    ctrl = list(controllers or controllers_of(results))
    by = {(r["path"], r["controller"]): r for r in results["per_path"]}
    names = sorted({r["path"] for r in results["per_path"]})
    seeds = results.get("seeds", {})
    out = ["| path (env seed) | " + " | ".join(f"`{c}`: reached, mean / max cross-track, buckles, time" for c in ctrl)
           + " |", "|---" * (len(ctrl) + 1) + "|"]
    for n in names:
        seed = f" ({seeds[n]})" if n in seeds else ""
        out.append(f"| {n}{seed} | " + " | ".join(_cell(by.get((n, c))) for c in ctrl) + " |")
    return out


def head_path_figure(folder: str | Path, results: dict[str, Any], out_png: str | Path,
                     controllers: Sequence[str] | None = None, title: str | None = None) -> Path | None:
    """Every controller's head path on every path of one folder (x-y above, x-z below, cm); None if no traces."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.follow_plots import save
    from agents.path_following import EpisodeTrace

    folder = Path(folder)
    ctrl = list(controllers or controllers_of(results))
    rows = [r for r in results["per_path"] if r.get("trace") and (folder / r["trace"]).is_file()]
    names = sorted({r["path"] for r in rows})
    if not names:
        return None
    fig, axes = plt.subplots(2, len(names), figsize=(3.3 * len(names), 6.6), squeeze=False)
    for k, name in enumerate(names):
        way = None
        for c in ctrl:
            r = next((r for r in rows if r["path"] == name and r["controller"] == c), None)
            if r is None:
                continue
            tr = EpisodeTrace.load(folder / r["trace"])
            way = np.vstack([np.zeros(3), tr.waypoints]) * 100
            for ax, j in zip(axes[:, k], (1, 2)):
                ax.plot(tr.head[:, 0] * 100, tr.head[:, j] * 100, lw=1,
                        label=f"{c} ({'reached' if r['success'] else 'failed'})")
        if way is not None:
            for ax, j in zip(axes[:, k], (1, 2)):
                ax.plot(way[:, 0], way[:, j], "ko--", ms=3, lw=0.8)
                ax.set_aspect("equal", adjustable="datalim")
        axes[0, k].set_title(name, fontsize=9)
        axes[0, k].legend(fontsize=6)
        axes[0, k].set_ylabel("y (cm)")
        axes[1, k].set_ylabel("z (cm)")
        axes[1, k].set_xlabel("x (cm)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = save(fig, Path(out_png))
    plt.close(fig)  # pyplot keeps every figure it made until closed (a report makes dozens)
    return out


def folder_report(folder: str | Path, fig_dir: str | Path | None = None, name: str | None = None,
                  controllers: Sequence[str] | None = None, link_from: str | Path | None = None) -> list[str]:
    """Markdown lines for one evaluate folder: settings, aggregate and paired tables, the head-path figure
    (written to ``fig_dir``/<name>.png, linked relative to ``link_from`` if given)."""
    folder = Path(folder)
    res = load_results(folder)
    name = name or folder.name
    rand = res.get("env_overrides", {}).get("randomize")
    setting = "nominal swimmer" if not rand else (
        f"E, μ, b within ±{rand['youngs_modulus'] * 100:g} %, helix ±{rand['geometry'] * 100:g} %")
    seeds = sorted(set(res.get("seeds", {}).values()))
    lines = [f"### {name}: {setting} ({res.get('preset')} preset)", "",
             f"Folder `{folder}`" + ((f"; env seeds {seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else
                                     f"; env seed {seeds[0]} for every path") if seeds else "") + ".", ""]
    lines += aggregate_table(res, controllers) + [""] + paired_table(res, controllers) + [""]
    if res.get("missing"):
        lines += [f"Not finished: {', '.join(res['missing'])}.", ""]
    if fig_dir is not None:
        png = head_path_figure(folder, res, Path(fig_dir) / f"{name}.png", controllers, f"{name}: {setting}")
        if png is not None:
            import os

            rel = os.path.relpath(png, link_from) if link_from is not None else str(png)
            lines += [f"![head paths, {name}]({rel})", ""]
    return lines
