"""The report of ``flagellum bench --quick`` (``fidelity.quick_rows``): every tier's speed and its errors against
``reference`` as markdown tables, and the Pareto figure (error against CPU cost, one point per tier)."""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

from flagellum_bench.fidelity import BURST_RPM, BURST_TC, EPISODE_PATH, SURROGATE_CONFIG, TURN_TCS
from flagellum_bench.surrogate_tier import SPEED_DECISIONS

#: the error columns, in order: the physics presets' against ``reference``, then the surrogate's between its samples
QUICK_ERROR_KEYS = ("swim_per_turn", *(f"theta_tc{t:g}" for t in (*TURN_TCS, BURST_TC)),
                    *(f"phi_tc{t:g}" for t in (*TURN_TCS, BURST_TC)), "lratio_end_of_burst", "theta_between_samples")
#: where a zero error (``reference`` against itself) is drawn on the log axis
ERROR_FLOOR = 1e-5


def _fmt(v: Any) -> str:
    return "—" if v is None else f"{v:.3g}"


def _label(key: str) -> str:
    for name, sym in (("theta_tc", "θ "), ("phi_tc", "φ ")):
        if key.startswith(name):
            return f"{sym}{key[len(name):]} s"
    return {"swim_per_turn": "swim per turn", "lratio_end_of_burst": f"L'/L end of the {BURST_TC:g} s burst",
            "theta_between_samples": "θ between map samples"}[key]


def largest_error(row: dict[str, Any]) -> float | None:
    """The row's largest relative error over ``QUICK_ERROR_KEYS`` (None without any)."""
    errs = [row["errors"][k] for k in QUICK_ERROR_KEYS if k in row["errors"]]
    return max(errs) if errs else None


