"""How the helix is laid out, and what the alternatives would change: the rigid helix's thrust
coefficient and the distance swum per motor turn for several readings of the paper's N and L.

    python scripts/helix_geometry.py [--out docs/geometry.json]

Sec. 2.2 of the paper: node x0 is the head centre, e0 (length b) points along -X_b, e1 = -R x_b + R y_b,
"all the remaining nodes (x2 ... x_{N-1})" lie on the helix with edges 2 delta, and "this discrete
formulation of LSBT requires that the length of each edge be 2 delta, resulting in a total node
number of N = 122". So N counts the head centre and the arm node: 120 helix nodes, 119 chords of
2 delta (this project's layout, ``physics.model.geometry``). Sec. 2.1 gives L = 13 cm axial length and
"a contour length l = 20 cm". The variants below keep R, lambda and the 2 delta chord and change only
how many chords there are (and so the axial length), or where the helix ends (its final phase).

For each variant, rigid swimmer, 10 rpm, b = 1.2 cm, no contact involved (nothing touches):
* thrust coefficient B: axial force on the rigid helix (head absent) rotating at unit rate about
  its axis while held in place, N/(rad/s), and B / (mu L_ax^2) (nondimensional);
* distance per motor turn with the head, for the torque-free reading (head spinning per eqn 13,
  reciprocal head forms) and for the paper's (head not spinning, eqns 10-11 as printed), cm.
Both from the generalised resistance of ``physics.hydro.hydrodynamics`` (LSBT with the default smoothing;
and raw eqn 8 without smoothing for the thrust coefficient).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from physics.model.geometry import helix_phase_step
from physics.hydro.hydrodynamics import resistance_matrix
from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams

P = SwimmerParams()
NM = NumericsConfig()


def nodes(n_chords: int, b: float, phase_extra: float = 0.0) -> np.ndarray:
    """Head centre, arm node, then n_chords + 1 helix nodes 2 delta apart (``phase_extra``, rad,
    spread over the chords, would lengthen them; 0 keeps them at 2 delta)."""
    R, c = P.helix_radius, P.pitch / (2 * math.pi)
    dphi = helix_phase_step(P) + phase_extra / n_chords
    phi = dphi * np.arange(n_chords + 1)
    base = b if b > 0 else 2 * P.cutoff_length
    helix = np.stack([-base - R - c * phi, R * np.cos(phi), R * np.sin(phi)], axis=1)
    return np.vstack([np.zeros((1, 3)), [[-base, 0.0, 0.0]], helix])


def thrust_coefficient(x_helix: np.ndarray, smoothing: float) -> float:
    """Axial force on the rigid helix spinning at 1 rad/s about x, held in place, N/(rad/s)."""
    R = resistance_matrix(x_helix, P.viscosity, P.cutoff_length, 0.0, False, smoothing)
    ex = np.array([1.0, 0.0, 0.0])
    G = -(R @ np.cross(ex, x_helix).ravel()).reshape(-1, 3)
    return float(G[:, 0].sum())


def per_turn(x: np.ndarray, b: float, reading: str) -> float:
    """Distance per motor turn of the rigid swimmer at 10 rpm, m (force-free; torque-free head
    for the consistent reading)."""
    spin = reading == "torque_free"
    R = resistance_matrix(x, P.viscosity, P.cutoff_length, b, spin, NM.lsbt_smoothing,
                          printed_head=reading == "paper")
    n = len(x)
    ex = np.array([1.0, 0.0, 0.0])
    nv = 3 * n + (1 if spin else 0)

    def field(kind):
        V = np.zeros(nv)
        if kind == "U":
            V[:3 * n] = np.tile(ex, n)
        elif kind == "flag":  # flagellum nodes rotating at 1 rad/s about x (head still)
            V[3:3 * n] = np.cross(ex, x[1:]).ravel()
        else:  # head spinning at 1 rad/s about x (spin axis a = -x)
            V[-1] = -1.0
        G = -R @ V
        f = G[:3 * n].reshape(-1, 3)
        force = f[:, 0].sum()
        torque = np.cross(x, f)[:, 0].sum() + (-G[-1] if spin else 0.0)
        return force, torque

    omega = 10 * RPM_TO_RAD_S
    fU, tU = field("U")
    ff, tf = field("flag")
    # the motor turns the flagellum at omega about t0 = -x relative to the head: Omega_f = Omega_h - omega
    if spin:
        fh, th = field("head")
        # unknowns U, Omega_h: force and torque balance of the whole swimmer
        A = np.array([[fU, ff + fh], [tU, tf + th]])
        rhs = np.array([ff * omega, tf * omega])
        U, _ = np.linalg.solve(A, rhs)
    else:
        U = ff * omega / fU
    return float(abs(U) * 2 * math.pi / omega)


def rigid_drops() -> dict[str, list[float]]:
    """Drop of the rigid swimmer's distance per turn against b = 0 for b = 0.4, 0.8, 1.2 cm (%), head
    not spinning, for three head models: the printed forms (the paper's reading), the reciprocal forms,
    and the head's own Stokes drag with no head-flagellum flow coupling."""
    from physics.hydro.hydrodynamics import ResistanceOperator

    def speed(b: float, printed: bool, coupling: bool) -> float:
        x = nodes(119, b)
        R = ResistanceOperator(x, P.viscosity, P.cutoff_length, b, False, NM.lsbt_smoothing,
                               head_coupling=coupling, printed_head=printed and b > 0).dense()
        n, ex = len(x), np.array([1.0, 0.0, 0.0])
        V_u, V_f = np.zeros(R.shape[0]), np.zeros(R.shape[0])
        V_u[:3 * n] = np.tile(ex, n)
        V_f[3:3 * n] = np.cross(ex, x[1:]).ravel()
        f_u, f_f = (-(R @ V)[:3 * n].reshape(-1, 3)[:, 0].sum() for V in (V_u, V_f))
        return abs(f_f / f_u)

    base = speed(0.0, False, True)
    out = {}
    for name, printed, coupling in (("printed forms (paper's reading)", True, True),
                                    ("reciprocal forms", False, True), ("Stokes drag only, no coupling", False, False)):
        out[name] = [100 * (1 - speed(b, printed, coupling) / base) for b in (0.004, 0.008, 0.012)]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/geometry.json")
    args = ap.parse_args(argv)
    ds = 2 * P.cutoff_length
    c = P.pitch / (2 * math.pi)
    dphi = helix_phase_step(P)
    chords_13cm = int(round(0.13 / (c * dphi)))
    chords_20cm = int(round(0.20 / ds))
    variants = [("this project: N = 122 counts head centre and arm node (119 chords)", 119, 0.0),
                ("N = 122 helix nodes (121 chords)", 121, 0.0),
                (f"axial length exactly 13 cm ({chords_13cm} chords)", chords_13cm, 0.0),
                (f"contour length 20 cm ({chords_20cm} chords)", chords_20cm, 0.0),
                ("a quarter turn longer (127 chords)", 127, 0.0),
                ("a quarter turn shorter (111 chords)", 111, 0.0)]
    rows = []
    for name, nc, extra in variants:
        x0 = nodes(nc, 0.0, extra)[2:]
        ax_len = float(x0[0, 0] - x0[-1, 0])
        B = thrust_coefficient(x0, NM.lsbt_smoothing)
        B_raw = thrust_coefficient(x0, 0.0)
        xh = nodes(nc, P.head_radius, extra)
        rows.append({"variant": name, "helix_chords": nc, "helix_nodes": nc + 1,
                     "axial_length_cm": 100 * ax_len, "contour_length_cm": 100 * nc * ds * (1 + 0 * extra),
                     "turns": nc * (dphi + extra / nc) / (2 * math.pi),
                     "thrust_N_per_rad_s": B, "thrust_nondim": B / (P.viscosity * ax_len**2),
                     "thrust_raw_eqn8_N_per_rad_s": B_raw,
                     "per_turn_cm_torque_free": 100 * per_turn(xh, P.head_radius, "torque_free"),
                     "per_turn_cm_paper": 100 * per_turn(xh, P.head_radius, "paper")})
    Path(args.out).write_text(json.dumps(rows, indent=1))
    md = [__doc__.split("\n\n", 2)[2].strip(), "", "Produced by `python scripts/helix_geometry.py`.", "",
          "| variant | helix nodes | axial length (cm) | contour (cm) | turns | B (uN per rad/s) | B raw eqn 8 | "
          "cm/turn, torque-free | cm/turn, paper's reading |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['variant']} | {r['helix_nodes']} | {r['axial_length_cm']:.2f} | {r['contour_length_cm']:.2f} | "
                  f"{r['turns']:.2f} | {1e6 * r['thrust_N_per_rad_s']:.1f} | {1e6 * r['thrust_raw_eqn8_N_per_rad_s']:.1f} | "
                  f"{r['per_turn_cm_torque_free']:.3f} | {r['per_turn_cm_paper']:.3f} |")
    drops = rigid_drops()
    md += ["", "## Rigid estimate of R4: drop of the distance per turn against b = 0 (head not spinning)", "",
           "| head model | b = 0.4 cm | 0.8 cm | 1.2 cm |", "|---|---|---|---|",
           "| paper (Fig. 4d) | 16 | 32 | 43 |"]
    md += [f"| {k} | " + " | ".join(f"{v:.1f}" for v in vals) + " |" for k, vals in drops.items()]
    Path(args.out).write_text(json.dumps({"variants": rows, "rigid_drops_pct": drops}, indent=1))
    Path(args.out).with_suffix(".md").write_text("# Geometry of the helix\n\n" + "\n".join(md) + "\n")
    for k, vals in drops.items():
        print(f"rigid drops, {k}: " + ", ".join(f"{v:.1f} %" for v in vals))
    print(f"{'variant':62s} {'L_ax cm':>7s} {'turns':>5s} {'B uN/(rad/s)':>12s} {'B raw':>8s} "
          f"{'cm/turn TF':>10s} {'cm/turn paper':>13s}")
    for r in rows:
        print(f"{r['variant']:62s} {r['axial_length_cm']:7.2f} {r['turns']:5.2f} {1e6 * r['thrust_N_per_rad_s']:12.2f} "
              f"{1e6 * r['thrust_raw_eqn8_N_per_rad_s']:8.2f} {r['per_turn_cm_torque_free']:10.3f} "
              f"{r['per_turn_cm_paper']:13.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
