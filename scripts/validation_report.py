"""Rows R1-R9, R11 of paper_targets.md for both readings of the head, and the Fig. 4 panels, from
the runs of scripts/validate_readings.py (docs/validation.json, docs/validation.md,
docs/figures/fig4_{ab,c,d,e,f}.png)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from physics.params import SwimmerParams

CMD = "python scripts/validate_readings.py"
READING_TEXT = {
    "torque_free": "consistent: torque-free head (eqn 13), reciprocal head forms",
    "paper": "paper: head not spinning, base at omega in the lab frame, eqns (10)-(11) as printed",
}
DISCUSSION = """## The default reading, and why

The default stays `head_rotation=torque_free`, the physically consistent reading, and
`head_rotation=paper` is offered beside it (with `fixed`, the non-spinning head with reciprocal
head forms). Reasons, in order:

1. **It is the algorithm the paper describes.** Sec. 2.4 updates the head's angular velocity "from
   the torque balance of the entire structure", eqn (13), and Sec. 2.5 defines the motor speed as
   the flagellum's rate *relative to the head*. The reading that reproduces the paper's numbers has
   a head that does not spin, which contradicts that text; it reproduces the numbers, not the
   method. paper_targets.md asks for eqn (13) as the default for the same reason.
2. **It is consistent physics.** With the printed forms of eqns (10)-(11) the head-flagellum
   coupling is not reciprocal: the resistance is not symmetric (its antisymmetric part is 6.5 % of
   its largest entry on the undeformed swimmer), so the model no longer follows from a dissipation
   function; the reciprocal (Faxén) forms are the exact Stokes results for a translating sphere.
3. **The paper's reading is not a full match either**: the table above lists the rows it misses.