def quick_pareto_plot(rows: list[dict[str, Any]], path: Path) -> None:
    """The Pareto figure: each tier's largest relative error (``largest_error``) against its CPU cost per simulated
    second in the 150 rpm burst, cruising at 10 rpm, and in the rule planner's episode (the one cost every tier
    down to the surrogate has), log-log, one point per tier. ``reference`` (error 0 by definition) sits on the
    floor."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    panels = ((axes[0], "burst_real_time_factor_cpu", f"CPU s per simulated s, {BURST_RPM:g} rpm burst"),
              (axes[1], "real_time_factor_cpu", "CPU s per simulated s, steady 10 rpm"),
              (axes[2], "episode_real_time_factor_cpu", "CPU s per simulated s, rule planner's episode"))
    for ax, rtf_key, xlabel in panels:
        for k, r in enumerate(rows):
            err = largest_error(r)
            if not r.get(rtf_key) or err is None:
                continue
            cost, err = 1.0 / r[rtf_key], max(err, ERROR_FLOOR)
            ax.scatter(cost, err, s=80, color=f"C{k}", zorder=3)
            ax.annotate(r["config"], (cost, err), textcoords="offset points", xytext=(6, 6), fontsize=9)
        ax.axhline(ERROR_FLOOR, color="grey", lw=0.6, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("largest relative error")
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("flagellum bench --quick: error against cost, one point per tier (dotted: reference's 0; the "
                 "surrogate's error is between its map's samples)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def quick_markdown(rows: list[dict[str, Any]], wall_s: float, missing: list[str], figure: str | None = None) -> str:
    """The report: speed by phase, errors against ``reference``, values, and the surrogate's own figures, one row
    per tier; ``figure``: the file name of the Pareto figure (``quick_pareto_plot``) beside it."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    turns = ", ".join(f"{t:g}" for t in (*TURN_TCS, BURST_TC))
    lines = ["# flagellum bench --quick", "",
             f"{platform.node()}, {os.cpu_count()} cores, load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} "
             f"at the end; {wall_s:.0f} s in all. Real-time factor = simulated s per CPU s (`time.process_time`; "
             "wall-clock in brackets where measured), one task per core. Steady: 12 s at 10 rpm after 26 s of "
             f"start-up (the helix has settled). Turns: bursts of {turns} s at {BURST_RPM:g} rpm, each from the "
             "same 6 s of 10 rpm, then 10 rpm until the heading settles (θ, φ: the paper's turn angles); burst RTF "
             f"and L'/L from the {BURST_TC:g} s burst; relaxation: the 10 rpm after it. "
             f"Episode: the rule planner on agents/eval_paths/{EPISODE_PATH}; env (rule): the episode's simulated "
             "time in env steps of 2 s per CPU s; env (random): `FlagellumSteer-v0`, control_dt 2 s, 40 random "
             "actions (seed 0). Episode and env are not run for paper and reference. Surrogate: "
             "`FlagellumTurn-surrogate-v0` (no rod), the same episode with the planner's own turns, and "
             f"{SPEED_DECISIONS} decisions on random paths through `gym.make`. Errors: |x - x_ref| / max(|x_ref|, "
             "floor) against the `reference` preset, floor 10° for angles; the surrogate's: its turn map's "
             "leave-one-out θ error on the rising branch, the same relative form (its samples are `faithful`'s "
             "turns).", "",
             "## Speed", "",
             "| tier | steady RTF | burst RTF | relaxation RTF | episode CPU s | episode RTF | env steps/s (rule) "
             "| env steps/s (random) | decisions/s |", "|---" * 9 + "|"]

    def pair(a, b):
        return "—" if a is None else f"{_fmt(b)} ({a:.3g})"

    for r in rows:
        lines.append(f"| {r['config']} | {pair(r['real_time_factor'], r['real_time_factor_cpu'])} | "
                     f"{pair(r['burst_real_time_factor'], r['burst_real_time_factor_cpu'])} | "
                     f"{_fmt(r.get('relax_real_time_factor_cpu'))} | "
                     f"{pair(r['episode_wall_s'], r['episode_cpu_s'])} | {_fmt(r.get('episode_real_time_factor_cpu'))}"
                     f" | {_fmt(r.get('env_steps_per_s_rule'))} | {_fmt(r.get('env_steps_per_s_random'))} | "
                     f"{_fmt(r.get('decisions_per_cpu_s'))} |")
    lines += ["", "## Errors", "", "| tier | " + " | ".join(_label(k) for k in QUICK_ERROR_KEYS) + " |",
              "|---" * (1 + len(QUICK_ERROR_KEYS)) + "|"]
    for r in rows:
        lines.append(f"| {r['config']} | "
                     + " | ".join(f"{100 * r['errors'][k]:.2f} %" if k in r["errors"] else "—" for k in QUICK_ERROR_KEYS)
                     + " |")
    if figure:
        lines += ["", f"![Error against CPU cost, one point per tier]({figure})"]
    angle_keys = [f"{a}_tc{t:g}" for a in ("theta", "phi") for t in (*TURN_TCS, BURST_TC)]
    lines += ["", "## Values", "", "| tier | swim per turn (mm) | " + " | ".join(f"{_label(k)} (deg)" for k in angle_keys)
              + " | L'/L end of burst | episode |", "|---" * (4 + len(angle_keys)) + "|"]
    for r in rows:
        v = r["values"]
        ep = ("—" if "episode_success" not in v else
              f"{'reached' if v['episode_success'] else 'FAILED'}, {v['episode_time_s']:.0f} s simulated, "
              f"cross-track {100 * v['episode_mean_cross_track_m']:.2f} cm")
        swim = v.get("swim_per_turn_10rpm")
        lines.append(f"| {r['config']} | {'—' if swim is None else f'{1e3 * swim:.4f}'} | "
                     + " | ".join(_fmt(v.get(k)) for k in angle_keys) + f" | {_fmt(v.get('lratio_burst'))} | {ep} |")
    sur = next((r for r in rows if r["config"] == SURROGATE_CONFIG), None)
    if sur is not None and "map_loo_rising_rms_deg" in sur["values"]:
        v = sur["values"]
        lines += ["", f"The surrogate's map between its samples (leave one out, θ error in degrees): rising branch RMS "
                      f"{v['map_loo_rising_rms_deg']:.1f}, largest {v['map_loo_rising_max_deg']:.1f}; at the peak RMS "
                      f"{v['map_loo_peak_rms_deg']:.1f}; beyond it (tumbling) RMS {v['map_loo_beyond_rms_deg']:.1f}. "
                      "Held-out turns against `faithful` and the planners' episodes in both: docs/surrogate.md."]
    fails = [(r["config"], f) for r in rows for f in r["failures"]]
    if fails:
        lines += ["", "Failures:", ""] + [f"- {c}: {f}" for c, f in fails]
    if missing:
        lines += ["", "Not measured (interrupted?): " + ", ".join(missing)]
    return "\n".join(lines) + "\n"
