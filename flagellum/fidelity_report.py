"""Table, JSON and Pareto plot of the fidelity ladder (``flagellum.fidelity``)."""

from __future__ import annotations

import json
import platform
import time
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


def pareto_plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in rows:
        rtf = r["real_time_factor"]
        err = r["errors"].get("swim_per_turn_10rpm")
        if rtf is None or err is None:
            continue
        err = max(err, 1e-4)
        marker = "o" if r["preset"] else "s"
        ax.scatter(rtf, err, marker=marker, s=60 if r["preset"] else 30)
        ax.annotate(r["config"], (rtf, err), fontsize=7, xytext=(4, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("real-time factor at 10 rpm (simulated s per wall s, one core)")
    ax.set_ylabel("relative error of the swim speed vs paper")
    ax.set_title("Fidelity ladder (circles: presets; errors below 1e-4 drawn at 1e-4)")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_report(rows: list[dict[str, Any]], json_path: Path, md_path: Path | None, png_path: Path | None,
                 command: str, wall_s: float) -> None:
    meta = {"command": command, "date": time.strftime("%Y-%m-%d %H:%M"), "wall_time_s": wall_s,
            "machine": f"{platform.platform()}, {platform.processor() or 'cpu'}, one core per task"}
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps({"meta": meta, "rows": rows}, indent=2))
    if md_path is not None:
        header = (f"# Fidelity ladder\n\nProduced by `{command}` on {meta['date']} "
                  f"({meta['machine']}; {wall_s / 60:.0f} min wall).")
        md_path.write_text(markdown(rows, header))
    if png_path is not None:
        pareto_plot(rows, png_path)
