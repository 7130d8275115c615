"""Contact energies (physics/forces/contact.py): derivatives against finite differences, the broad
phase against brute force, and swimmers pushed onto the head and onto themselves keeping
their gap."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.forces.contact import ContactModel, add_blocks_to_dense, candidate_pairs, contact_kernel

R0 = 1e-3
EPS = 0.25 * R0
K = 0.1


def _energy_grad_hess(x: np.ndarray, b: float):
    """Energy, gradient (3n,) and dense Hessian (3n,3n) of every pair of x (brute-force pairs)."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
    first = 1 if b > 0 else 0
    pairs = candidate_pairs(x, arc, first, math.pi * R0, np.inf)
    E, g, nodes, blocks = contact_kernel(x, pairs, b, np.arange(2, len(x) - 1), R0, EPS, K)
    H = np.zeros((x.size, x.size))
    add_blocks_to_dense(H, nodes, blocks, 3)
    return E, g, H, len(nodes)


def _check_fd(x: np.ndarray, b: float) -> int:
    E, g, H, active = _energy_grad_hess(x, b)
    h = 1e-8
    g_fd = np.zeros_like(g)
    H_fd = np.zeros_like(H)
    for i in range(x.size):
        xp = x.copy().ravel()
        xm = x.copy().ravel()
        xp[i] += h
        xm[i] -= h
        Ep, gp, _, _ = _energy_grad_hess(xp.reshape(-1, 3), b)
        Em, gm, _, _ = _energy_grad_hess(xm.reshape(-1, 3), b)
        g_fd[i] = (Ep - Em) / (2 * h)
        H_fd[:, i] = (gp - gm) / (2 * h)
    scale_g = np.abs(g).max() + 1e-30
    scale_h = np.abs(H).max() + 1e-30
    assert np.abs(g - g_fd).max() <= 1e-5 * scale_g
    assert np.abs(H - H_fd).max() <= 1e-4 * scale_h
    return active


def _two_segments(a, b, c, d):
    """A 7-node rod whose edges 0 and 5 are a-b and c-d (edges between them are far away)."""
    far1 = b + 5 * (b - a) - np.array([0.0, 0.0, 0.01])
    far2 = c + 5 * (c - d) - np.array([0.0, 0.0, 0.01])
    mid = 0.5 * (far1 + far2) - np.array([0.0, 0.0, 0.01])
    return np.array([a, b, far1, mid, far2, c, d])


@pytest.mark.parametrize("case", ["interior", "end_interior", "end_end", "parallel", "crossing_skew"])
def test_rod_rod_gradient_and_hessian_match_finite_differences(case):
    rng = np.random.default_rng(3)
    z = 2 * R0 + 0.1 * EPS  # inside the activation distance, outside contact
    if case == "interior":
        a, b = np.array([-2e-3, 0, 0]), np.array([2e-3, 0.1e-3, 0])
        c, d = np.array([0.1e-3, -2e-3, z]), np.array([-0.1e-3, 2e-3, z])
    elif case == "end_interior":
        a, b = np.array([-2e-3, 0, 0]), np.array([2e-3, 0, 0])
        c, d = np.array([2.15e-3, -2e-3, z]), np.array([2.1e-3, 2e-3, z])
    elif case == "end_end":
        a, b = np.array([-2e-3, 0, 0]), np.array([0.0, 0, 0])
        c, d = np.array([0.3e-3, 0.2e-3, z]), np.array([2e-3, 1e-3, 3e-3])
    elif case == "parallel":
        a, b = np.array([-1e-3, 0, 0]), np.array([1e-3, 0, 0])
        c, d = np.array([-0.5e-3, 0, z]), np.array([1.5e-3, 0, z + 1e-9])
    else:
        a, b = np.array([-2e-3, 0, 0]), np.array([2e-3, 0, 0])
        c, d = np.array([0.2e-3, -2e-3, 1.7e-3]), np.array([0.1e-3, 2e-3, 2.3e-3])
    x = _two_segments(a, b, c, d) + 1e-6 * rng.standard_normal((7, 3))
    assert _check_fd(x, 0.0) >= 1


def test_head_gradient_and_hessian_match_finite_differences():
    b = 0.012
    rng = np.random.default_rng(5)
    # head centre, arm node on the surface, then a rod that comes back close to the head
    x = np.array([[0, 0, 0], [-b, 0, 0], [-b - 5e-3, 5e-3, 0], [-5e-3, 11e-3, 0.0],
                  [1e-3, 12.5e-3, 1e-3], [6e-3, 13e-3, 0.0]]) + 1e-6 * rng.standard_normal((6, 3))
    assert _check_fd(x, b) >= 1