**The paper's reading misses R2 and R4 at b = 1.2 cm only** (R4: drop 50.5 % vs 43 %; R2: ω_b
reduction 45.9 % vs 40 %; the 0.4 and 0.8 cm heads are within tolerance). Measured cause: the rigid
swimmer gives the same drops (13.2 / 33.8 / 50.9 % with the printed forms,
[geometry.md](geometry.md), `python scripts/helix_geometry.py`), so neither flexibility nor contact
causes it; with the head's own Stokes drag and no head-flagellum flow coupling the rigid drops are
19.5 / 32.8 / 42.3 % (paper 16 / 32 / 43 %). The printed eqn (11) coupling adds drag that grows with
b, and the paper's Fig. 4d looks like a swimmer without it (or with a weaker one). R9's 139° at
t_c = 54 s is inside the tolerance but comes from a 20 ms step, which turns less than 1 ms in
buckled bursts (issue #15 measured -14 % at 150 rpm).

What the comparison says about the paper: its ω_b, its 0.37 cm per turn and its small-head
drops come from a swimmer whose flagellum base turns at ω in the lab frame with the printed head
forms; the torque-free head counter-rotates (fast for small heads, whose rotational drag scales as
b³), which is why under eqn (13) small heads swim far less (R4), the torque depends on b (R6), and
buckling needs a faster motor (R1, R2). Rigid-helix estimates of the distance per turn for both
readings and for other readings of the paper's N and L: [geometry.md](geometry.md).
"""
PAPER_R2 = [19.0, 32.0, 40.0]
PAPER_R4 = [16.0, 32.0, 43.0]


def _points(done, reading, b=None):
    pts = [r for r in done.values() if r["kind"] == "point" and r["reading"] == reading
           and (b is None or abs(r["head_radius"] - b) < 1e-9)]
    return sorted(pts, key=lambda r: (r["head_radius"], r["omega_rpm"]))


def _mid(br):
    lo, hi = br
    return None if lo is None or hi is None else 0.5 * (lo + hi)


def rows_for(done, reading, plan) -> list[dict]:
    p = SwimmerParams()
    EI, L = p.bending_stiffness, p.axial_length
    rows = []

    def row(rid, what, paper, ours, tol, ok, why=""):
        rows.append({"row": rid, "reading": reading, "what": what, "paper": paper, "ours": ours,
                     "tolerance": tol, "pass": ok, "note": why})

    br = {b: plan.bracket(reading, b) for b in (0.0, 0.004, 0.008, 0.012)}
    # R1
    lo, hi = br[0.012]
    mid = _mid(br[0.012])
    row("R1", "omega_b for b = 1.2 cm (rpm), bisection on L'/L(100 s) < 0.98", 52.0,
        {"bracket_rpm": [lo, hi], "midpoint_rpm": mid, "omega_bar_b": None if mid is None else
         p.omega_bar(mid * 2 * math.pi / 60)}, "±10 %",
        None if mid is None else bool(lo <= 57.2 and hi >= 46.8 and abs(mid - 52) <= 5.2))
    # R2
    base = _mid(br[0.0])
    red = {}
    never = False  # a head that does not buckle where the headless swimmer does: omega_b raised, not lowered
    for b in (0.004, 0.008, 0.012):
        m = _mid(br[b])
        entry = {"bracket_rpm": list(br[b]),
                 "reduction_pct": None if m is None or base is None else 100 * (1 - m / base)}
        if br[b][0] is not None and br[b][1] is None and base is not None and br[b][0] > base:
            entry["no_buckling_up_to_rpm"] = br[b][0]
            entry["reduction_pct_below"] = 100 * (1 - br[b][0] / base)
            never = True
        red[f"{100 * b:.1f} cm"] = entry
    vals = [red[k]["reduction_pct"] for k in ("0.4 cm", "0.8 cm", "1.2 cm")]
    ok = False if never else (None if any(v is None for v in vals)
                              else bool(all(abs(v - t) <= 5 for v, t in zip(vals, PAPER_R2))))
    row("R2", "reduction of omega_b against b = 0 (bracket midpoints), b = 0.4, 0.8, 1.2 cm (%)", PAPER_R2,
        {"b=0 bracket_rpm": list(br[0.0]), **red}, "±5 points", ok)
    # R3: L'/L below omega_b
    low = [r for r in _points(done, reading) if r["omega_rpm"] <= 30 and r["error"] is None]
    ll = [r["end_to_end_ratio"] for r in low]
    row("R3", "L'/L at t_bar = 1.02 below omega_b (10 and 30 rpm, every head)", "slightly above 1",
        {"min": min(ll, default=None), "max": max(ll, default=None)}, "> 1 and < 1.05",
        None if not ll else bool(min(ll) > 1 and max(ll) < 1.05))
    # R4: drop of ||s|| at 10 rpm vs b = 0
    s = {round(r["head_radius"], 4): r["displacement_m"] for r in low if r["omega_rpm"] == 10.0}
    drops = None
    if 0.0 in s and all(b in s for b in (0.004, 0.008, 0.012)):
        drops = [100 * (1 - s[b] / s[0.0]) for b in (0.004, 0.008, 0.012)]
    row("R4", "drop of ||s|| over t_bar = 1.02 at 10 rpm against b = 0, b = 0.4, 0.8, 1.2 cm (%)", PAPER_R4,
        drops, "±5 points", None if drops is None else bool(all(abs(d - t) <= 5 for d, t in zip(drops, PAPER_R4))))
    # R5: ||s|| vs omega_bar linear below omega_b (b = 1.2 cm)
    b12 = [r for r in _points(done, reading, 0.012) if r["error"] is None and r["end_to_end_ratio"] >= 0.98]
    if len(b12) >= 3:
        w = np.array([r["omega_bar"] for r in b12])
        d = np.array([r["displacement_m"] for r in b12])
        fit = np.polyfit(w, d, 1)
        r2 = 1 - np.sum((d - np.polyval(fit, w)) ** 2) / np.sum((d - d.mean()) ** 2)
    else:
        r2 = None
    row("R5", "||s|| against omega_bar below omega_b, b = 1.2 cm: linear fit R^2", "close to linear",
        {"R2_linear_fit": r2, "points": len(b12)}, "R² > 0.98", None if r2 is None else bool(r2 > 0.98))
    # R6: torque spread across b > 0 at 10 and 30 rpm
    spread = []
    for rpm in (10.0, 30.0):
        t = [r["mean_motor_torque_Nm"] * L / EI for r in low if r["omega_rpm"] == rpm and r["head_radius"] > 0]
        if len(t) == 3:
            spread.append([rpm, (max(t) - min(t)) / np.mean(t)])
    row("R6", "T_bar = T L / EI against omega_bar nearly independent of b (b > 0, 10 and 30 rpm)",
        "negligible variation", {"max_relative_spread": max((x[1] for x in spread), default=None),
                                 "by_rpm": spread}, "spread < 10 %",
        None if not spread else bool(max(x[1] for x in spread) < 0.10))
    # R7: P_bar ~ omega_bar^2 (b = 1.2 cm, unbuckled)
    if len(b12) >= 2:
        w = np.array([r["omega_bar"] for r in b12])
        P = np.array([r["mean_motor_torque_Nm"] * L / EI * r["omega_bar"] for r in b12])
        slope = float(np.polyfit(np.log(w), np.log(P), 1)[0])
    else:
        slope = None
    row("R7", "P_bar against omega_bar below omega_b (b = 1.2 cm): log-log slope", "close to quadratic",
        {"loglog_slope": slope}, "—", None if slope is None else bool(abs(slope - 2) < 0.2))
    # R8
    r10 = [r for r in b12 if r["omega_rpm"] == 10.0]
    per_turn = r10[0]["distance_per_turn_m"] * 100 if r10 and r10[0]["distance_per_turn_m"] else None
    row("R8", "distance swum per motor turn at 10 rpm, b = 1.2 cm (cm, last 5 turns of 100 s)", 0.37, per_turn,
        "±15 %", None if per_turn is None else bool(abs(per_turn / 0.37 - 1) <= 0.15))
    # R9
    turns = sorted([r for r in done.values() if r["kind"] == "turn" and r["reading"] == reading],
                   key=lambda r: r["t_c_s"])
    th = [r["theta_deg"] for r in turns if r["theta_deg"] is not None]
    row("R9", "turning angle theta against t_c at omega_h = 60 rpm from steady 10 rpm (b = 1.2 cm); max theta (deg)",
        154.0, {"t_c_s": [r["t_c_s"] for r in turns], "theta_deg": [r["theta_deg"] for r in turns],
                "phi_deg": [r["phi_deg"] for r in turns], "errors": [r["error"] for r in turns if r["error"]],
                "max_theta_deg": max(th, default=None)}, "max within ±15°",
        None if not th else bool(abs(max(th) - 154) <= 15))
    # R11
    r60 = [r for r in _points(done, reading, 0.012) if r["omega_rpm"] in (10.0,)]
    buck = [r for r in _points(done, reading, 0.012) if r["error"] is None]
    at60 = min(buck, key=lambda r: abs(r["omega_rpm"] - 60.0), default=None)
    ours = {"L/L_10rpm": r60[0]["end_to_end_ratio"] if r60 else None,
            "nearest_to_60rpm": None if at60 is None else [at60["omega_rpm"], at60["end_to_end_ratio"]]}
    ok = None
    if r60 and at60 is not None:
        ok = bool(r60[0]["end_to_end_ratio"] >= 0.98 and (at60["end_to_end_ratio"] < 0.98) == (mid is not None and mid < 60))
    row("R11", "configuration at t = 100 s, b = 1.2 cm: stable helix at 10 rpm, buckled at 60 rpm",
        "stable / buckled", ours, "qualitative",
        None if not (r60 and at60) else bool(r60[0]["end_to_end_ratio"] >= 0.98 and at60["end_to_end_ratio"] < 0.98))
    return rows


def physical(done) -> dict:
    """Contact check over every validation run: smallest gaps and nodes inside the head."""
    pts = [r for r in done.values() if r["kind"] == "point"]
    return {"runs": len(pts), "errors": sum(r["error"] is not None for r in pts),
            "min_rod_rod_gap_mm": min((r["min_rod_rod_gap_mm"] for r in pts), default=None),
            "min_head_gap_mm": min((r["min_head_gap_mm"] for r in pts if r["head_radius"] > 0), default=None),
            "nodes_inside_head_at_end": max((r["nodes_inside_head_at_end"] for r in pts), default=None),
            "max_reynolds_up_to_100_rpm": max((r["max_reynolds"] for r in pts if r["omega_rpm"] <= 100), default=None)}


def figures(done, figdir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = SwimmerParams()
    EI, L = p.bending_stiffness, p.axial_length
    figdir.mkdir(parents=True, exist_ok=True)
    panels = {
        "c": ("L'/L at t̄ = 1.02", lambda r: r["end_to_end_ratio"]),
        "d": ("‖s‖ over t̄ = 1.02 (m)", lambda r: r["displacement_m"]),
        "e": ("T̄ = T L / EI", lambda r: r["mean_motor_torque_Nm"] * L / EI),
        "f": ("P̄ = T̄ ω̄", lambda r: r["mean_motor_torque_Nm"] * L / EI * r["omega_bar"]),
    }
    for key, (label, fn) in panels.items():
        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
        for ax, reading in zip(axes, ("torque_free", "paper")):
            for b in (0.0, 0.004, 0.008, 0.012):
                pts = [r for r in _points(done, reading, b) if r["error"] is None and r["mean_motor_torque_Nm"]]
                if pts:
                    ax.plot([r["omega_bar"] for r in pts], [fn(r) for r in pts], "-o", ms=3,
                            label=f"b = {100 * b:.1f} cm")
            if key == "c":
                ax.axhline(0.98, color="k", lw=0.5, ls=":")
                ax.axvline(534.66, color="gray", lw=0.8, ls=":", label="paper ω̄_b (b = 1.2 cm)")
            ax.set_xlabel("ω̄ = ω μ L⁴ / EI")
            ax.set_title(f"reading: {reading}", fontsize=9)
            ax.legend(fontsize=7)
        axes[0].set_ylabel(label)
        fig.suptitle(f"Fig. 4({key}), contact on")
        fig.tight_layout()
        fig.savefig(figdir / f"fig4_{key}.png", dpi=110)
        plt.close(fig)
    _fig4ab(done, figdir / "fig4_ab.png")


def _tube(ax, x, r0, color):
    """The rod as a tube of radius r0 around the centre line x (n,3), cm."""
    t = np.gradient(x, axis=0)
    t /= np.linalg.norm(t, axis=1)[:, None]
    a = np.cross(t, [0.0, 0.0, 1.0])
    bad = np.linalg.norm(a, axis=1) < 1e-6
    a[bad] = np.cross(t[bad], [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a, axis=1)[:, None]
    c = np.cross(t, a)
    ang = np.linspace(0, 2 * np.pi, 10)
    surf = x[:, None, :] + r0 * (np.cos(ang)[None, :, None] * a[:, None, :] + np.sin(ang)[None, :, None] * c[:, None, :])
    ax.plot_surface(surf[..., 0], surf[..., 1], surf[..., 2], color=color, linewidth=0, shade=True)


def _fig4ab(done, path: Path) -> None:
    import matplotlib.pyplot as plt

    p = SwimmerParams()
    fig = plt.figure(figsize=(12, 4.2))
    picks = [("torque_free", 10.0), ("torque_free", 90.0), ("paper", 60.0)]
    for k, (reading, rpm) in enumerate(picks):
        pts = [r for r in _points(done, reading, 0.012) if r["error"] is None]
        if not pts:
            continue
        r = min(pts, key=lambda r: abs(r["omega_rpm"] - rpm))
        x = 100 * np.array(r["final_nodes"])
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        u, v = np.mgrid[0:2 * np.pi:24j, 0:np.pi:12j]
        b = 100 * p.head_radius
        ax.plot_surface(x[0, 0] + b * np.cos(u) * np.sin(v), x[0, 1] + b * np.sin(u) * np.sin(v),
                        x[0, 2] + b * np.cos(v), color="0.6", alpha=0.5, linewidth=0)
        _tube(ax, x[1:], 100 * p.rod_radius, "C0")
        lo, hi = x.min(0) - b, x.max(0) + b
        c, span = 0.5 * (lo + hi), (hi - lo).max() / 2
        ax.set_xlim(c[0] - span, c[0] + span)
        ax.set_ylim(c[1] - span, c[1] + span)
        ax.set_zlim(c[2] - span, c[2] + span)
        ax.set_box_aspect((1, 1, 1))
        ax.set_title(f"{reading}, {r['omega_rpm']:g} rpm, t = 100 s\nL'/L = {r['end_to_end_ratio']:.2f}", fontsize=8)
        ax.set_xlabel("x (cm)", fontsize=7)
        ax.set_ylabel("y (cm)", fontsize=7)
        ax.set_zlabel("z (cm)", fontsize=7)
        ax.tick_params(labelsize=6)
    fig.suptitle("Fig. 4(a, b): head (grey sphere, b = 1.2 cm) and rod at its real thickness (r0 = 1 mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _fmt(v) -> str:
    return json.dumps(v, default=lambda o: float(o)) if not isinstance(v, str) else v


def write_report(done: dict, docs: Path, plan) -> None:
    rows = []
    for reading in ("torque_free", "paper"):
        rows += rows_for(done, reading, plan)
    phys = physical(done)
    meta = {"command": CMD, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "runs": len(done), "cpu_min": sum(r["cpu_s"] for r in done.values()) / 60,
            "dt_s": sorted({r["dt"] for r in done.values()}), "physical": phys,
            "readings": READING_TEXT}
    (docs / "validation.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1,
                                                     default=lambda o: float(o)))
    figures(done, docs / "figures")
    md = ["# Validation against Huang & Jawed 2020 (Fig. 4, Fig. 5d and paper_targets.md)", "",
          f"Produced by `{CMD}` (report: `--report-only`) on {meta['date']}: {meta['runs']} runs, "
          f"{meta['cpu_min']:.0f} CPU-min, time step {meta['dt_s']} s on the paper's grid (N = 122, edges 2δ), "
          "contact on (physics/contact.py), near-field kernel on. Each point: 100 s (t̄ = 1.02) from rest at a "
          "constant motor speed; buckled means L'/L(100 s) < 0.98. No physical constant was tuned.", "",
          "Readings:", ""]
    md += [f"- `{k}`: {v}" for k, v in READING_TEXT.items()]
    md += ["", f"Physical check over all {phys['runs']} runs: smallest rod-rod gap "
           f"{_fmt(phys['min_rod_rod_gap_mm'])} mm, smallest head gap {_fmt(phys['min_head_gap_mm'])} mm "
           f"(checked every 25 steps; negative would be an overlap, the penalty's margin is 0.25 mm), nodes inside the head at "
           f"t = 100 s: {phys['nodes_inside_head_at_end']}, runs ending in an error: {phys['errors']}, largest "
           f"Reynolds number up to 100 rpm {_fmt(phys['max_reynolds_up_to_100_rpm'])} (paper ≤ 4e-2; the largest "
           "values come from buckled runs at 90 rpm, whose tail whips faster than the rigid estimate ρωRr0/μ).", "",
           "| row | reading | what | paper | ours | tolerance | pass |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        ok = {True: "yes", False: "no", None: "not measured"}[r["pass"]]
        md.append(f"| {r['row']} | {r['reading']} | {r['what']} | {_fmt(r['paper'])} | {_fmt(r['ours'])} | "
                  f"{r['tolerance']} | {ok} |")
    md += ["", "## Which reading passes what", ""]
    for reading in ("torque_free", "paper"):
        rr = [r for r in rows if r["reading"] == reading]
        yes = [r["row"] for r in rr if r["pass"] is True]
        no = [r["row"] for r in rr if r["pass"] is False]
        unk = [r["row"] for r in rr if r["pass"] is None]
        md.append(f"- `{reading}`: within tolerance {', '.join(yes) or 'none'}; outside "
                  f"{', '.join(no) or 'none'}" + (f"; not measured {', '.join(unk)}" if unk else "") + ".")
    md += ["", DISCUSSION]
    md += ["", "## Figures", ""] + [f"![Fig. 4({k})](figures/fig4_{k}.png)" for k in ("ab", "c", "d", "e", "f")]
    (docs / "validation.md").write_text("\n".join(md) + "\n")
