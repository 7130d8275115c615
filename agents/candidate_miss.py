"""How far each candidate turn of the rule planner misses its target: the (burst length x burst phase) grid of
``agents.turn_planner.RulePlanner.rule_plan``, compiled.

The formulas are the planner's (docs/planner.md; Huang & Jawed 2020, Sec. 3, the paper's rule): a candidate i
(map turn theta_i, direction psi_i, head displacement off_i) flown at the flagellum phase beta_j about the heading d
(``perpendicular_basis(d)`` = (e1, e2), right-handed with d) ends at

    after_ij = head + off_i0 d + off_i1 e_ref_j + off_i2 (d x e_ref_j),   e_ref_j = cos(beta_j) e1 + sin(beta_j) e2

(``turn_ends``) heading along

    h_ij = cos(theta_i) d + sin(theta_i) (cos(beta_j + psi_i) e1 + sin(beta_j + psi_i) e2),

and misses the target by the distance of the target from the ray after_ij + s h_ij (s >= 0), or, with the target
behind (along <= 0), by its distance plus ``behind_penalty`` (``line_miss``, one line each). In the frame (d, e1, e2) neither the
end's offset nor the heading depends on d (d x e_ref = cos(beta) e2 - sin(beta) e1), so ``candidate_frames``
tabulates them once per candidate set and each plan only rotates the target into that frame. Numba: the world-frame
form (``agents.turn_planner.candidate_misses``: ``turn_ends`` and the lines' misses) costs ~0.4 ms per plan, which the
turn-level surrogate (``FlagellumTurn-surrogate-v0``) cannot afford; tests/agents/test_surrogate_env.py checks that the
two agree.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from agents.turn_geometry import angle_of, norm3, unit_basis, wrap_angle
from physics.linalg.vec3 import dot3, rowdot3, rownorm3


@njit(cache=True)
def candidate_frames(theta: np.ndarray, psi: np.ndarray, off: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """(T, B, 6): each candidate's end offset from the head (m) and its unit heading, both in the frame
    (d, e1, e2); theta, psi (T,) rad, off (T, 3) m, beta (B,) rad."""
    n_t, n_b = theta.shape[0], beta.shape[0]
    out = np.empty((n_t, n_b, 6))
    for i in range(n_t):
        ct, st = math.cos(theta[i]), math.sin(theta[i])
        for j in range(n_b):
            cb, sb = math.cos(beta[j]), math.sin(beta[j])
            out[i, j, 0] = off[i, 0]
            out[i, j, 1] = off[i, 1] * cb - off[i, 2] * sb
            out[i, j, 2] = off[i, 1] * sb + off[i, 2] * cb
            out[i, j, 3] = ct
            out[i, j, 4] = st * math.cos(beta[j] + psi[i])
            out[i, j, 5] = st * math.sin(beta[j] + psi[i])
    return out


@njit(cache=True)
def candidate_miss(frames: np.ndarray, q0: float, q1: float, q2: float, behind_penalty: float) -> np.ndarray:
    """Miss (m) of each candidate, (T, B): ``frames`` from ``candidate_frames``; (q0, q1, q2) the target minus the
    head in the frame (d, e1, e2), m."""
    out = np.empty((frames.shape[0], frames.shape[1]))
    _candidate_miss_into(frames, q0, q1, q2, behind_penalty, out)
    return out


@njit(cache=True)
def _candidate_miss_into(frames: np.ndarray, q0: float, q1: float, q2: float, behind_penalty: float,
                         out: np.ndarray) -> None:
    """``candidate_miss`` written to ``out`` (T, B)."""
    for i in range(frames.shape[0]):
        for j in range(frames.shape[1]):
            out[i, j] = _miss(frames, i, j, q0, q1, q2, behind_penalty)


@njit(cache=True)
def _miss(frames: np.ndarray, i: int, j: int, q0: float, q1: float, q2: float, behind_penalty: float) -> float:
    """One candidate's miss (m): ``frames[i, j]`` (6,) its row of ``candidate_frames``, (q0, q1, q2) the target
    (``candidate_miss``). (Elements, not a row view: a view handed to a call costs reference counting per candidate.)"""
    f0, f1, f2, f3, f4, f5 = (frames[i, j, 0], frames[i, j, 1], frames[i, j, 2], frames[i, j, 3], frames[i, j, 4],
                              frames[i, j, 5])
    r0, r1, r2 = q0 - f0, q1 - f1, q2 - f2
    along = r0 * f3 + r1 * f4 + r2 * f5
    if along > 0.0:
        l0, l1, l2 = r0 - along * f3, r1 - along * f4, r2 - along * f5
        return math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    return math.sqrt(r0 * r0 + r1 * r1 + r2 * r2) + behind_penalty


@njit(cache=True)
def local_target(head: np.ndarray, d: np.ndarray, e1: np.ndarray, e2: np.ndarray, target: np.ndarray
                 ) -> tuple[float, float, float]:
    """The target minus the head in the frame (d, e1, e2), m; all (3,) float64."""
    q = target - head
    return dot3(q, d), dot3(q, e1), dot3(q, e2)


@njit(cache=True)
def line_miss(starts: np.ndarray, directions: np.ndarray, target: np.ndarray, behind_penalty: float) -> np.ndarray:
    """How far the straight lines starts[i] + s directions[i] (s >= 0) pass from ``target``, (k,) m: the target's
    distance from the line, or, with the target behind the start, its distance plus ``behind_penalty`` (m). starts,
    directions (k, 3), target (3,), float64; rounded as the NumPy expression with ``einsum`` and ``norm`` rounds it
    (``physics.linalg.vec3``)."""
    k = starts.shape[0]
    out = np.empty(k)
    for i in range(k):
        out[i] = _line_miss_row(target[0] - starts[i, 0], target[1] - starts[i, 1], target[2] - starts[i, 2],
                                directions[i, 0], directions[i, 1], directions[i, 2], behind_penalty)
    return out


@njit(cache=True)
def _line_miss_row(r0: float, r1: float, r2: float, d0: float, d1: float, d2: float, behind_penalty: float) -> float:
    """``line_miss`` of one line: the target minus its start (r0, r1, r2) m, its direction (d0, d1, d2)."""
    along = rowdot3(r0, r1, r2, d0, d1, d2)
    if along > 0.0:
        return rownorm3(r0 - along * d0, r1 - along * d1, r2 - along * d2)
    return rownorm3(r0, r1, r2) + behind_penalty


@njit(cache=True)
def turn_wanted(miss0: float, d: np.ndarray, rel: np.ndarray, hit_miss_m: float, min_turn_deg: float) -> int:
    """The rule planner's gate (``RulePlanner._miss_if_off_course``): 1 if a turn is wanted, 0 if not (swimming on
    misses the target by ``miss0`` m, below ``hit_miss_m``, or the target ``rel`` (3,) m from the head lies less than
    ``min_turn_deg`` off the heading ``d`` (3,)), -1 if d or rel is zero or not finite (no angle)."""
    if miss0 < hit_miss_m:
        return 0
    angle = angle_of(d, rel)
    if math.isnan(angle):
        return -1
    return 0 if math.degrees(angle) < min_turn_deg else 1


@njit(cache=True)
def paper_rule_misses(head: np.ndarray, d: np.ndarray, target: np.ndarray, frames: np.ndarray,
                      behind_penalty: float, hit_miss_m: float, min_turn_deg: float, out: np.ndarray
                      ) -> tuple[int, float]:
    """(``turn_wanted``, swimming on's miss m) of the rule planner with the paper's miss (``line_miss``), and, when a
    turn is wanted, each candidate's miss (``candidate_miss``) written to ``out`` (T, B) m: head, d (unit heading),
    target (3,) m; ``frames`` from ``candidate_frames``."""
    wanted, miss0, q0, q1, q2 = _gate(head, d, target, behind_penalty, hit_miss_m, min_turn_deg)
    if wanted > 0:
        _candidate_miss_into(frames, q0, q1, q2, behind_penalty, out)
    return wanted, miss0


@njit(cache=True)
def _gate(head: np.ndarray, d: np.ndarray, target: np.ndarray, behind_penalty: float, hit_miss_m: float,
          min_turn_deg: float) -> tuple[int, float, float, float, float]:
    """(``turn_wanted``, swimming on's miss m (``line_miss``), and, when a turn is wanted, the target in the
    heading's frame m (``target_in_frame``; else zeros)) of ``paper_rule_misses``' arguments."""
    miss0 = _line_miss_row(target[0] - head[0], target[1] - head[1], target[2] - head[2], d[0], d[1], d[2],
                           behind_penalty)
    wanted = turn_wanted(miss0, d, target - head, hit_miss_m, min_turn_deg)
    if wanted > 0:
        q0, q1, q2 = target_in_frame(head, d, target)
        return wanted, miss0, q0, q1, q2
    return wanted, miss0, 0.0, 0.0, 0.0


@njit(cache=True)
def pick_least(miss: np.ndarray, miss_straight: float, improvement: float) -> tuple[int, float]:
    """(flat index of the least of ``miss`` (T, B) m, that miss), the first among equals and a NaN before all
    (``np.argmin``'s); index -1 if it does not beat swimming on's ``miss_straight`` by
    ``improvement`` (m): the rule planner's choice by the miss alone (``agents.turn_planner.pick_turn``)."""
    flat = miss.ravel()
    k, best = 0, math.inf
    for c in range(flat.shape[0]):  # np.argmin's: the first least, the first NaN before all
        x = flat[c]
        if x < best:
            k, best = c, x
        elif math.isnan(x):
            k, best = c, x
            break
    return _if_improving(k, best, miss_straight, improvement)


@njit(cache=True)
def _if_improving(k: int, best: float, miss_straight: float, improvement: float) -> tuple[int, float]:
    """(``k``, ``best``) if the least miss ``best`` (m) beats swimming on's by ``improvement`` (m), else (-1, best)."""
    if best > miss_straight - improvement:
        return -1, best
    return k, best


@njit(cache=True)
def paper_rule_choice(head: np.ndarray, d: np.ndarray, target: np.ndarray, frames: np.ndarray,
                      behind_penalty: float, hit_miss_m: float, min_turn_deg: float, improvement: float
                      ) -> tuple[int, float, int, float]:
    """The rule planner's plan with the paper's miss and no line score: (``turn_wanted``, swimming on's miss m, the
    chosen candidate's flat index in (T, B) or -1 for none, its miss m): ``paper_rule_misses`` (its arguments) and
    ``pick_least`` in one pass over the candidates, the misses not stored."""
    wanted, miss0, q0, q1, q2 = _gate(head, d, target, behind_penalty, hit_miss_m, min_turn_deg)
    if wanted <= 0:
        return wanted, miss0, -1, math.nan
    n_b = frames.shape[1]
    k, best = 0, math.inf
    for i in range(frames.shape[0]):
        for j in range(n_b):  # pick_least's argmin
            x = _miss(frames, i, j, q0, q1, q2, behind_penalty)
            if x < best:
                k, best = i * n_b + j, x
            elif math.isnan(x):
                return wanted, miss0, i * n_b + j, x  # NaN is not above swimming on's miss: _if_improving keeps it
    k, best = _if_improving(k, best, miss0, improvement)
    return wanted, miss0, k, best


@njit(cache=True)
def candidate_plan(t_c: np.ndarray, theta: np.ndarray, psi: np.ndarray, beta: np.ndarray, i: int, j: int
                   ) -> tuple[float, float, float, float]:
    """Candidate turn ``i`` (``t_c`` s, ``theta``, ``psi`` rad, (T,)) flown at burst phase ``j`` (``beta`` (B,) rad):
    (its burst length s, theta deg, the burst phase rad and the new heading's predicted azimuth rad, beta + psi,
    both wrapped to (-pi, pi]) (``agents.turn_planner.RulePlanner.plan_of``)."""
    b = beta[j]
    return t_c[i], math.degrees(theta[i]), wrap_angle(b), wrap_angle(b + psi[i])


@njit(cache=True)
def target_in_frame(head: np.ndarray, d: np.ndarray, target: np.ndarray) -> tuple[float, float, float]:
    """The target minus the head in the frame (d, e1, e2) of the unit heading d, (e1, e2) = ``perpendicular_basis(d)``
    (``local_target``), m; all (3,) float64."""
    e1, e2 = unit_basis(d / norm3(d))
    return local_target(head, d, e1, e2, target)


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


@njit(cache=True)
def first_improving_distance(frames: np.ndarray, q0: float, q1: float, q2: float, behind_penalty: float,
                             threshold: float, lo: float, hi: float) -> float:
    """How far (m) the head can swim straight along d before some candidate turn's miss (``candidate_miss``, the
    same candidates and target frame) drops to ``threshold`` (m) or below: the first x in [lo, hi], inf if none.
    Moving the head by x d moves every candidate's end by x d and keeps its heading h, so with r the target from the
    end its lateral miss squared is a quadratic in x, (1 - h_d^2) x^2 + 2 ((r.h) h_d - r_d) x + |r|^2 - (r.h)^2,
    valid while the target is ahead of the end (r.h - x h_d > 0), and the behind miss |r - x d| + behind_penalty
    beyond. The rule planner flies a turn at the first control step where its best miss is ``improvement_m`` below
    swimming on's (``pick_turn``), so this is when it plans next on a straight stretch along which swimming on keeps
    its miss (the target ahead and off course)."""
    n_t, n_b = frames.shape[0], frames.shape[1]
    best = math.inf
    rest = threshold - behind_penalty
    for i in range(n_t):
        for j in range(n_b):
            r0, r1, r2 = q0 - frames[i, j, 0], q1 - frames[i, j, 1], q2 - frames[i, j, 2]
            rr = r0 * r0 + r1 * r1 + r2 * r2
            dh = frames[i, j, 3]
            rh = r0 * dh + r1 * frames[i, j, 4] + r2 * frames[i, j, 5]
            a_lo, a_hi = lo, hi  # where the target is ahead of the end
            if dh > 1e-15:
                a_hi = min(hi, rh / dh)
            elif dh < -1e-15:
                a_lo = max(lo, rh / dh)
            elif rh <= 0.0:
                a_hi = -math.inf
            if threshold > 0.0:
                x = _first_negative(1.0 - dh * dh, 2.0 * (rh * dh - r0), rr - rh * rh - threshold * threshold,
                                    a_lo, a_hi)
                if x < best:
                    best = x
            if rest > 0.0:  # behind: the complement of the interval above within [lo, hi]
                if dh > 1e-15:
                    x = _first_negative(1.0, -2.0 * r0, rr - rest * rest, max(lo, rh / dh), hi)
                elif dh < -1e-15:
                    x = _first_negative(1.0, -2.0 * r0, rr - rest * rest, lo, min(hi, rh / dh))
                else:
                    x = _first_negative(1.0, -2.0 * r0, rr - rest * rest, lo, hi) if rh <= 0.0 else math.inf
                if x < best:
                    best = x
    return best


@njit(cache=True)
def first_improving_sample(frames: np.ndarray, q0: float, q1: float, q2: float, behind_penalty: float,
                           improvement: float, step_m: float, n_max: int) -> int:
    """The first k in 1..n_max at which, with the head moved by k step_m along d, the best candidate's miss
    (``candidate_miss``) is at most swimming on's (the same ray miss from the moved head along d) less
    ``improvement`` (m); -1 if none. The sampled form of ``first_improving_distance`` for stretches along which
    swimming on's miss changes (the target behind).

    Only the candidates that can pass at some k are tried at every k (``_may_pass``: over the head's moves x in
    [step_m, n_max step_m] a candidate's miss has a least value in closed form; one above the largest bound by more
    than ``_BOUND_MARGIN_M``, far above rounding, cannot pass)."""
    bound = np.empty(n_max)
    largest = -math.inf
    for k in range(1, n_max + 1):
        m0 = q0 - k * step_m
        if m0 > 0.0:
            straight = math.sqrt(q1 * q1 + q2 * q2)
        else:
            straight = math.sqrt(m0 * m0 + q1 * q1 + q2 * q2) + behind_penalty
        bound[k - 1] = straight - improvement
        largest = max(largest, bound[k - 1])
    if not largest + _BOUND_MARGIN_M >= 0.0:
        return -1  # a miss is never negative
    n_t, n_b = frames.shape[0], frames.shape[1]
    kept = np.empty(n_t * n_b, np.int64)  # flat indices of the candidates that may pass
    n_kept = 0
    for i in range(n_t):
        for j in range(n_b):
            if _may_pass(frames, i, j, q0, q1, q2, behind_penalty, step_m, n_max * step_m, largest + _BOUND_MARGIN_M):
                kept[n_kept] = i * n_b + j
                n_kept += 1
    for k in range(1, n_max + 1):
        m0 = q0 - k * step_m
        for c in range(n_kept):
            i, j = divmod(kept[c], n_b)
            if _miss(frames, i, j, m0, q1, q2, behind_penalty) <= bound[k - 1]:
                return k
    return -1


#: How far (m) a candidate's least line distance must exceed the largest bound of ``first_improving_sample`` to be
#: left out: rounding moves these distances by ~1e-16 m.
_BOUND_MARGIN_M = 1e-9


@njit(cache=True)
def _may_pass(frames: np.ndarray, i: int, j: int, q0: float, q1: float, q2: float, behind_penalty: float, lo: float,
              hi: float, bound: float) -> bool:
    """False if the candidate ``frames[i, j]``'s miss (``_miss``, its row of ``candidate_frames``) of the target
    (q0 - x, q1, q2) exceeds ``bound`` (m, >= 0) for every move x in [lo, hi] m of the head along d. With r the target from the
    candidate's end and h its heading, the target lies ahead (r.h - x h_d > 0) on an interval of x, where the miss
    squared is the convex quadratic (1 - h_d^2) x^2 + 2 ((r.h) h_d - r_d) x + |r|^2 - (r.h)^2
    (``first_improving_distance``), and behind on the rest, where it is |r - x d| + behind_penalty; each part's
    least value lies at its vertex or an end of its interval (both widened by ``_BOUND_MARGIN_M``)."""
    r0, r1, r2 = q0 - frames[i, j, 0], q1 - frames[i, j, 1], q2 - frames[i, j, 2]
    rr = r0 * r0 + r1 * r1 + r2 * r2
    dh = frames[i, j, 3]
    rh = r0 * dh + r1 * frames[i, j, 4] + r2 * frames[i, j, 5]
    slack = _BOUND_MARGIN_M
    a_lo, a_hi, b_lo, b_hi = lo, hi, lo, hi  # where the target is ahead of the end (a) and behind it (b)
    if dh > 1e-15:
        a_hi, b_lo = min(hi, rh / dh + slack), max(lo, rh / dh - slack)
    elif dh < -1e-15:
        a_lo, b_hi = max(lo, rh / dh - slack), min(hi, rh / dh + slack)
    elif rh <= 0.0:
        a_hi = -math.inf
    else:
        b_hi = -math.inf
    if a_lo <= a_hi and _least_quadratic(max(1.0 - dh * dh, 0.0), 2.0 * (rh * dh - r0), rr - rh * rh, a_lo,
                                         a_hi) <= bound * bound:
        return True
    behind = bound - behind_penalty
    return b_lo <= b_hi and behind >= 0.0 and _least_quadratic(1.0, -2.0 * r0, rr, b_lo, b_hi) <= behind * behind


@njit(cache=True)
def _least_quadratic(a: float, b: float, c: float, lo: float, hi: float) -> float:
    """The least value of a x^2 + b x + c (a >= 0) over x in [lo, hi]: at the vertex or an end."""
    least = min((a * lo + b) * lo + c, (a * hi + b) * hi + c)
    if a > 0.0:
        x = min(max(-b / (2.0 * a), lo), hi)
        least = min(least, (a * x + b) * x + c)
    return least