def test_penalty_is_zero_outside_the_activation_distance():
    x = _two_segments(np.array([-2e-3, 0, 0]), np.array([2e-3, 0, 0]),
                      np.array([0, -2e-3, 2 * R0 + 1.01 * EPS]), np.array([0, 2e-3, 2 * R0 + 1.01 * EPS]))
    E, g, H, active = _energy_grad_hess(x, 0.0)
    assert active == 0 and E == 0.0 and not g.any()


def test_broad_phase_finds_every_pair_within_reach():
    """Sweep and prune returns exactly the pairs a brute-force box test returns."""
    rng = np.random.default_rng(11)
    steps = rng.standard_normal((150, 3))
    steps *= 1.6e-3 / np.linalg.norm(steps, axis=1)[:, None]
    x = np.cumsum(steps, axis=0)  # a random walk folds back on itself often
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
    reach = 2 * R0 + EPS
    got = {tuple(p) for p in candidate_pairs(x, arc, 0, math.pi * R0, reach)}
    want = set()
    for i in range(len(x) - 1):
        for j in range(i + 2, len(x) - 1):
            if arc[j] - arc[i + 1] < math.pi * R0:
                continue
            lo_i, hi_i = np.minimum(x[i], x[i + 1]), np.maximum(x[i], x[i + 1])
            lo_j, hi_j = np.minimum(x[j], x[j + 1]), np.maximum(x[j], x[j + 1])
            if np.all(lo_i - reach <= hi_j) and np.all(lo_j - reach <= hi_i):
                want.add((i, j))
    assert got == want and len(want) > 0


def test_straight_swimmer_has_no_contact_work():
    """The undeformed helix: no candidate pair, no head candidate, no energy."""
    from physics.model.geometry import initial_nodes
    from physics.params import SwimmerParams

    p = SwimmerParams()
    x = initial_nodes(p)
    model = ContactModel(np.linalg.norm(np.diff(x, axis=0), axis=1), p.rod_radius, p.head_radius, 0.25, K)
    pairs, head = model.broad_phase(x)
    assert len(head) == 0
    assert len(pairs) == 0
    E, g, nodes, _ = model.evaluate(x)
    assert E == 0.0 and len(nodes) == 0
    g_rr, g_h = model.gaps(x)
    assert g_rr > EPS and g_h > 4 * R0


class _Pulled:
    """A simulator whose node i is pulled towards node j by a force of magnitude F (N), and j
    towards i: presses the rod onto the head (j = 0) or onto itself. Its steps run the Python chord iteration
    (``chord_reference``), whose residual takes the extra force."""

    @staticmethod
    def make(i: int, j: int, force: float, contact: bool):
        from physics.model.geometry import nodes_of
        from physics.params import NumericsConfig, SwimmerParams
        from tests.physics.chord_reference import PythonChordSimulator

        class Pulled(PythonChordSimulator):
            def residual(self, q, h):
                r, grad, f, inertia, frames = super().residual(q, h)
                x = nodes_of(q)
                d = x[j] - x[i]
                u = force * d / np.linalg.norm(d)
                r = r.copy()
                r[4 * i:4 * i + 3] -= u
                r[4 * j:4 * j + 3] += u
                return r, grad, f, inertia, frames

        p = SwimmerParams(n_nodes=60, head_rotation="fixed")
        n = NumericsConfig(dt=0.01, newton_tol=1e-5, contact=contact, near_field_radius=1.5 if contact else 0.0)
        return Pulled(p, n)


def _run_min_gaps(sim, duration: float) -> tuple[float, float]:
    g_rr, g_h = np.inf, np.inf
    while sim.time < duration - 1e-9:
        sim.advance(0.25)
        a, b = sim.min_gaps()
        g_rr, g_h = min(g_rr, a), min(g_h, b)
    return g_rr, g_h


def test_rod_pulled_onto_the_head_keeps_its_gap():
    """The tail pulled onto the head with 0.02 N rests on it (the penalty force k (1 - g/eps)^2
    alone would balance 0.02 N at g = 0.14 mm; the bent rod's elasticity carries part of it)."""
    sim = _Pulled.make(59, 0, 0.02, contact=True)
    g_rr, g_h = _run_min_gaps(sim, 3.0)
    assert sim.contact_count >= 1
    assert 0.0 < g_h < EPS
    # without contact the same pull takes the tail into the head
    free = _Pulled.make(59, 0, 0.02, contact=False)
    assert _run_min_gaps(free, 2.0)[1] < -0.5 * R0


def test_rod_pulled_onto_itself_keeps_its_gap():
    sim = _Pulled.make(59, 25, 0.06, contact=True)
    g_rr, g_h = _run_min_gaps(sim, 4.0)
    assert sim.contact_count >= 1
    assert 0.0 < g_rr < EPS and g_h > 0.0


