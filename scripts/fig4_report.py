"""Figures and validation table from the Fig. 4 sweep (scripts/reproduce_fig4.py).

    python scripts/fig4_report.py [--sweep out/fig4] [--docs docs]

Writes docs/figures/fig4_{c,d,e,f}.png (one curve per head size, both readings of the head's
rotation), docs/figures/fig4_ab.png (configurations at t = 100 s), and docs/validation.json /
docs/validation.md with rows R1-R9 and R11 of ../shared/reference/paper_targets.md.
Buckling criterion: L'/L at t_bar = 1.02 below 0.98; omega_b is bracketed by the largest
unbuckled and the smallest buckled swept speed (midpoint reported).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from pathlib import Path

import numpy as np

from physics.params import RPM_TO_RAD_S, SwimmerParams

BUCKLED_RATIO = 0.98
#: Fig. 4's speed axis ends near omega_bar = 1000 (about 97 rpm); faster points only bracket omega_b.
PAPER_RANGE_RPM = 100.0
READINGS = ("torque_free", "fixed_head")
CMD = "python scripts/reproduce_fig4.py && python scripts/fig4_report.py"


def load(sweep: Path) -> dict[str, list[dict]]:
    out = {}
    for reading in READINGS:
        f = sweep / reading / "results.jsonl"
        recs = []
        if f.exists():
            for line in f.read_text().splitlines():
                try:
                    r = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if r.get("status") == "ok":
                    r["_dir"] = str(sweep / reading)
                    recs.append(r)
        out[reading] = recs
    return out


def by_head(recs: list[dict]) -> dict[float, list[dict]]:
    d: dict[float, list[dict]] = {}
    for r in recs:
        d.setdefault(r["values"]["head_radius"], []).append(r)
    for v in d.values():
        v.sort(key=lambda r: r["values"]["omega_rpm"])
    return d


def steady_per_turn(rec: dict, turns: int = 5) -> float:
    """Distance per motor turn over the last ``turns`` turns of the run (start-up excluded), m."""
    z = np.load(Path(rec["_dir"]) / rec["trajectory"])
    t, x = z["times"], z["head_positions"]
    period = 60.0 / rec["values"]["omega_rpm"]
    t_end = t[-1]
    t_start = max(t_end - turns * period, 0.0)
    i0 = int(np.searchsorted(t, t_start))
    n_turns = (t_end - t[i0]) / period
    return float(np.linalg.norm(x[-1] - x[i0]) / n_turns)


def omega_b_bracket(recs: list[dict]) -> tuple[float | None, float | None]:
    below = [r["values"]["omega_rpm"] for r in recs if r["summary"]["end_to_end_ratio"] >= BUCKLED_RATIO]
    above = [r["values"]["omega_rpm"] for r in recs if r["summary"]["end_to_end_ratio"] < BUCKLED_RATIO]
    lo = max([w for w in below if not above or w < min(above)], default=None)
    hi = min(above, default=None)
    return lo, hi


def figures(data: dict[str, list[dict]], figdir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = SwimmerParams()
    EI, L = p.bending_stiffness, p.axial_length
    figdir.mkdir(parents=True, exist_ok=True)
    panels = {
        "c": ("L'/L at t̄ = 1.02", lambda r: r["summary"]["end_to_end_ratio"]),
        "d": ("‖s‖ over t̄ = 1.02 (m)", lambda r: r["summary"]["displacement_m"]),
        "e": ("T̄ = T L / EI", lambda r: r["summary"]["mean_motor_torque_Nm"] * L / EI),
        "f": ("P̄ = T̄ ω̄", lambda r: r["summary"]["mean_motor_torque_Nm"] * L / EI * r["summary"]["omega_bar"]),
    }
    for key, (label, fn) in panels.items():
        fig, ax = plt.subplots(figsize=(6, 4))
        for reading, style in zip(READINGS, ("-o", "--s")):
            for b, recs in sorted(by_head(data[reading]).items()):
                ax.plot([r["summary"]["omega_bar"] for r in recs], [fn(r) for r in recs], style,
                        label=f"b = {100 * b:.1f} cm ({reading.replace('_', ' ')})", ms=4)
        if key == "c":
            ax.axhline(BUCKLED_RATIO, color="k", lw=0.5, ls=":")
            ax.axvline(534.66, color="gray", lw=0.8, ls=":", label="paper ω̄_b (b = 1.2 cm)")
        ax.set_xlabel("ω̄ = ω μ L⁴ / EI")
        ax.set_ylabel(label)
        ax.set_title(f"Fig. 4({key}) reproduction")
        ax.legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(figdir / f"fig4_{key}.png", dpi=120)
        plt.close(fig)
    # Fig. 4(a, b): configurations at t = 100 s for b = 1.2 cm at 10 and 60 rpm (or the nearest)
    fig = plt.figure(figsize=(9, 4))
    for k, (reading, target) in enumerate((("torque_free", 10.0), ("torque_free", 90.0), ("fixed_head", 60.0))):
        recs = [r for r in data[reading] if abs(r["values"]["head_radius"] - 0.012) < 1e-9]
        if not recs:
            continue
        r = min(recs, key=lambda r: abs(r["values"]["omega_rpm"] - target))
        z = np.load(Path(r["_dir"]) / r["trajectory"])
        nodes = z["node_positions"][-1]
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        ax.plot(*(100 * nodes.T), "-", lw=1.5)
        ax.scatter(*(100 * nodes[0]), s=60, c="tab:red")
        ax.set_title(f"{reading.replace('_', ' ')}, {r['values']['omega_rpm']:.0f} rpm "
                     f"(ω̄ = {r['summary']['omega_bar']:.0f})\nL'/L = {r['summary']['end_to_end_ratio']:.3f}",
                     fontsize=8)
        ax.set_xlabel("x (cm)", fontsize=7)
        ax.set_ylabel("y (cm)", fontsize=7)
        ax.set_zlabel("z (cm)", fontsize=7)
        ax.set_box_aspect((1, 1, 1))
    fig.tight_layout()
    fig.savefig(figdir / "fig4_ab.png", dpi=120)
    plt.close(fig)


def validation_rows(data: dict[str, list[dict]]) -> list[dict]:
    rows = []
    tf, fx = by_head(data["torque_free"]), by_head(data["fixed_head"])

    def add(rid, what, paper, ours, tol, ok, note=""):
        rows.append({"id": rid, "what": what, "paper": paper, "ours": ours, "tolerance": tol,
                     "pass": bool(ok), "note": note, "command": CMD})

    # R1
    lo, hi = omega_b_bracket(tf.get(0.012, []))
    mid = None if lo is None or hi is None else 0.5 * (lo + hi)
    add("R1", "omega_b for b = 1.2 cm (rpm), eqn (13) head", 52.0,
        {"bracket_rpm": [lo, hi], "midpoint_rpm": mid}, "±10 %",
        mid is not None and abs(mid - 52) <= 5.2 and (lo is None or lo < 52 * 1.1) and (hi is None or hi > 52 * 0.9),
        "bracket from the swept speeds (L'/L < 0.98 at t̄ = 1.02)")
    lo_f, hi_f = omega_b_bracket(fx.get(0.012, []))
    rows[-1]["ours"]["fixed_head_bracket_rpm"] = [lo_f, hi_f]
    # R2 (both readings; b = 0 has no head, so its bracket is the baseline of both)
    base = omega_b_bracket(tf.get(0.0, []))
    for reading, groups in (("eqn (13) torque-free", tf), ("fixed head", fx)):
        red: dict[str, dict] = {}
        for b in (0.004, 0.008, 0.012):
            br = omega_b_bracket(groups.get(b, []))
            entry: dict = {"bracket_rpm": list(br)}
            if None not in br and None not in base:
                mid0, midb = 0.5 * (base[0] + base[1]), 0.5 * (br[0] + br[1])
                entry["reduction_pct"] = 100 * (1 - midb / mid0)
                entry["reduction_range_pct"] = [100 * (1 - br[1] / base[0]), 100 * (1 - br[0] / base[1])]
            red[f"{100 * b:.1f} cm"] = entry
        got = [e.get("reduction_pct") for e in red.values()]
        ok = None not in got and all(abs(g - p) <= 5 for g, p in zip(got, (19, 32, 40), strict=True))
        add("R2" if reading.startswith("eqn") else "R2 (fixed head)",
            f"reduction of omega_b vs b = 0 for b = 0.4, 0.8, 1.2 cm, {reading} (%, bracket midpoints)",
            [19, 32, 40], {"b=0 bracket_rpm": list(base), **red}, "±5 points", ok,
            "from the brackets of the swept speeds; a head with no bracket has no reduction")
    # R3
    ratios = [r["summary"]["end_to_end_ratio"] for b in tf for r in tf[b]
              if r["summary"]["end_to_end_ratio"] >= BUCKLED_RATIO]
    add("R3", "L'/L at t̄ = 1.02 below omega_b (all heads, eqn 13)", "slightly above 1",
        {"min": min(ratios, default=None), "max": max(ratios, default=None)}, "> 1 and < 1.05",
        bool(ratios) and min(ratios) > 1.0 and max(ratios) < 1.05)
    # R4 (at 10 rpm, both readings)
    for reading, groups in (("eqn (13) torque-free", tf), ("fixed head", fx)):
        d0 = [r for r in tf.get(0.0, []) if r["values"]["omega_rpm"] == 10.0]
        drops = {}
        for b in (0.004, 0.008, 0.012):
            rb = [r for r in groups.get(b, []) if r["values"]["omega_rpm"] == 10.0]
            if d0 and rb:
                drops[f"{100 * b:.1f} cm"] = 100 * (1 - rb[0]["summary"]["displacement_m"] / d0[0]["summary"]["displacement_m"])
        ok = len(drops) == 3 and all(abs(drops[k] - v) <= 5 for k, v in zip(drops, (16, 32, 43)))
        add("R4" if reading.startswith("eqn") else "R4 (fixed head)",
            f"drop of ||s|| vs b = 0 at 10 rpm, {reading} (%)", [16, 32, 43], drops, "±5 points", ok)
    # R5
    rec5 = [r for r in tf.get(0.012, []) if r["summary"]["end_to_end_ratio"] >= BUCKLED_RATIO]
    r2 = None
    if len(rec5) >= 3:
        w = np.array([r["summary"]["omega_bar"] for r in rec5])
        s = np.array([r["summary"]["displacement_m"] for r in rec5])
        coef = np.polyfit(w, s, 1)
        r2 = 1 - np.sum((s - np.polyval(coef, w)) ** 2) / np.sum((s - s.mean()) ** 2)
    add("R5", "||s|| vs omega_bar below omega_b is linear (b = 1.2 cm)", "close to linear",
        {"R2_linear_fit": r2, "points": len(rec5)}, "R² > 0.98", r2 is not None and r2 > 0.98)
    # R6 (both readings)
    for reading, groups in (("eqn (13) torque-free", tf), ("fixed head", fx)):
        spreads = []
        for w in sorted({r["values"]["omega_rpm"] for b in groups for r in groups[b]}):
            T = [r["summary"]["mean_motor_torque_Nm"] for b in groups if b > 0 for r in groups[b]
                 if r["values"]["omega_rpm"] == w and r["summary"]["end_to_end_ratio"] >= BUCKLED_RATIO]
            if len(T) >= 2:
                spreads.append((w, (max(T) - min(T)) / np.mean(T)))
        worst = max((s for _, s in spreads), default=None)
        add("R6" if reading.startswith("eqn") else "R6 (fixed head)",
            f"T̄ vs omega_bar nearly independent of b (b > 0, unbuckled), {reading}", "negligible variation",
            {"max_relative_spread": worst, "by_rpm": spreads}, "spread < 10 %", worst is not None and worst < 0.10)
    # R7
    rec7 = [r for r in tf.get(0.012, []) if r["values"]["omega_rpm"] <= PAPER_RANGE_RPM]
    q = None
    if len(rec7) >= 3:
        w = np.array([r["summary"]["omega_bar"] for r in rec7])
        P = np.array([r["summary"]["mean_motor_power_W"] for r in rec7])
        q = float(np.polyfit(np.log(w), np.log(np.abs(P)), 1)[0])
    add("R7", "P̄ vs omega_bar (b = 1.2 cm): log-log slope", "close to quadratic (slope 2)",
        {"loglog_slope": q}, "—", q is not None and abs(q - 2) < 0.3)
    # R8 (both readings)
    for reading, groups in (("eqn (13) torque-free", tf), ("fixed head", fx)):
        rb = [r for r in groups.get(0.012, []) if r["values"]["omega_rpm"] == 10.0]
        v = steady_per_turn(rb[0]) if rb else None
        add("R8" if reading.startswith("eqn") else "R8 (fixed head)",
            f"distance per motor turn at 10 rpm, b = 1.2 cm, {reading} (cm)", 0.37,
            None if v is None else 100 * v, "±15 %", v is not None and abs(100 * v - 0.37) <= 0.37 * 0.15)
    # Reynolds number of every point (Sec. 2.1: <= 4e-2 in all the paper's runs)
    def re_max(limit_rpm: float) -> float | None:
        return max((r["summary"]["max_reynolds"] for recs in data.values() for r in recs
                    if r["summary"].get("max_reynolds") is not None and r["values"]["omega_rpm"] <= limit_rpm),
                   default=None)

    in_range = re_max(PAPER_RANGE_RPM)
    add("Re", f"largest Reynolds number rho |v|max r0 / mu over the sweep points in the paper's range "
              f"(omega <= {PAPER_RANGE_RPM:g} rpm, omega_bar <= 1028)", "<= 4e-2",
        {"max": in_range, "max_all_points_up_to_150_rpm": re_max(math.inf)}, "< 4e-2",
        in_range is not None and in_range < 4e-2, "max node speed, both readings")
    # R9: turn maps of the paper's protocol (omega_h = 60 rpm), data/turn_maps/r9_*.json
    r9 = {}
    for f in sorted(Path("data/turn_maps").glob("r9_*.json")):
        m = json.loads(f.read_text())
        by_tc: dict[float, list[float]] = {}
        for p in m["points"]:
            by_tc.setdefault(p["t_c"], []).append(p["theta_deg"])
        r9[f"{m['preset']} preset, {m['params']['head_rotation']}"] = {
            "t_c_s": sorted(by_tc), "theta_deg": [float(np.mean(by_tc[t])) for t in sorted(by_tc)],
            "max_theta_deg": max(float(np.mean(v)) for v in by_tc.values())}
    tf9 = next((v["max_theta_deg"] for k, v in r9.items() if k.endswith("torque_free")), None)
    add("R9", "max turning angle theta over t_c <= 54 s at omega_h = 60 rpm from 10 rpm (Fig. 5d), eqn 13", 154,
        r9 or None, "±15°", tf9 is not None and abs(tf9 - 154) <= 15,
        "flagellum calibrate-turns --omega-h 60 (see docs/planner.md)")
    # R11
    r10 = [r for r in tf.get(0.012, []) if r["values"]["omega_rpm"] == 10.0]
    r60 = [r for r in tf.get(0.012, []) if r["values"]["omega_rpm"] == 60.0]
    f60 = [r for r in fx.get(0.012, []) if r["values"]["omega_rpm"] == 60.0]
    add("R11", "configuration at t = 100 s, b = 1.2 cm: stable helix at 10 rpm, buckled at 60 rpm (eqn 13)",
        "stable / buckled",
        {"L/L_10rpm": r10[0]["summary"]["end_to_end_ratio"] if r10 else None,
         "L/L_60rpm": r60[0]["summary"]["end_to_end_ratio"] if r60 else None,
         "L/L_60rpm_fixed_head": f60[0]["summary"]["end_to_end_ratio"] if f60 else None},
        "qualitative", bool(r10 and r60) and r10[0]["summary"]["end_to_end_ratio"] >= BUCKLED_RATIO
        and r60[0]["summary"]["end_to_end_ratio"] < BUCKLED_RATIO,
        "see docs/figures/fig4_ab.png")
    return rows


# Likely reasons for rows that do not pass (analysis, not tuning; see docs/validation.md)
REASONS = {
    "R1": "The fixed-head bracket (50-60 rpm) contains the paper's 52 rpm. With the head torque-free (eqn 13) the head counter-rotates, so the flagellum turns slower in "
          "the lab than the motor speed and buckles later. In the 'fixed head' reading the threshold is "
          "lower (bracket in 'ours'). The paper's eqn (13) is lagged by one step in its scheme; the "
          "counter-rotation depends on the printed head-flow coefficients, which are not self-consistent "
          "(see physics/higdon_head.py).",
    "R2": "Under eqn (13) small heads counter-rotate almost at the motor speed (their rotational drag "
          "scales as b^3), so the flagellum barely turns in the lab: b = 0.4 and 0.8 cm did not buckle even "
          "at 150 rpm (L'/L 1.009 and 1.044 at t_bar = 1.02), while b = 0 buckles between 90 and 120 rpm. "
          "In this reading a small head raises omega_b instead of lowering it; the paper's trend appears "
          "in the fixed-head reading (next row).",
    "R4": "Under eqn (13) small heads counter-rotate almost at the motor speed, so the displacement drops "
          "far more than the paper's 16/32/43 % (see the paper_targets note: R4 and R8 are not "
          "reachable under one reading); the fixed-head row shows the other reading.",
    "R6": "Under eqn (13) small heads counter-rotate, so the flagellum turns slower in the lab and needs "
          "less torque; with the head not spinning the torque is almost independent of b (fixed-head row).",
    "R4 (fixed head)": "With the head not spinning the drops (9, 27, 42 %) are close to the paper's for the "
                       "larger heads; the smallest head and the baseline depend on the b = 0 convention "
                       "(here a 2-delta motor shaft turning at omega with no head), which the paper leaves open.",
    "R8 (fixed head)": "0.429 cm is just outside the +15 % band (0.4255 cm); eqn (13) gives 0.276 cm. The paper's "
                       "0.37 cm lies between the two readings, as the rigid-helix estimate in paper_targets predicts.",
    "R2 (fixed head)": "With the head not spinning every head size has a bracket; the midpoint reductions "
                       "(24, 38, 48 %) are 5-8 points above the paper's 19, 32, 40 %, and the brackets "
                       "(10-30 rpm wide; reduction ranges in 'ours') contain the paper's values. Finer speeds "
                       "near each threshold (bisection) would narrow them; the b = 0 baseline (90-120 rpm) "
                       "depends on the b = 0 convention (a motor shaft with no head).",
    "R3": "The smallest L'/L (0.994) is the headless swimmer at 10 rpm (b = 0 convention); the largest L'/L comes from small heads at high speed under eqn (13): the fast-counter-rotating "
          "head leaves a strongly twisted, stretched helix that has not buckled.",
    "R8": "The torque-free head gives ~0.28 cm per turn, the fixed head ~0.43 cm; the paper's 0.37 cm lies "
          "between the two readings, as the rigid-helix estimate in paper_targets predicts.",
    "R9": "With the head torque-free (eqn 13) 60 rpm is below this model's buckling threshold (R1), so a "
          "burst at the paper's omega_h = 60 rpm hardly turns the swimmer (fast preset: at most 1.1 deg for "
          "t_c <= 54 s). With the head not spinning (the other reading) 60 rpm buckles the paper-preset "
          "swimmer: 9.4 deg after t_c = 30 s and 131.8 deg after 54 s (t_bar_c = 0.55, the end of the "
          "paper's range), 22 deg short of 154 deg with only two burst lengths measured (CPU time); the "
          "fast preset (N = 45) does not buckle at 60 rpm even then (4.6 deg). The planner bursts at "
          "150 rpm, where the paper-preset map reaches 163 deg (docs/planner.md).",
    "R11": "At 60 rpm the torque-free swimmer does not buckle (L'/L = 1.028; threshold 70-90 rpm, R1); with "
           "the head not spinning it does (L'/L = 0.20). fig4_ab.png shows the buckled shapes.",
}


def markdown(rows: list[dict], meta: dict) -> str:
    out = ["# Validation against Huang & Jawed 2020 (Fig. 4 and paper_targets.md)", "",
           f"Produced by `{CMD}` on {meta['date']} ({meta['machine']}); "
           f"sweep CPU time {meta['sweep_cpu_time_s'] / 60:.0f} min over {meta['sweep_points']} points "
           "(2 worker processes). Each point: 100 s (t̄ = 1.02) from rest, N = 122, h = 5 ms. "
           f"Buckling criterion: {meta['buckling_criterion']}. No physical constant was tuned.", "",
           "| row | what | paper | ours | tolerance | pass |", "|---|---|---|---|---|---|"]
    for r in rows:
        ours = json.dumps(r["ours"], default=lambda v: round(float(v), 4))
        out.append(f"| {r['id']} | {r['what']} | {r['paper']} | {ours} | {r['tolerance']} | "
                   f"{'yes' if r['pass'] else 'no'} |")
    out += ["", "## Rows that do not pass, and the most likely reason", ""]
    for r in rows:
        if not r["pass"]:
            key = r["id"].split()[0]
            out.append(f"- **{r['id']}**: {REASONS.get(r['id'], REASONS.get(key, r.get('note') or 'see the table'))}")
    out += ["", "## Figures", ""] + [f"![Fig. 4({k})](figures/fig4_{k}.png)" for k in ("ab", "c", "d", "e", "f")]
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sweep", default="data/fig4")
    ap.add_argument("--docs", default="docs")
    args = ap.parse_args(argv)
    data = load(Path(args.sweep))
    docs = Path(args.docs)
    figures(data, docs / "figures")
    rows = validation_rows(data)
    wall = sum(r["wall_time_s"] for recs in data.values() for r in recs)
    meta = {"date": time.strftime("%Y-%m-%d %H:%M"), "machine": platform.platform(),
            "sweep_points": {k: len(v) for k, v in data.items()}, "sweep_cpu_time_s": wall,
            "buckling_criterion": f"L'/L < {BUCKLED_RATIO} at t_bar = 1.02"}
    (docs / "validation.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=2, default=float))
    (docs / "validation.md").write_text(markdown(rows, meta))
    for r in rows:
        print(f"{r['id']:16s} pass={r['pass']!s:5s} ours={json.dumps(r['ours'], default=float)[:110]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
