"""Why coarse grids turn less: the buckling onset against node count, time step and refresh rule.

One metric, the turning angle after a t_c = 40 s burst at ``OMEGA_HIGH_RPM`` from steady 10 rpm
swimming (``turn_tc40`` of ``flagellum_bench.fidelity``), on a grid of discretisations that start from
the numerics of the retired N = 45 preset (implicit Euler, Newton tolerance 1e-5, LSBT + Higdon head; the
parameter defaults otherwise): node count N at h = 10 ms for two
refresh tolerances, and the time step h at N = 122. The reference is ``paper``'s value from the
fidelity ladder. Results are appended to a JSONL file as they finish (resumable).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from flagellum_bench.fidelity import FidelityConfig, relative_error

NODE_COUNTS = (45, 60, 80, 100, 122)
REFRESH_TOLS = (0.1, 0.03)
TIME_STEPS_S = (5e-3, 1e-2, 2e-2, 5e-2)
METRIC = "turn_tc40"


def _name(n: int, h: float, tol: float) -> str:
    return f"N = {n}, h = {h * 1e3:g} ms, refresh {tol:g} r0"


def sweep_configs() -> tuple[FidelityConfig, ...]:
    """The grid: N x refresh at h = 10 ms, then h at N = 122 and refresh 0.03 r0 (no duplicates)."""
    grid = [(n, 1e-2, tol) for tol in REFRESH_TOLS for n in NODE_COUNTS]
    grid += [(122, h, 0.03) for h in TIME_STEPS_S if h != 1e-2]
    return tuple(FidelityConfig(_name(n, h, tol), None, params={"n_nodes": n},
                                numerics={"dt": h, "hydro_refresh_tol": tol, "newton_tol": 1e-5}) for n, h, tol in grid)


def sweep_rows(done: dict[tuple[str, str], dict], reference: dict[str, float] | None) -> list[dict[str, Any]]:
    """One row per configuration with N, h, refresh, θ, φ (deg), turn-task RTF and the relative θ error."""
    rows = []
    for cfg in sweep_configs():
        rec = done.get((cfg.name, METRIC))
        res = (rec or {}).get("result") or {}
        theta = res.get("theta_tc40")
        err = None
        if theta is not None and reference:
            err = relative_error("theta_tc40", theta, reference["theta_tc40"])
        rows.append({"config": cfg.name, "n_nodes": cfg.params["n_nodes"], "dt": cfg.numerics["dt"],
                     "hydro_refresh_tol": cfg.numerics["hydro_refresh_tol"], "theta_tc40": theta,
                     "phi_tc40": res.get("phi_tc40"), "rtf_turn": res.get("rtf"), "theta_error": err,
                     "error": (rec or {}).get("error"), "measured": (rec or {}).get("measured")})
    return rows


def markdown(rows: list[dict[str, Any]], reference: dict[str, float] | None, header: str) -> str:
    def f(v, spec):
        return "—" if v is None else format(v, spec)

    ref = (f"`paper` (N = 122, h = 1 ms, refresh 0.03 r0, Newton 1e-6): θ = {reference['theta_tc40']:.1f}°, "
           f"φ = {reference['phi_tc40']:.1f}°, turn-task RTF {f(reference.get('rtf'), '.2f')}."
           if reference else "`paper`'s turn_tc40 is not measured yet (scripts/bench_fidelity.py).")
    lines = [header, "", ref, "",
             "| N | h (ms) | refresh (r0) | θ t_c=40 (°) | φ t_c=40 (°) | θ error | RTF (turn task) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        err = "—" if r["theta_error"] is None else f"{100 * r['theta_error']:.0f} %"
        if r["error"]:
            err = r["error"]
        lines.append(f"| {r['n_nodes']} | {r['dt'] * 1e3:g} | {r['hydro_refresh_tol']:g} | {f(r['theta_tc40'], '.1f')} | "
                     f"{f(r['phi_tc40'], '.1f')} | {err} | {f(r['rtf_turn'], '.2f')} |")
    ok = [r for r in rows if r["theta_error"] is not None and r["theta_error"] <= 0.10 and r["rtf_turn"]]
    if reference:
        lines += ["", "Within 10 % of `paper`'s θ: " + (", ".join(f"{r['config']} (RTF {r['rtf_turn']:.2f})"
                                                            for r in ok) or "none") + "."]
        if ok:
            best = max(ok, key=lambda r: r["rtf_turn"])
            lines.append(f"Fastest of these: {best['config']}, {best['rtf_turn'] / reference['rtf']:.1f}x `paper`'s "
                         "turn-task speed (same task, measured two at a time on this machine).")
    lines += ["", "![θ against N and h](figures/node_convergence.png)"]
    return "\n".join(lines) + "\n"


def plot(rows: list[dict[str, Any]], reference: dict[str, float] | None, path: Path) -> None:
    """θ(t_c = 40 s) against N (left, one line per refresh tolerance) and against h at N = 122 (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_n, ax_h) = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for k, tol in enumerate(REFRESH_TOLS):
        pts = sorted((r["n_nodes"], r["theta_tc40"]) for r in rows
                     if r["dt"] == 1e-2 and r["hydro_refresh_tol"] == tol and r["theta_tc40"] is not None)
        if pts:
            ax_n.plot(*zip(*pts), "o-", color=f"C{k}", label=f"refresh {tol:g} r0, h = 10 ms")
    pts = sorted((r["dt"] * 1e3, r["theta_tc40"]) for r in rows
                 if r["n_nodes"] == 122 and r["hydro_refresh_tol"] == 0.03 and r["theta_tc40"] is not None)
    if pts:
        ax_h.plot(*zip(*pts), "o-", color="C1", label="N = 122, refresh 0.03 r0")
    for ax in (ax_n, ax_h):
        if reference:
            ax.axhline(reference["theta_tc40"], color="k", ls="--", lw=1, label="paper (N 122, h 1 ms)")
            ax.axhspan(0.9 * reference["theta_tc40"], 1.1 * reference["theta_tc40"], color="grey", alpha=0.15,
                       label="within 10 %")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    ax_n.set_xlabel("node count N")
    ax_n.set_ylabel("turning angle θ after t_c = 40 s (deg)")
    ax_h.set_xscale("log")
    ax_h.set_xlabel("time step h (ms)")
    fig.suptitle("Buckling onset against the discretisation: θ after a 40 s burst at 90 rpm from 10 rpm", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
