"""Head-rod and rod-rod contact as smooth penalty energies inside the implicit step.

The paper has no contact model: a buckled flagellum of the paper's swimmer can sweep through
the head and through itself. Following the idea of implicit penalty contact for discrete
elastic rods (IMC: Tong, Choi, Jawed, "A fully implicit method for robust frictional contact
handling in elastic rods", Extreme Mech. Lett. 2023; DisMech), contact is an energy of the
node positions that enters eqn (6) like the elastic energies: its gradient joins the residual
and its Hessian the Newton Jacobian, so contact is resolved inside the same implicit solve.
The energy here is our own (frictionless):

* rod-rod: every pair of *non-adjacent* edges (i, j) keeps its centre-line distance
  d_ij = min |x_i + s e^i - x_j - t e^j| (segment-segment, s, t in [0, 1]) above 2 r0;
* rod-head: every flagellum edge apart from those attached to the head (e^0 lies inside the
  head, e^1 starts on its surface) keeps its distance to the head centre above b + r0.

For a gap g = d - d_min each active pair stores the C2 penalty

    E(g) = k eps / 3 (1 - g / eps)^3   for g < eps,   0 otherwise,

so the repulsive force is k (1 - g/eps)^2: zero at g = eps (the activation distance), k at
contact (g = 0) and 4 k at a penetration of eps. A pair pressed together by a force F settles
at g = eps (1 - sqrt(F/k)): no overlap while F < k, an overlap smaller than the margin eps while
F < 4 k (the stated tolerance: g > -eps). k (N, ``contact_stiffness``, default 0.1 N) is well above
the forces that press a buckled rod together (measured gaps: docs/contact_check.json,
docs/stability.md).

Derivatives of the distance: with D = d^2 = min_u f(x, u), f = |w|^2 and u the closest-point
parameters, the envelope theorem gives grad D = f_x at u*, and (u* interior)
hess D = f_xx - f_xu f_uu^{-1} f_ux over the parameters not clamped to 0 or 1; a clamped
parameter is a constant. Pairs of edges are "adjacent" when they share a node or when the rest
arc length between them is below pi r0 (the tightest fold of a rod of radius r0, a half circle of
radius r0, brings such points 2 r0 close: they cannot be in contact).

A sweep-and-prune broad phase along the longest axis of the rod's bounding box finds candidate
pairs; a scene with no near pair does no narrow-phase work.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


@njit(cache=True)
def _closest_params(a, b, c, d):
    """Closest-point parameters (s, t) of segments a-b and c-d, and whether each is interior.

    Ericson, Real-Time Collision Detection (2005), 5.1.9, with a parallel-segment branch.
    """
    d1 = b - a
    d2 = d - c
    r = a - c
    return _closest_from_dots(d1 @ d1, d2 @ d2, d2 @ r, d1 @ r, d1 @ d2)


@njit(cache=True)
def _closest_from_dots(aa, ee, f, cc, bb):
    """``_closest_params`` from the dot products of d1 = b - a, d2 = d - c, r = a - c: aa = d1.d1, ee = d2.d2,
    f = d2.r, cc = d1.r, bb = d1.d2."""
    den = aa * ee - bb * bb
    if den > 1e-12 * aa * ee:
        s = (bb * f - cc * ee) / den
        s = min(max(s, 0.0), 1.0)
    else:  # parallel: any s works, take the one for t = 0 (projection of c on a-b)
        s = min(max(-cc / aa, 0.0), 1.0)
    t = (bb * s + f) / ee
    if t < 0.0:
        t = 0.0
        s = min(max(-cc / aa, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((bb - cc) / aa, 0.0), 1.0)
    return s, t


@njit(cache=True)
def _sq_distance_derivatives(a, b, c, d, s, t, free_s, free_t, grad, hess):
    """D = |w|^2 at (s, t), w = (1-s) a + s b - (1-t) c - t d; grad (12,), hess (12,12) in place.

    DOF order a, b, c, d (3 each). Interior (free) parameters are eliminated through the Schur
    complement f_xx - f_xu f_uu^-1 f_ux (envelope theorem).
    """
    w = (1.0 - s) * a + s * b - (1.0 - t) * c - t * d
    alpha = np.array([1.0 - s, s, -(1.0 - t), -t])
    for p in range(4):
        for k in range(3):
            grad[3 * p + k] = 2.0 * alpha[p] * w[k]
    for p in range(4):
        for q in range(4):
            v = 2.0 * alpha[p] * alpha[q]
            for k in range(3):
                for m in range(3):
                    hess[3 * p + k, 3 * q + m] = v if k == m else 0.0
    nfree = (1 if free_s else 0) + (1 if free_t else 0)
    if nfree == 0:
        return w @ w
    u1 = b - a  # dw/ds
    u2 = c - d  # dw/dt
    # f_xu columns: df_x/ds and df_x/dt
    fxs = np.zeros(12)
    fxt = np.zeros(12)
    for k in range(3):
        fxs[0 + k] = -2.0 * w[k] + 2.0 * (1.0 - s) * u1[k]
        fxs[3 + k] = 2.0 * w[k] + 2.0 * s * u1[k]
        fxs[6 + k] = -2.0 * (1.0 - t) * u1[k]
        fxs[9 + k] = -2.0 * t * u1[k]
        fxt[0 + k] = 2.0 * (1.0 - s) * u2[k]
        fxt[3 + k] = 2.0 * s * u2[k]
        fxt[6 + k] = 2.0 * w[k] - 2.0 * (1.0 - t) * u2[k]
        fxt[9 + k] = -2.0 * w[k] - 2.0 * t * u2[k]
    fss = 2.0 * (u1 @ u1)
    ftt = 2.0 * (u2 @ u2)
    fst = 2.0 * (u1 @ u2)
    if nfree == 2:
        det = fss * ftt - fst * fst
        if det <= 1e-12 * fss * ftt:  # parallel: the distance does not depend on s; keep t only
            free_s = False
            nfree = 1
        else:
            i00 = ftt / det
            i11 = fss / det
            i01 = -fst / det
            for p in range(12):
                for q in range(12):
                    hess[p, q] -= (fxs[p] * (i00 * fxs[q] + i01 * fxt[q])
                                   + fxt[p] * (i01 * fxs[q] + i11 * fxt[q]))
            return w @ w
    if free_s:
        for p in range(12):
            for q in range(12):
                hess[p, q] -= fxs[p] * fxs[q] / fss
    else:
        for p in range(12):
            for q in range(12):
                hess[p, q] -= fxt[p] * fxt[q] / ftt
    return w @ w


@njit(cache=True)
def _penalty(g, eps, k):
    """(E, dE/dg, d2E/dg2) of the C2 penalty k eps/3 (1 - g/eps)^3 on g < eps."""
    if g >= eps:
        return 0.0, 0.0, 0.0
    y = 1.0 - g / eps
    return k * eps / 3.0 * y * y * y, -k * y * y, 2.0 * k * y / eps


@njit(cache=True)
def _pair_energy(a, b, c, d, s, t, free_s, free_t, dmin, eps, k, grad, hess):
    """Penalty energy of one pair; its gradient (12,) and Hessian (12,12) w.r.t. a, b, c, d."""
    D = _sq_distance_derivatives(a, b, c, d, s, t, free_s, free_t, grad, hess)
    dist = math.sqrt(max(D, 1e-300))
    E, dE, d2E = _penalty(dist - dmin, eps, k)
    # d = sqrt(D): grad d = grad D / 2d; hess d = hess D / 2d - grad D grad D^T / 4 d^3
    for p in range(12):
        for q in range(12):
            hess[p, q] = (d2E * grad[p] * grad[q] / (4.0 * D)
                          + dE * (hess[p, q] / (2.0 * dist) - grad[p] * grad[q] / (4.0 * D * dist)))
    for p in range(12):
        grad[p] = dE * grad[p] / (2.0 * dist)
    return E


@njit(cache=True)
def _segment_aabb_overlap(x, i, j, pad):
    for k in range(3):
        lo_i = min(x[i, k], x[i + 1, k])
        hi_i = max(x[i, k], x[i + 1, k])
        lo_j = min(x[j, k], x[j + 1, k])
        hi_j = max(x[j, k], x[j + 1, k])
        if lo_i - pad > hi_j or lo_j - pad > hi_i:
            return False
    return True


@njit(cache=True)
def candidate_pairs(x: np.ndarray, arc: np.ndarray, first_edge: int, min_arc_gap: float,
                    reach: float) -> np.ndarray:
    """Broad phase: edge pairs (i, j), i < j, whose padded bounding boxes overlap. (P, 2) int64.

    x: (n,3) nodes, m; arc: (n,) rest arc length at each node, m; edges from ``first_edge`` on
    take part; pairs closer than ``min_arc_gap`` along the rod are adjacent (skipped); reach, m:
    boxes are padded by this (the contact distance plus the activation margin).
    Sweep and prune along the axis of the largest extent of the rod.
    """
    n = x.shape[0]
    ne = n - 1 - first_edge
    if ne < 2:
        return np.zeros((0, 2), dtype=np.int64)
    ext = np.zeros(3)
    for k in range(3):
        ext[k] = x[:, k].max() - x[:, k].min()
    ax = int(np.argmax(ext))
    lo = np.empty(ne)
    hi = np.empty(ne)
    for m in range(ne):
        e = first_edge + m
        lo[m] = min(x[e, ax], x[e + 1, ax]) - reach
        hi[m] = max(x[e, ax], x[e + 1, ax])
    order = np.argsort(lo)
    out = np.empty((16 * ne, 2), dtype=np.int64)
    cnt = 0
    for a in range(ne):
        ea = order[a]
        for bidx in range(a + 1, ne):
            eb = order[bidx]
            if lo[eb] > hi[ea]:
                break
            i = first_edge + min(ea, eb)
            j = first_edge + max(ea, eb)
            if arc[j] - arc[i + 1] < min_arc_gap:
                continue
            if not _segment_aabb_overlap(x, i, j, reach):
                continue
            if cnt == out.shape[0]:
                bigger = np.empty((2 * out.shape[0], 2), dtype=np.int64)
                bigger[:cnt] = out[:cnt]
                out = bigger
            out[cnt, 0] = i
            out[cnt, 1] = j
            cnt += 1
    return out[:cnt].copy()


@njit(cache=True)
def within_reach(x: np.ndarray, pairs: np.ndarray, reach: float) -> np.ndarray:
    """The pairs of ``pairs`` whose centre lines are closer than ``reach`` (m). (P',2) int64."""
    keep = np.zeros(pairs.shape[0], dtype=np.bool_)
    d1, d2, r, w = np.empty(3), np.empty(3), np.empty(3), np.empty(3)  # ``_pair_sq_distance``'s buffers
    reach2 = reach * reach
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        if _boxes_beyond(x, i, j, reach2):
            continue
        keep[p] = _pair_sq_distance(x, i, j, d1, d2, r, w)[2] < reach2
    return pairs[keep]


@njit(cache=True)
def _boxes_beyond(x: np.ndarray, i: int, j: int, reach2: float) -> bool:
    """Whether the bounding boxes of edges i and j of x (n, 3) are farther apart than sqrt(reach2) (m) by a
    relative 1e-6 of reach2. The distance between the boxes is a lower bound of the edges' distance, and the margin
    is far above the rounding of either computation: such a pair is out of reach, and the closest-point test
    (``_pair_sq_distance``) would say so too."""
    g2 = 0.0
    for k in range(3):
        g = max(min(x[i, k], x[i + 1, k]) - max(x[j, k], x[j + 1, k]),
                min(x[j, k], x[j + 1, k]) - max(x[i, k], x[i + 1, k]), 0.0)
        g2 += g * g
    return g2 > reach2 * (1.0 + 1e-6)


@njit(cache=True)
def _pair_sq_distance(x: np.ndarray, i: int, j: int, d1: np.ndarray, d2: np.ndarray, r: np.ndarray,
                      w: np.ndarray) -> tuple[float, float, float]:
    """(s, t, |w|^2 m^2) of edges i and j of x (n, 3): ``_closest_params`` of x_i-x_{i+1} and x_j-x_{j+1} and the
    squared distance of their closest points, w = (1-s) x_i + s x_{i+1} - (1-t) x_j - t x_{j+1}, with the same
    arithmetic in the buffers d1, d2, r, w (3,) (no temporaries)."""
    for k in range(3):
        d1[k] = x[i + 1, k] - x[i, k]
        d2[k] = x[j + 1, k] - x[j, k]
        r[k] = x[i, k] - x[j, k]
    s, t = _closest_from_dots(d1 @ d1, d2 @ d2, d2 @ r, d1 @ r, d1 @ d2)
    for k in range(3):
        w[k] = (1.0 - s) * x[i, k] + s * x[i + 1, k] - (1.0 - t) * x[j, k] - t * x[j + 1, k]
    return s, t, w @ w


@njit(cache=True)
def _head_sq_distance(x: np.ndarray, i: int, e: np.ndarray, hc: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    """(t, |w|^2 m^2) of edge i of x (n, 3) and the head centre x[0]: the clamped projection parameter
    t = (x_0 - x_i).e / e.e, e = x_{i+1} - x_i, and w = x_0 - (1-t) x_i - t x_{i+1}, with the arithmetic of the
    array expressions of ``contact_kernel`` in the buffers e, hc, w (3,) (no temporaries)."""
    for k in range(3):
        e[k] = x[i + 1, k] - x[i, k]
        hc[k] = x[0, k] - x[i, k]
    t = min(max(hc @ e / (e @ e), 0.0), 1.0)
    for k in range(3):
        w[k] = x[0, k] - (1.0 - t) * x[i, k] - t * x[i + 1, k]
    return t, w @ w


@njit(cache=True)
def head_candidates(x: np.ndarray, first_head_edge: int, reach: float) -> np.ndarray:
    """Broad phase for the head: edges from ``first_head_edge`` on whose bounding box comes
    within ``reach`` (m) of the head centre x[0]. (H,) int64."""
    out = np.empty(x.shape[0], dtype=np.int64)
    cnt = 0
    for i in range(first_head_edge, x.shape[0] - 1):
        near = True
        for k in range(3):
            lo = min(x[i, k], x[i + 1, k]) - reach
            hi = max(x[i, k], x[i + 1, k]) + reach
            if x[0, k] < lo or x[0, k] > hi:
                near = False
                break
        if near:
            out[cnt] = i
            cnt += 1
    return out[:cnt].copy()


@njit(cache=True)
def contact_kernel(x: np.ndarray, pairs: np.ndarray, head_radius: float, head_edges: np.ndarray,
                   r0: float, eps: float, k: float):
    """Contact energy, gradient and local Hessians.

    x: (n,3) nodes, m (x[0] the head centre when head_radius > 0); pairs: (P,2) candidate edge
    pairs; head_edges: (H,) candidate edges for the head. eps: activation margin, m;
    k: contact force at zero gap, N. Returns (E [J], grad (3n,) [N], nodes (A,4) int64,
    blocks (A,12,12) [N/m]) over the A active interactions; a head interaction lists its node
    as (0, 0, i, i+1) with the head centre as a point (its block is zero in the second slot).
    """
    n = x.shape[0]
    grad = np.zeros(3 * n)
    npairs = pairs.shape[0]
    nmax = npairs + head_edges.shape[0]
    nodes = np.empty((nmax, 4), dtype=np.int64)
    blocks = np.empty((nmax, 12, 12))
    g12 = np.empty(12)
    h12 = np.empty((12, 12))
    b1, b2, b3, b4 = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    E = 0.0
    cnt = 0
    dmin_rr = 2.0 * r0
    for p in range(npairs):
        i = pairs[p, 0]
        j = pairs[p, 1]
        if _boxes_beyond(x, i, j, (dmin_rr + eps) ** 2):  # out of reach: skipped as the test below would
            continue
        s, t, ww = _pair_sq_distance(x, i, j, b1, b2, b3, b4)
        if ww >= (dmin_rr + eps) ** 2:
            continue
        a, b, c, d = x[i], x[i + 1], x[j], x[j + 1]
        E += _pair_energy(a, b, c, d, s, t, 0.0 < s < 1.0, 0.0 < t < 1.0, dmin_rr, eps, k, g12, h12)
        idx = (i, i + 1, j, j + 1)
        for q in range(4):
            nodes[cnt, q] = idx[q]
            for m in range(3):
                grad[3 * idx[q] + m] += g12[3 * q + m]
        blocks[cnt] = h12
        cnt += 1
    if head_radius > 0.0:
        dmin_h = head_radius + r0
        h0 = x[0]
        for i in head_edges:
            t, ww = _head_sq_distance(x, i, b1, b2, b3)
            if ww >= (dmin_h + eps) ** 2:
                continue
            c, d = x[i], x[i + 1]
            E += _pair_energy(h0, h0, c, d, 0.0, t, False, 0.0 < t < 1.0, dmin_h, eps, k, g12, h12)
            # fold the two copies of the head point (slots a and b) into slot a
            for m in range(3):
                g12[m] += g12[3 + m]
                g12[3 + m] = 0.0
            for r in range(12):
                for m in range(3):
                    h12[r, m] += h12[r, 3 + m]
                    h12[r, 3 + m] = 0.0
            for r in range(3):
                for m in range(12):
                    h12[r, m] += h12[3 + r, m]
                    h12[3 + r, m] = 0.0
            idx = (0, 0, i, i + 1)
            for q in range(4):
                for m in range(3):
                    grad[3 * idx[q] + m] += g12[3 * q + m]
            for q in range(4):
                nodes[cnt, q] = idx[q]
            blocks[cnt] = h12
            cnt += 1
    return E, grad, nodes[:cnt].copy(), blocks[:cnt].copy()


@njit(cache=True)
def add_blocks_to_dense(J: np.ndarray, nodes: np.ndarray, blocks: np.ndarray, stride: int) -> None:
    """J[stride*node + k, stride*node' + m] += block entries (stride 4 for the DOF layout, 3 for x)."""
    for a in range(nodes.shape[0]):
        for p in range(4):
            for q in range(4):
                ip = nodes[a, p]
                iq = nodes[a, q]
                for k in range(3):
                    for m in range(3):
                        v = blocks[a, 3 * p + k, 3 * q + m]
                        if v != 0.0:
                            J[stride * ip + k, stride * iq + m] += v


class ContactParams(NamedTuple):
    """What the compiled contact kernels take of a ``ContactModel`` (SI)."""

    arc: np.ndarray  # (n,) arc length of each node along the rest rod from the first node, m
    first_rod_edge: int  # the first edge taking part in rod-rod contact
    min_arc_gap: float  # m: edges closer than this along the rod are never a pair
    head_radius: float  # b, m (0: no head)
    first_head_edge: int  # the first edge tested against the head
    r0: float  # rod radius, m
    eps: float  # activation margin, m
    stiffness: float  # k: contact force at zero gap, N


class ContactState(NamedTuple):
    """The contact broad phase a step's iterates use (``implicit_residual.contact_state_at``)."""

    q: np.ndarray  # (ndof,) the configuration of the broad phase
    pad: float  # m: how far the boxes were padded
    pairs: np.ndarray  # (P, 2) int64 candidate edge pairs
    head_edges: np.ndarray  # (H,) int64 candidate edges for the head
    none: bool  # no candidates at all


@njit(cache=True)
def contact_broad_phase(x: np.ndarray, model: ContactParams, pad: float) -> tuple[np.ndarray, np.ndarray]:
    """The broad phase: (rod-rod candidate pairs (P, 2), head candidate edges (H,)) at x (n, 3), m, with boxes
    padded by the contact distance, the activation margin and ``pad`` (m). model = ``ContactModel.model``."""
    b, r0, eps = model.head_radius, model.r0, model.eps
    reach = 2.0 * r0 + eps + pad
    pairs = within_reach(x, candidate_pairs(x, model.arc, model.first_rod_edge, model.min_arc_gap, reach), reach)
    if b > 0.0:
        head = head_candidates(x, model.first_head_edge, b + r0 + eps + pad)
    else:
        head = np.zeros(0, dtype=np.int64)
    return pairs, head


#: what the compiled kernels take for a scene without contact: no pairs, no head edges, a placeholder model
NO_PAIRS = np.zeros((0, 2), dtype=np.int64)
NO_EDGES = np.zeros(0, dtype=np.int64)
NO_CONTACT_MODEL = ContactParams(np.zeros(1), 0, 0.0, 0.0, 0, 0.0, 0.0, 0.0)


class ContactModel:
    """Contact of one swimmer: which edges take part, distances, stiffness (SI).

    The broad phase runs once per time step (``broad_phase``, padded by how far the nodes may
    move within the step); the narrow phase (``evaluate``) then only looks at its candidates,
    and is skipped altogether when there are none (``Candidates.empty``).
    """

    def __init__(self, rest_edge_lengths: np.ndarray, rod_radius: float, head_radius: float,
                 margin: float, stiffness: float) -> None:
        self.r0 = float(rod_radius)
        self.b = float(head_radius)
        self.eps = float(margin) * self.r0
        self.k = float(stiffness)
        self.arc = np.concatenate([[0.0], np.cumsum(rest_edge_lengths)])
        has_head = self.b > 0.0
        # e0 lies in the head: it takes no part in rod-rod contact (the head's own test covers it)
        self.first_rod_edge = 1 if has_head else 0
        self.first_head_edge = 2  # e0 and e1 are attached to the head
        self.min_arc_gap = math.pi * self.r0

    @property
    def model(self) -> ContactParams:
        """What the compiled kernels take of this model."""
        return ContactParams(arc=self.arc, first_rod_edge=self.first_rod_edge, min_arc_gap=self.min_arc_gap,
                             head_radius=self.b, first_head_edge=self.first_head_edge, r0=self.r0, eps=self.eps,
                             stiffness=self.k)

    def broad_phase(self, x: np.ndarray, pad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(rod-rod candidate pairs (P,2), head candidate edges (H,)) at x (n,3), m, with boxes
        padded by the contact distance, the activation margin and ``pad`` (m)."""
        return contact_broad_phase(np.ascontiguousarray(x), self.model, pad)

    def evaluate(self, x: np.ndarray, candidates: tuple[np.ndarray, np.ndarray] | None = None):
        """(E J, grad (3n,) N, nodes (A,4), Hessian blocks (A,12,12) N/m) at x (n,3), m."""
        x = np.ascontiguousarray(x)
        pairs, head = candidates if candidates is not None else self.broad_phase(x)
        return contact_kernel(x, pairs, self.b, head, self.r0, self.eps, self.k)

    def gaps(self, x: np.ndarray) -> tuple[float, float]:
        """(smallest rod-rod gap d - 2 r0 over non-adjacent edges, smallest head gap d - b - r0), m.

        Brute force over all pairs (a diagnostic, not used in the step); inf where not defined.
        """
        x = np.ascontiguousarray(x)
        all_pairs = candidate_pairs(x, self.arc, self.first_rod_edge, self.min_arc_gap, np.inf)
        return min_gaps(x, all_pairs, self.b, self.first_head_edge, self.r0)


@njit(cache=True)
def min_gaps(x, pairs, head_radius, first_head_edge, r0):
    """Smallest rod-rod and rod-head gaps (see ``ContactModel.gaps``)."""
    g_rr = np.inf
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        a, b, c, d = x[i], x[i + 1], x[j], x[j + 1]
        s, t = _closest_params(a, b, c, d)
        w = (1.0 - s) * a + s * b - (1.0 - t) * c - t * d
        g_rr = min(g_rr, math.sqrt(w @ w) - 2.0 * r0)
    g_h = np.inf
    if head_radius > 0.0:
        for i in range(first_head_edge, x.shape[0] - 1):
            c, d = x[i], x[i + 1]
            e = d - c
            t = min(max((x[0] - c) @ e / (e @ e), 0.0), 1.0)
            w = x[0] - (1.0 - t) * c - t * d
            g_h = min(g_h, math.sqrt(w @ w) - head_radius - r0)
    return g_rr, g_h
