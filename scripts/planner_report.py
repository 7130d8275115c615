"""docs/planner.md and its figures from the shipped turn maps, the burst-speed study and the square run.

    python scripts/planner_report.py

Inputs (each made by the command given; missing ones are reported as not measured):
- agents/turn_maps/<preset>.json          flagellum calibrate-turns --preset <preset> --out agents/turn_maps/<preset>.json
- results/turn_maps/burst_<rpm>.json      flagellum calibrate-turns --omega-h <rpm> --t-c ... --out ...
                                          (the default swimmer at faithful, one burst speed each)
- results/eval/burst_<rpm>/<run>/level_<x>/results.json
                                          FLAGELLUM_TURN_MAPS=<folder holding burst_<rpm>.json as faithful.json>
                                          flagellum evaluate --paths results/eval/burst_paths --seed0 12000 [--randomize x]
- docs/square/faithful/summary.json       make demo, copied (flagellum follow --path square --controller rule
                                          --controller adaptive@line=2 --out docs/square/faithful)
The prose is scripts/templates/planner.md.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from agents.follow_plots import save, turn_map_figure
from agents.turn_map import PLANNER_OMEGA_H_RPM, TurnMap

DOCS = Path("docs")
TEMPLATE = Path(__file__).with_name("templates") / "planner.md"
PRESETS = ("faithful", "paper", "fast")  # coarse retired (docs/presets.md)
BURST_RPM = (60, 90, 150)
LEVELS = ("0", "0.1")


def _burst_map(rpm: int) -> TurnMap | None:
    f = Path("results/turn_maps") / f"burst_{rpm}.json"
    return TurnMap.load(f) if f.is_file() else None


def _slope_at(m: TurnMap, theta: float, dt: float = 0.25) -> float:
    """d theta / d t_c on the rising branch at ``theta`` (deg/s)."""
    t, y = m.rising_branch()
    tc = m.t_c_for(theta)
    return float((np.interp(tc + dt, t, y) - np.interp(tc - dt, t, y)) / (2 * dt))


def _offset_cm(m: TurnMap) -> float:
    """Head displacement over a turn of 60 deg (or the largest), cm."""
    return float(100 * np.linalg.norm(m.offset_for(m.t_c_for(min(60.0, m.max_theta_deg)))))


def burst_table() -> tuple[str, dict[int, TurnMap]]:
    maps = {rpm: m for rpm in BURST_RPM if (m := _burst_map(rpm)) is not None}
    if not maps:
        return "Not measured.", maps
    rows = ["| ω_h (rpm) | rising branch: longest t_c (s) → largest θ (°) | t_c for θ = 30 / 60 / 90° (s) | "
            "dθ/dt_c at 45° / 90° (°/s) | θ spread over 4 phases on the branch (°) | head drift over a 60° turn "
            "(cm) | relaxation (s) |", "|---|---|---|---|---|---|---|"]
    for rpm, m in maps.items():
        t, _ = m.rising_branch()
        tcs, _, spread = m.theta_curve()
        tc_for = " / ".join(f"{m.t_c_for(a):.1f}" if a <= m.max_theta_deg else "—" for a in (30, 60, 90))
        slopes = " / ".join(f"{_slope_at(m, a):.0f}" if a <= m.max_theta_deg else "—" for a in (45, 90))
        rows.append(f"| {rpm} | {t[-1]:g} → {m.max_theta_deg:.1f} | {tc_for} | {slopes} | "
                    f"{spread[tcs <= t[-1]].max():.1f} | {_offset_cm(m):.1f} | {m.relax_s:.0f} |")
    return "\n".join(rows), maps


def _dev_results(rpm: int) -> dict[tuple[str, str], dict]:
    """(level, controller) -> aggregate of the development evaluations at ``rpm``."""
    out: dict[tuple[str, str], dict] = {}
    for f in sorted((Path("results/eval") / f"burst_{rpm}").glob("*/level_*/results.json")):
        level = f.parent.name.removeprefix("level_")
        for ctrl, agg in json.loads(f.read_text())["aggregate"].items():
            out[(level, ctrl)] = agg
    return out


def dev_table() -> tuple[str, dict[int, dict], int, int]:
    res = {rpm: r for rpm in BURST_RPM if (r := _dev_results(rpm))}
    if not res:
        return "Not measured.", res, 0, 0
    ctrls = sorted({c for r in res.values() for _, c in r})
    rows = ["| controller | ω_h (rpm) | nominal: success | nominal: mean cross-track (cm) | ±10 %: success | "
            "±10 %: mean cross-track (cm) |", "|---|---|---|---|---|---|"]
    n_paths = 0
    for c in ctrls:
        for rpm, r in res.items():
            cells = []
            for lv in LEVELS:
                a = r.get((lv, c))
                if a is None:
                    cells += ["not run", "—"]
                    continue
                n_paths = max(n_paths, a["episodes"])
                cells += [f"{100 * a['success_rate']:.0f} % of {a['episodes']}",
                          f"{100 * a['mean_cross_track_m']:.2f}"]
            rows.append(f"| `{c}` | {rpm} | " + " | ".join(cells) + " |")
    return "\n".join(rows), res, n_paths, 12000


def choice_text(maps: dict[int, TurnMap], res: dict[int, dict]) -> str:
    kept = int(PLANNER_OMEGA_H_RPM)
    if kept not in maps:
        return "Its map was not measured here."
    m = maps[kept]
    parts = [f"One burst at {kept} rpm turns the swimmer by up to {m.max_theta_deg:.0f}°"]
    others = [f"{rpm} rpm {o.max_theta_deg:.0f}° in {o.rising_branch()[0][-1]:g} s"
              for rpm, o in maps.items() if rpm != kept]
    parts.append(f"in {m.rising_branch()[0][-1]:g} s ({', '.join(others)})")
    text = " ".join(parts) + "."
    if kept in res:
        nominal = {c: a for (lv, c), a in res[kept].items() if lv == "0"}
        best = {c: min((r[("0", c)]["mean_cross_track_m"] for r in res.values() if ("0", c) in r))
                for c in nominal}
        lowest = [c for c, a in nominal.items() if a["mean_cross_track_m"] <= best[c] + 1e-12]
        if lowest:
            text += (f" On the development paths it keeps the nominal swimmer nearest the path with "
                     f"{', '.join(f'`{c}`' for c in lowest)}.")
    randomised = {rpm: max((a["success_rate"], c) for (lv, c), a in r.items() if lv == "0.1")
                  for rpm, r in res.items() if any(lv == "0.1" for lv, _ in r)}
    if kept in randomised:
        best = ", ".join(f"{rpm} rpm {100 * s:.0f} % (`{c}`)" for rpm, (s, c) in sorted(randomised.items()))
        text += (f" It is kept for robustness: with the swimmer randomised by ±10 %, the best planner's success is "
                 f"{best}.")
    return text


def maps_section() -> tuple[str, str]:
    lines: list[str] = []
    spreads = []
    for preset in PRESETS:
        f = Path("agents/turn_maps") / f"{preset}.json"
        if not f.is_file():
            lines += [f"### `{preset}`", "", "Not calibrated.", ""]
            continue
        m = TurnMap.load(f)
        fig = save(turn_map_figure(m, f"turn map, {preset} preset, ω_l = {m.omega_l_rpm:g} rpm, "
                                      f"ω_h = {m.omega_h_rpm:g} rpm"), DOCS / "figures" / f"turn_map_{preset}.png")
        tc, th, spread = m.theta_curve()
        t_branch = m.rising_branch()[0][-1]
        phases = sorted({p.phase_deg for p in m.points})
        if len(phases) > 1:
            spreads.append(f"`{preset}` {spread[tc <= t_branch].max():.1f}°")
        _, psi, psi_spread = m.psi_curve()
        lines += [f"### `{preset}`: ω_l = {m.omega_l_rpm:g} rpm, ω_h = {m.omega_h_rpm:g} rpm", "",
                  f"{len(m.points)} turns ({len(tc)} burst lengths × phases {', '.join(f'{p:g}' for p in phases)}°), "
                  f"{m.meta.get('wall_time_s_all_turns', 0) / 60:.0f} min of worker time. Largest turn of one burst: "
                  f"**{m.max_theta_deg:.1f}°** (t_c = {t_branch:g} s); head drift over a 60° turn "
                  f"{_offset_cm(m):.1f} cm; wobble period {m.period_s:.2f} s; median relaxation {m.relax_s:.1f} s.",
                  "", f"![turn map {preset}](figures/{fig.name})", "",
                  "| t_c (s) | t̄_c | θ mean (°) | θ spread over phases (°) | ψ (°) | ψ spread (°) |",
                  "|---|---|---|---|---|---|"]
        for row in zip(tc, th, spread, psi, psi_spread, strict=True):
            lines.append(f"| {row[0]:g} | {row[0] / m.params.viscous_time:.3f} | {row[1]:.1f} | {row[2]:.1f} | "
                         f"{row[3]:.1f} | {row[4]:.1f} |")
        lines.append("")
    return "\n".join(lines), ", ".join(spreads) or "not measured"


def square_section() -> str:
    f = DOCS / "square" / "faithful" / "summary.json"
    if not f.is_file():
        return "Not run."
    s = json.loads(f.read_text())
    lines = ["`make demo` (the `faithful` preset), copied to docs/square/faithful:", "",
             "| controller | corners | Δz/ΔL (paper: < 5 %) | mean / max cross-track (cm) | simulated (s) | "
             "wall (s) | bursts |", "|---|---|---|---|---|---|---|"]
    for ctrl, m in s["controllers"].items():
        ratio = m["max_out_of_plane_ratio"]
        lines.append(f"| `{ctrl}` | {m['waypoints_reached']}/{m['n_waypoints']} | "
                     f"{'—' if ratio is None else f'{100 * ratio:.2f} %'} | {100 * m['mean_cross_track_m']:.2f} / "
                     f"{100 * m['max_cross_track_m']:.2f} | {m['time_s']:.0f} | {m['wall_time_s']:.0f} | "
                     f"{len(m.get('turns', []))} |")
    lines += ["", "![square, faithful](square/faithful/path.png)", "", "![omega, faithful](square/faithful/omega.png)"]
    return "\n".join(lines)


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()  # --help, and no stray arguments
    btable, maps = burst_table()
    dtable, res, n_dev, dev_seed = dev_table()
    maps_text, phase_spread = maps_section()
    omega_l = next(iter(maps.values())).omega_l_rpm if maps else 10.0
    text = TEMPLATE.read_text(encoding="utf-8").format(
        omega_l=omega_l, burst_table=btable, offset_60=_offset_cm(maps[60]) if 60 in maps else float("nan"),
        n_dev=n_dev, dev_seed=dev_seed, dev_table=dtable, omega_h=PLANNER_OMEGA_H_RPM,
        choice=choice_text(maps, res), maps=maps_text, phase_spread=phase_spread, square=square_section())
    text = re.sub(r"\n{3,}", "\n\n", text)
    (DOCS / "planner.md").write_text(text, encoding="utf-8")
    print(f"wrote {DOCS / 'planner.md'}")


if __name__ == "__main__":
    main()
