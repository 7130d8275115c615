"""Lighthill slender-body theory for the flagellum, eqns (8)-(9) of Huang & Jawed 2020.

The mobility matrix A maps the hydrodynamic forces on the flagellum nodes, F (3M,), to
minus the flagellum-induced velocities: -U_f = A F (eqn 9). Rows/columns are node-major
(node j occupies 3j:3j+3).

Regularisation (the paper's "the force varies smoothly along the arc length"): with nodes
2 delta apart, eqn (8) is a midpoint quadrature of a first-kind integral operator whose
tangential part has *negative* eigenvalues at wavelengths below about six node spacings
(for a straight rod the alternating tangential mode has eigenvalue -4 ln2 / (8 pi mu 2 delta)).
An indefinite mobility would pump energy into those modes. We add a fourth-difference
penalty on the force,

    A_reg = A + s / (8 pi mu 2 delta) * (D2^T D2 / 16) (x) I_3,

where D2 is the second difference along the node index and s = ``lsbt_smoothing``. It
adds s/(8 pi mu 2 delta) to the mobility of the alternating mode and O((k ds)^4) to a mode of
wavenumber k, so modes spanning many nodes (a helical turn spans ~30) change by < 0.1 %,
while rough force distributions become expensive: the inverse problem yields a smooth force.
s >= 6 makes a straight rod's mobility positive definite (s >= 8 the paper helix); the default s = 20 leaves margin
for strongly deformed shapes. Rigid-helix swimming speeds change by < 1.5 % for s = 10 ... 160.

Segments longer than 2 delta (the arm edge e1, or a coarser grid): node j stands for the
segment ell_j = max(half-edge sum, 2 delta); its local term uses the force density F_j/ell_j,
and the Stokeslets of its own segment beyond the cutoff, int_{delta<|s|<a} (I + t t)/(8 pi mu |s|)
ds, are added in closed form, (I + t t) ln(a/delta) / (8 pi mu ell_j) per half-edge a > delta.
On the paper's 2-delta grid both reduce exactly to eqn (8).

Near field (strands that come close): eqn (8)'s Stokeslet 1/(8 pi mu r) between two distant
parts of the rod that approach each other within a few r0 makes the mobility lose definiteness
(a hairpin of two strands 1.5 mm apart: lowest eigenvalue -0.47 / (8 pi mu 2 delta), the
Cholesky of the step fails). For node pairs far apart *along* the rod but close in space the
Stokeslet is blended into the Rotne-Prager-Yamakawa tensor of two spheres of radius
a = ``near_radius`` (default 1.5 r0: a 2-delta segment of radius r0 has a hydrodynamic radius
of about that size), which is positive definite for every configuration and bounded as
r -> 0 (``near_field_weight``, ``rpy_coefficients``). Pairs farther than 5 r0 apart in space, or
closer than 4 r0 along the rod, keep eqn (8) exactly, so a swimmer whose strands stay apart
(every unbuckled shape) is unchanged.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def node_tangent(x: np.ndarray, j: int) -> tuple[float, float, float, float]:
    """(t0, t1, t2, ell) of node j of x (M,3), m: the unit tangent, normalised (t^{j-1} + t^j) (eqn 8 text; an
    end node uses its edge), and half the sum of the adjacent edge lengths, m. Scalars only (no allocation)."""
    m = x.shape[0]
    a0 = a1 = a2 = 0.0
    ell = 0.0
    if j > 0:
        e0, e1, e2 = x[j, 0] - x[j - 1, 0], x[j, 1] - x[j - 1, 1], x[j, 2] - x[j - 1, 2]
        le = math.sqrt(e0 ** 2 + e1 ** 2 + e2 ** 2)
        a0, a1, a2 = a0 + e0 / le, a1 + e1 / le, a2 + e2 / le
        ell += 0.5 * le
    if j < m - 1:
        e0, e1, e2 = x[j + 1, 0] - x[j, 0], x[j + 1, 1] - x[j, 1], x[j + 1, 2] - x[j, 2]
        le = math.sqrt(e0 ** 2 + e1 ** 2 + e2 ** 2)
        a0, a1, a2 = a0 + e0 / le, a1 + e1 / le, a2 + e2 / le
        ell += 0.5 * le
    na = math.sqrt(a0 ** 2 + a1 ** 2 + a2 ** 2)
    return a0 / na, a1 / na, a2 / na, ell


@njit(cache=True)
def node_tangents(x: np.ndarray) -> np.ndarray:
    """Unit node tangents, t_j = normalised (t^{j-1} + t^j) (eqn 8 text), end nodes use their edge. (M,3)."""
    m = x.shape[0]
    t = np.empty((m, 3))
    for j in range(m):
        t[j, 0], t[j, 1], t[j, 2], _ = node_tangent(x, j)
    return t


@njit(cache=True)
def _dist(x: np.ndarray, i: int, j: int) -> float:
    return math.sqrt((x[i, 0] - x[j, 0]) ** 2 + (x[i, 1] - x[j, 1]) ** 2 + (x[i, 2] - x[j, 2]) ** 2)


@njit(cache=True)
def _smoothstep(u: float) -> float:
    """0 for u <= 0, 1 for u >= 1, C1 in between."""
    if u <= 0.0:
        return 0.0
    if u >= 1.0:
        return 1.0
    return u * u * (3.0 - 2.0 * u)


@njit(cache=True)
def near_field_weight(dist: float, arc_gap: float, a: float) -> float:
    """Weight of the near-field kernel for a node pair (0 = plain eqn 8, 1 = RPY).

    dist: distance, m; arc_gap: arc length between the nodes, m; a: near-field radius, m.
    C1 blends: 1 at dist <= 2a, 0 at dist >= 10a/3; 0 at arc_gap <= 8a/3, 1 at arc_gap >= 16a/3.
    For the default a = 1.5 r0 that is 3 r0 / 5 r0 in space and 4 r0 / 8 r0 along the rod.
    """
    w_arc = _smoothstep((arc_gap - 8.0 * a / 3.0) / (8.0 * a / 3.0))
    return w_arc * (1.0 - _smoothstep((dist - 2.0 * a) / (4.0 * a / 3.0)))


@njit(cache=True)
def rpy_coefficients(d: float, a: float, mu: float) -> tuple[float, float]:
    """Rotne-Prager-Yamakawa pair mobility c_iso I + c_rr r^ r^ of two spheres of radius a, m/(N s).

    Rotne & Prager, J. Chem. Phys. 50, 4831 (1969); overlapping form (d < 2a): Wajnryb et al.,
    J. Fluid Mech. 731, R3 (2013). Positive definite for any configuration; equals the Stokeslet
    plus its O(a^2 / d^2) Faxen correction for d >= 2a and stays bounded as d -> 0.
    """
    if d >= 2.0 * a:
        c = 1.0 / (8.0 * math.pi * mu * d)
        return c * (1.0 + 2.0 * a * a / (3.0 * d * d)), c * (1.0 - 2.0 * a * a / (d * d))
    c = 1.0 / (6.0 * math.pi * mu * a)
    return c * (1.0 - 9.0 * d / (32.0 * a)), c * 3.0 * d / (32.0 * a)


@njit(cache=True)
def lsbt_mobility(x: np.ndarray, t: np.ndarray, mu: float, delta: float, smoothing: float,
                  near_radius: float = 0.0) -> np.ndarray:
    """Regularised LSBT mobility A_reg, eqn (8)-(9) plus the smoothness term. (3M,3M), m/(N s).

    x: (M,3) flagellum node positions, m; t: (M,3) unit node tangents; mu: Pa s;
    delta: cutoff length, m; smoothing: s (dimensionless, 0 = plain eqn 8);
    near_radius: a, m, of the near-field kernel for strands that come close (0 = off, see
    the module docstring).
    """
    m = x.shape[0]
    a = np.empty((3 * m, 3 * m))  # every entry is written: the diagonal blocks, then each pair's two blocks
    arc = np.zeros(m)  # arc length along the current centre line, m
    for j in range(1, m):
        arc[j] = arc[j - 1] + _dist(x, j - 1, j)
    c_nl = 1.0 / (8.0 * math.pi * mu)
    for j in range(m):
        # half-edges on either side of node j; the node stands for a segment of length ell
        am = 0.5 * _dist(x, j - 1, j) if j > 0 else 0.0
        ap = 0.5 * _dist(x, j, j + 1) if j < m - 1 else 0.0
        ell = max(am + ap, 2.0 * delta)
        # Stokeslets of the node's own segment beyond the cutoff (zero on the paper's 2-delta grid)
        self_log = 0.0
        if am > delta:
            self_log += math.log(am / delta)
        if ap > delta:
            self_log += math.log(ap / delta)
        c_self = self_log / (8.0 * math.pi * mu * ell)
        c_perp = 1.0 / (4.0 * math.pi * mu * ell)
        for p in range(3):
            for k in range(3):
                kd = 1.0 if p == k else 0.0
                tt = t[j, p] * t[j, k]
                a[3 * j + p, 3 * j + k] = c_perp * (kd - tt) + c_self * (kd + tt)
        for i in range(j + 1, m):
            r0 = x[j, 0] - x[i, 0]
            r1 = x[j, 1] - x[i, 1]
            r2 = x[j, 2] - x[i, 2]
            d = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
            rh = (r0 / d, r1 / d, r2 / d)
            s = c_nl / d  # eqn (8): (I + r r) / (8 pi mu r)
            w = 0.0
            if near_radius > 0.0 and d < 10.0 / 3.0 * near_radius:
                w = near_field_weight(d, arc[i] - arc[j], near_radius)
            if w == 0.0:
                for p in range(3):
                    for k in range(3):
                        v = s * ((1.0 if p == k else 0.0) + rh[p] * rh[k])
                        a[3 * j + p, 3 * i + k] = v
                        a[3 * i + p, 3 * j + k] = v
            else:  # near field: blend the Stokeslet into the RPY tensor
                k_iso, k_rr = rpy_coefficients(d, near_radius, mu)
                c_iso = (1.0 - w) * s + w * k_iso
                c_rr = (1.0 - w) * s + w * k_rr
                for p in range(3):
                    for k in range(3):
                        v = c_iso * (1.0 if p == k else 0.0) + c_rr * rh[p] * rh[k]
                        a[3 * j + p, 3 * i + k] = v
                        a[3 * i + p, 3 * j + k] = v
    if smoothing > 0.0 and m >= 3:
        w = smoothing / (8.0 * math.pi * mu * 2.0 * delta) / 16.0
        # D2^T D2, D2 the second derivative along arc length times (2 delta)^2, so that on the
        # paper's uniform 2-delta grid its rows are the stencil (1, -2, 1). On a non-uniform grid
        # (the arm edge e1 is ~5x longer) it uses the actual spacings h-, h+. The end rows
        # reflect the grid (ghost node F_{-1} = F_1), so free ends cannot host rough modes either.
        ds2 = (2.0 * delta) ** 2
        for j in range(m):
            if j == 0:
                hp = _dist(x, 0, 1)
                idx = (0, 1, 1)
                st = (-2.0 * ds2 / (hp * hp), 2.0 * ds2 / (hp * hp), 0.0)
            elif j == m - 1:
                hm = _dist(x, m - 2, m - 1)
                idx = (m - 2, m - 1, m - 1)
                st = (2.0 * ds2 / (hm * hm), -2.0 * ds2 / (hm * hm), 0.0)
            else:
                hm = _dist(x, j - 1, j)
                hp = _dist(x, j, j + 1)
                c = 2.0 * ds2 / (hm + hp)
                idx = (j - 1, j, j + 1)
                st = (c / hm, -c / hm - c / hp, c / hp)
            for u in range(3):
                for v in range(3):
                    val = w * st[u] * st[v]
                    if val == 0.0:
                        continue
                    for k in range(3):
                        a[3 * idx[u] + k, 3 * idx[v] + k] += val
    return a


def mobility_for(x: np.ndarray, mu: float, delta: float, smoothing: float,
                 near_radius: float = 0.0) -> np.ndarray:
    """Convenience: tangents from x, then ``lsbt_mobility``. x: (M,3) m. Returns (3M,3M)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    return lsbt_mobility(x, node_tangents(x), mu, delta, smoothing, near_radius)