def _within_reach_reference(x, pairs, reach):
    """``within_reach`` as first written (closest points of every pair, no box bound): the reference."""
    from physics.forces.contact import _closest_params

    keep = np.zeros(pairs.shape[0], dtype=bool)
    for p, (i, j) in enumerate(pairs):
        a, b, c, d = x[i], x[i + 1], x[j], x[j + 1]
        s, t = _closest_params(a, b, c, d)
        w = (1.0 - s) * a + s * b - (1.0 - t) * c - t * d
        keep[p] = w @ w < reach * reach
    return pairs[keep]


def test_within_reach_with_its_box_bound_keeps_exactly_the_pairs_of_the_closest_point_test():
    """Random segments around the reach (some at reach x (1 +- 1e-9), where only the exact test decides; some
    axis-aligned at reach x (1 +- 1e-7, 1e-12), where the box bound is as tight as it gets), far from the origin too:
    the box lower bound never drops a pair the closest-point test keeps, in ``within_reach`` or in
    ``contact_kernel``."""
    from physics.forces.contact import within_reach

    rng = np.random.default_rng(11)
    reach = 2.75e-3
    for trial in range(60):
        n = 30
        origin = rng.normal(size=3) * (10.0 if trial % 2 else 0.1)
        x = origin + np.cumsum(rng.normal(size=(n, 3)) * 1.2e-3, axis=0)
        pairs = np.array([(i, j) for i in range(n - 1) for j in range(i + 2, n - 1)], dtype=np.int64)
        if trial % 4 == 0:  # segment j placed at exactly about reach from segment i along a normal
            i, j = 3, 20
            e = x[i + 1] - x[i]
            nrm = np.cross(e, rng.normal(size=3))
            nrm /= np.linalg.norm(nrm)
            mid = 0.5 * (x[i] + x[i + 1])
            x[j] = mid + reach * (1.0 + rng.choice([-1e-9, 0.0, 1e-9])) * nrm - 1e-4 * e
            x[j + 1] = x[j] + 2e-4 * e
        elif trial % 4 == 1:  # axis-aligned parallel segments: their boxes are as far apart as they are
            i, j = 5, 17
            k, m = rng.choice(3, size=2, replace=False)
            x[i + 1] = x[i].copy()
            x[i + 1, k] += 1.2e-3
            x[j] = x[i].copy()
            x[j, m] += reach * (1.0 + rng.choice([-1e-7, -1e-12, 0.0, 1e-12, 1e-7]))
            x[j + 1] = x[j].copy()
            x[j + 1, k] += 1.2e-3
        got = within_reach(x, pairs, reach)
        assert np.array_equal(got, _within_reach_reference(x, pairs, reach))
        r0, eps = 1e-3, reach - 2e-3  # contact_kernel skips pairs by the same bound: its active pairs are these
        active = _within_reach_reference(x, pairs, 2.0 * r0 + eps)
        nodes = contact_kernel(x, pairs, 0.0, np.zeros(0, dtype=np.int64), r0, eps, 0.1)[2]
        assert np.array_equal(nodes, np.column_stack([active[:, 0], active[:, 0] + 1, active[:, 1], active[:, 1] + 1]))


def test_buffered_pair_and_head_distances_are_the_array_expressions_bit_for_bit():
    """``_pair_sq_distance`` / ``_head_sq_distance`` (the rejection tests of ``contact_kernel`` in buffers) give
    exactly what the array expressions they replaced give: (s, t, |w|^2) and (t, |w|^2)."""
    from physics.forces.contact import _closest_params, _head_sq_distance, _pair_sq_distance

    rng = np.random.default_rng(12)
    x = np.ascontiguousarray(np.cumsum(rng.normal(size=(25, 3)) * 1.2e-3, axis=0) + 0.3)
    x[7] = x[6] + 1e-3 * (x[12] - x[11]) / np.linalg.norm(x[12] - x[11])  # a parallel pair, 6-7 and 11-12
    bufs = [np.empty(3) for _ in range(4)]
    for i in range(x.shape[0] - 1):
        for j in range(i + 2, x.shape[0] - 1):
            a, b, c, d = x[i], x[i + 1], x[j], x[j + 1]
            s, t = _closest_params(a, b, c, d)
            w = (1.0 - s) * a + s * b - (1.0 - t) * c - t * d
            assert _pair_sq_distance(x, i, j, *bufs) == (s, t, w @ w)
        c, d = x[i], x[i + 1]
        e = d - c
        t = min(max((x[0] - c) @ e / (e @ e), 0.0), 1.0)
        w = x[0] - (1.0 - t) * c - t * d
        assert _head_sq_distance(x, i, *bufs[:3]) == (t, w @ w)
