"""Table, JSON and Pareto plot of the fidelity ladder (``flagellum_bench.fidelity``)."""

from __future__ import annotations

import json
import math
import platform
from pathlib import Path
from typing import Any

METRIC_LABELS = {
    "swim_per_turn_10rpm": "swim/turn 10 rpm",
    "lratio_100s": "L'/L 100 s",
    "theta_tc10": "θ t_c=10", "theta_tc20": "θ t_c=20", "theta_tc40": "θ t_c=40",
    "phi_tc10": "φ t_c=10", "phi_tc20": "φ t_c=20", "phi_tc40": "φ t_c=40",
    "omega_b": "ω_b",
}


def _fmt(v: Any) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def markdown(rows: list[dict[str, Any]], header: str) -> str:
    metrics = [m for m in METRIC_LABELS if any(m in r["values"] for r in rows)]
    lines = [header, "", "Values (SI; angles in degrees, ω_b in rpm):", "",
             "| config | RTF (10 rpm) | RTF (90 rpm) | " + " | ".join(METRIC_LABELS[m] for m in metrics) + " |",
             "|---" * (3 + len(metrics)) + "|"]
    for r in rows:
        lines.append(f"| {r['config']} | {_fmt(r['real_time_factor'])} | {_fmt(r['real_time_factor_buckled'])} | "
                     + " | ".join(_fmt(r["values"].get(m)) for m in metrics) + " |")
    lines += ["", "Relative errors against `paper`:", "",
              "| config | " + " | ".join(METRIC_LABELS[m] for m in metrics) + " |", "|---" * (1 + len(metrics)) + "|"]
    for r in rows:
        lines.append(f"| {r['config']} | " + " | ".join(
            (f"{100 * r['errors'][m]:.1f} %" if m in r["errors"] else "—") for m in metrics) + " |")
    fails = [(r["config"], f) for r in rows for f in r["failures"]]
    if fails:
        lines += ["", "Failures:", ""] + [f"- {c}: {f}" for c, f in fails]
    return "\n".join(lines) + "\n"


TURN_KEYS = tuple(f"{a}_tc{t}" for t in (10, 20, 40) for a in ("theta", "phi"))


def _turn_error(row: dict[str, Any]) -> float | None:
    """Largest relative error of the turning and out-of-plane angles (None if none measured)."""
    errs = [row["errors"][k] for k in TURN_KEYS if k in row["errors"]]
    return max(errs) if errs else None


#: Preset names given to other configurations on 2026-12-02: a row measured before that date under the old name is
#: labelled with today's name for that configuration (or as retired). name -> (date of the change, label). The
#: configuration named 'fast' before that date was then named 'coarse', itself retired since (docs/bench_quick.md).
RENAMED = {"fast": ("2026-12-02", "retired 'coarse' (N = 45, h = 10 ms; named 'fast' then)"),
           "balanced": ("2026-12-02", "retired 'balanced' (paper grid, h = 20 ms)")}
TODAYS_PRESETS = ("reference", "paper", "faithful", "fast")  # coarse retired (docs/bench_quick.md)


def display_name(row: dict[str, Any]) -> tuple[str, bool]:
    """(label, is one of today's presets) of a ladder row, by the names in force when it was measured."""
    measured = sorted(row.get("measured") or [])
    name = row["config"]
    if name in RENAMED and measured and measured[-1][:10] < RENAMED[name][0]:
        label = RENAMED[name][1]
        return label, label.split(" ")[0] in TODAYS_PRESETS
    return name, bool(row.get("preset")) and name in TODAYS_PRESETS


def pareto_plot(rows: list[dict[str, Any]], path: Path) -> None:
    """Error against real-time factor: swim speed (left) and the worst turning angle (right). Points are numbered;
    the legend below names them (today's presets as red circles, other configurations as blue squares) and the
    title gives the dates the rows were measured."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(1, 2, figsize=(12, 6.4))
    panels = ((axes[0], lambda r: r["errors"].get("swim_per_turn_10rpm"), "relative error of the swim speed (10 rpm)"),
              (axes[1], _turn_error, "largest relative error of θ, φ (t_c = 10, 20, 40 s)"))
    shown = [r for r in rows if r["real_time_factor"] is not None]
    names = [display_name(r) for r in shown]
    for ax, err_of, ylabel in panels:
        drawn = 0
        for k, (r, (label, preset)) in enumerate(zip(shown, names), 1):
            err = err_of(r)
            if err is None:
                continue
            rtf, err = r["real_time_factor"], max(err, 1e-4)
            ax.scatter(rtf, err, marker="o" if preset else "s", s=150 if preset else 110,
                       color="C3" if preset else "C0", zorder=3)
            ax.annotate(str(k), (rtf, err), ha="center", va="center", fontsize=7, color="white", weight="bold",
                        zorder=4)
            drawn += 1
        if not drawn:
            ax.text(0.5, 0.5, "not measured", ha="center", va="center", transform=ax.transAxes)
        ax.axhline(0.10, color="grey", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("real-time factor at 10 rpm (simulated s per wall s, one core)")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
    handles = [Line2D([], [], ls="", marker="o" if preset else "s", color="C3" if preset else "C0", ms=7,
                      label=f"{k}  {label}") for k, (label, preset) in enumerate(names, 1)]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, frameon=False, handletextpad=0.3)
    dates = sorted({d[:10] for r in shown for d in r.get("measured", [])})
    when = "-" if not dates else dates[0] if len(dates) == 1 else f"{dates[0]} to {dates[-1]}"
    fig.suptitle(f"Fidelity ladder measured {when}: error against paper vs speed (red circles: today's presets; "
                 "dashed: 10 %; errors below 1e-4 drawn at 1e-4)", fontsize=10)
    fig.tight_layout(rect=(0, 0.05 + 0.028 * math.ceil(len(handles) / 3), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_report(rows: list[dict[str, Any]], json_path: Path, md_path: Path | None, png_path: Path | None,
                 command: str, wall_s: float, missing: list[str] = (), notes: str = "") -> None:
    """JSON (a list of rows), markdown table and Pareto plot. ``missing``: tasks not measured yet.

    The markdown names the command and the machine, not dates (the rows' measurement dates are in the JSON and
    the results file); ``wall_s`` is kept for the callers and not written."""
    machine = f"{platform.platform()}, {platform.processor() or 'cpu'}, one core per task"
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(list(rows), indent=2) + "\n")
    if md_path is not None:
        header = "# Fidelity ladder"
        if notes:
            header += "\n\n" + notes
        header += f"\n\nProduced by `{command}` ({machine})."
        if missing:
            by_metric: dict[str, list[str]] = {}
            for task in missing:
                config, metric = task.rsplit(": ", 1)
                by_metric.setdefault(metric, []).append(config)
            header += ("\n\n**Not measured yet** (— in the tables; the command resumes them): "
                       + "; ".join(f"{m} for {', '.join(f'`{c}`' for c in cs)}" for m, cs in by_metric.items()) + ".")
        md_path.write_text(markdown(rows, header))
    if png_path is not None:
        pareto_plot(rows, png_path)
