"""How far each candidate turn of the rule planner misses its target: the (burst length x burst phase) grid of
``agents.turn_planner.RulePlanner.rule_plan``, compiled.

The formulas are the planner's (docs/planner.md; Huang & Jawed 2020, Sec. 3, the paper's rule): a candidate i
(map turn theta_i, direction psi_i, head displacement off_i) flown at the flagellum phase beta_j about the heading d
(``perpendicular_basis(d)`` = (e1, e2)) ends at

    after_ij = head + off_i0 d + off_i1 e_ref_j + off_i2 (d x e_ref_j),   e_ref_j = cos(beta_j) e1 + sin(beta_j) e2

(``turn_ends``) heading along

    h_ij = cos(theta_i) d + sin(theta_i) (cos(beta_j + psi_i) e1 + sin(beta_j + psi_i) e2),

and misses the target by the distance of the target from the ray after_ij + s h_ij (s >= 0), or, with the target
behind (along <= 0), by its distance plus ``behind_penalty`` (``_line_miss``). Numba, one pass over the grid: the
NumPy version of the same formulas (``turn_ends``, ``_line_miss``) costs ~0.4 ms per plan, which the turn-level
surrogate (``FlagellumTurn-surrogate-v0``, 10^4 decisions/s) cannot afford; tests/agents/test_surrogate_env.py
checks the two agree.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, fastmath=False)
def candidate_miss(head: np.ndarray, d: np.ndarray, e1: np.ndarray, e2: np.ndarray, theta: np.ndarray,
                   psi: np.ndarray, off: np.ndarray, beta: np.ndarray, target: np.ndarray,
                   behind_penalty: float) -> np.ndarray:
    """Miss (m) of each candidate, (T, B): theta, psi (T,) rad; off (T, 3) m; beta (B,) rad; head, d, e1, e2,
    target (3,) (m, unit, unit, unit, m)."""
    n_t, n_b = theta.shape[0], beta.shape[0]
    out = np.empty((n_t, n_b))
    cb, sb = np.cos(beta), np.sin(beta)
    for i in range(n_t):
        ct, st = math.cos(theta[i]), math.sin(theta[i])
        cp, sp = math.cos(psi[i]), math.sin(psi[i])
        o0, o1, o2 = off[i, 0], off[i, 1], off[i, 2]
        for j in range(n_b):
            # e_ref and d x e_ref (= -sin(beta) e1 + cos(beta) e2 for a right-handed (e1, e2, d))
            rx = cb[j] * e1[0] + sb[j] * e2[0]
            ry = cb[j] * e1[1] + sb[j] * e2[1]
            rz = cb[j] * e1[2] + sb[j] * e2[2]
            px = d[1] * rz - d[2] * ry
            py = d[2] * rx - d[0] * rz
            pz = d[0] * ry - d[1] * rx
            # cos/sin(beta + psi) by the addition theorem
            ca = cb[j] * cp - sb[j] * sp
            sa = sb[j] * cp + cb[j] * sp
            hx = ct * d[0] + st * (ca * e1[0] + sa * e2[0])
            hy = ct * d[1] + st * (ca * e1[1] + sa * e2[1])
            hz = ct * d[2] + st * (ca * e1[2] + sa * e2[2])
            qx = target[0] - (head[0] + o0 * d[0] + o1 * rx + o2 * px)
            qy = target[1] - (head[1] + o0 * d[1] + o1 * ry + o2 * py)
            qz = target[2] - (head[2] + o0 * d[2] + o1 * rz + o2 * pz)
            along = qx * hx + qy * hy + qz * hz
            if along > 0.0:
                lx, ly, lz = qx - along * hx, qy - along * hy, qz - along * hz
                out[i, j] = math.sqrt(lx * lx + ly * ly + lz * lz)
            else:
                out[i, j] = math.sqrt(qx * qx + qy * qy + qz * qz) + behind_penalty
    return out


@njit(cache=True)
def _first_negative(a: float, b: float, c: float, lo: float, hi: float) -> float:
    """The first x in [lo, hi] with a x^2 + b x + c <= 0 (a >= 0), or inf."""
    if lo > hi:
        return math.inf
    if (a * lo + b) * lo + c <= 0.0:
        return lo
    if a <= 1e-15:
        if b < 0.0:
            x = -c / b
            return x if lo <= x <= hi else math.inf
        return math.inf
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return math.inf
    r1 = (-b - math.sqrt(disc)) / (2.0 * a)
    r2 = (-b + math.sqrt(disc)) / (2.0 * a)
    if lo <= r1 <= hi:
        return r1
    if r1 < lo <= r2:
        return lo
    return math.inf


@njit(cache=True, fastmath=False)
def first_improving_distance(head: np.ndarray, d: np.ndarray, e1: np.ndarray, e2: np.ndarray, theta: np.ndarray,
                             psi: np.ndarray, off: np.ndarray, beta: np.ndarray, target: np.ndarray,
                             behind_penalty: float, threshold: float, lo: float, hi: float) -> float:
    """How far (m) the head can swim straight along ``d`` from ``head`` before some candidate turn's miss
    (``candidate_miss``, the same candidates) drops to ``threshold`` (m) or below: the first x in [lo, hi], inf if
    none. Moving the head by x d moves every candidate's start by x d and keeps its heading h, so its lateral miss
    squared is a quadratic in x, (1 - (d.h)^2) x^2 + 2 ((q.h)(d.h) - q.d) x + |q|^2 - (q.h)^2 with q the target
    from the candidate's end, valid while the target is ahead of it (q.h - x d.h > 0), and the behind miss
    |q - x d| + behind_penalty beyond. The rule planner flies a turn at the first control step where its best
    miss is ``improvement_m`` below swimming on (``pick_turn``), so this is when it plans next on a straight
    stretch along which swimming on keeps its miss (the target ahead and off course)."""
    n_t, n_b = theta.shape[0], beta.shape[0]
    best = math.inf
    cb, sb = np.cos(beta), np.sin(beta)
    for i in range(n_t):
        ct, st = math.cos(theta[i]), math.sin(theta[i])
        cp, sp = math.cos(psi[i]), math.sin(psi[i])
        o0, o1, o2 = off[i, 0], off[i, 1], off[i, 2]
        for j in range(n_b):
            rx = cb[j] * e1[0] + sb[j] * e2[0]
            ry = cb[j] * e1[1] + sb[j] * e2[1]
            rz = cb[j] * e1[2] + sb[j] * e2[2]
            px = d[1] * rz - d[2] * ry
            py = d[2] * rx - d[0] * rz
            pz = d[0] * ry - d[1] * rx
            ca = cb[j] * cp - sb[j] * sp
            sa = sb[j] * cp + cb[j] * sp
            hx = ct * d[0] + st * (ca * e1[0] + sa * e2[0])
            hy = ct * d[1] + st * (ca * e1[1] + sa * e2[1])
            hz = ct * d[2] + st * (ca * e1[2] + sa * e2[2])
            qx = target[0] - (head[0] + o0 * d[0] + o1 * rx + o2 * px)
            qy = target[1] - (head[1] + o0 * d[1] + o1 * ry + o2 * py)
            qz = target[2] - (head[2] + o0 * d[2] + o1 * rz + o2 * pz)
            qq = qx * qx + qy * qy + qz * qz
            qd = qx * d[0] + qy * d[1] + qz * d[2]
            qh = qx * hx + qy * hy + qz * hz
            dh = d[0] * hx + d[1] * hy + d[2] * hz
            # the target ahead of the candidate's end: x < qh / dh (dh > 0) or x > qh / dh (dh < 0)
            a_lo, a_hi = lo, hi
            if dh > 1e-15:
                a_hi = min(hi, qh / dh)
            elif dh < -1e-15:
                a_lo = max(lo, qh / dh)
            elif qh <= 0.0:
                a_hi = -math.inf
            if threshold > 0.0:
                x = _first_negative(1.0 - dh * dh, 2.0 * (qh * dh - qd), qq - qh * qh - threshold * threshold,
                                    a_lo, a_hi)
                if x < best:
                    best = x
            rest = threshold - behind_penalty
            if rest > 0.0:
                # behind: the complement of the interval above within [lo, hi]
                if dh > 1e-15:
                    x = _first_negative(1.0, -2.0 * qd, qq - rest * rest, max(lo, qh / dh), hi)
                elif dh < -1e-15:
                    x = _first_negative(1.0, -2.0 * qd, qq - rest * rest, lo, min(hi, qh / dh))
                else:
                    x = _first_negative(1.0, -2.0 * qd, qq - rest * rest, lo, hi) if qh <= 0.0 else math.inf
                if x < best:
                    best = x
    return best


@njit(cache=True, fastmath=False)
def first_improving_sample(head: np.ndarray, d: np.ndarray, e1: np.ndarray, e2: np.ndarray, theta: np.ndarray,
                           psi: np.ndarray, off: np.ndarray, beta: np.ndarray, target: np.ndarray,
                           behind_penalty: float, improvement: float, step_m: float, n_max: int) -> int:
    """The first k in 1..n_max at which, with the head moved to head + k step_m d, the best candidate's miss
    (``candidate_miss``) is at most swimming on's miss (the same ray miss from the moved head along d) less
    ``improvement`` (m); -1 if none. The sampled form of ``first_improving_distance`` for stretches along which
    swimming on's miss changes (the target behind)."""
    miss = np.empty((theta.shape[0], beta.shape[0]))
    moved = np.empty(3)
    for k in range(1, n_max + 1):
        for c in range(3):
            moved[c] = head[c] + k * step_m * d[c]
        qx, qy, qz = target[0] - moved[0], target[1] - moved[1], target[2] - moved[2]
        along = qx * d[0] + qy * d[1] + qz * d[2]
        if along > 0.0:
            lx, ly, lz = qx - along * d[0], qy - along * d[1], qz - along * d[2]
            straight = math.sqrt(lx * lx + ly * ly + lz * lz)
        else:
            straight = math.sqrt(qx * qx + qy * qy + qz * qz) + behind_penalty
        miss = candidate_miss(moved, d, e1, e2, theta, psi, off, beta, target, behind_penalty)
        if miss.min() <= straight - improvement:
            return k
    return -1
