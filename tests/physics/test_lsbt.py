"""LSBT mobility (eqns 8-9) and its smoothness regularisation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.model.geometry import initial_nodes
from physics.hydro.hydrodynamics import resistance_matrix
from physics.hydro.lsbt import mobility_for
from physics.params import SwimmerParams

P = SwimmerParams()
MU, DELTA = P.viscosity, P.cutoff_length


def _straight_rod(n: int = 121) -> np.ndarray:
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * 2 * DELTA
    return x


def test_plain_eqn8_is_indefinite_on_the_paper_grid():
    # the reason for the regularisation: the alternating tangential mode has negative mobility
    a = mobility_for(_straight_rod(), MU, DELTA, smoothing=0.0)
    unit = 1.0 / (8 * math.pi * MU * 2 * DELTA)
    assert np.linalg.eigvalsh(a)[0] / unit == pytest.approx(-4 * math.log(2), rel=0.02)


@pytest.mark.parametrize("head_radius", [0.0, 0.012])
def test_regularised_mobility_is_positive_definite_for_the_paper_helix(head_radius):
    x = initial_nodes(P.replace(head_radius=head_radius))
    flag = x[1:] if head_radius > 0 else x
    assert np.linalg.eigvalsh(mobility_for(flag, MU, DELTA, P_NUM_SMOOTHING))[0] > 0


P_NUM_SMOOTHING = 20.0


def test_regularised_mobility_stays_positive_for_random_smooth_deformations():
    rng = np.random.default_rng(3)
    x = initial_nodes(P)[1:]
    s = np.linspace(0, 1, len(x))
    for _ in range(3):
        bend = sum(rng.normal(scale=5e-3) * np.sin((k + 1) * math.pi * s) for k in range(4))
        y = x.copy()
        y[:, 1] += bend
        y[:, 2] += np.roll(bend, 7)
        assert np.linalg.eigvalsh(mobility_for(y, MU, DELTA, P_NUM_SMOOTHING))[0] > 0


def test_smoothing_changes_smooth_modes_only_slightly():
    # rigid translation of a straight rod: drag changes by < 2 % between s = 10 and s = 160
    x = _straight_rod()
    u = np.tile([0.0, 1e-3, 0.0], len(x))
    f10 = np.linalg.solve(mobility_for(x, MU, DELTA, 10.0), u).reshape(-1, 3).sum(0)
    f160 = np.linalg.solve(mobility_for(x, MU, DELTA, 160.0), u).reshape(-1, 3).sum(0)
    assert f160[1] == pytest.approx(f10[1], rel=0.02)


def test_straight_rod_drag_matches_slender_body_formulas_broadside_and_lengthwise():
    x = _straight_rod()
    length = (len(x) - 1) * 2 * DELTA
    R = resistance_matrix(x, MU, DELTA, 0.0, False, P_NUM_SMOOTHING)
    u_par = np.tile([1e-3, 0.0, 0.0], len(x))
    u_perp = np.tile([0.0, 1e-3, 0.0], len(x))
    f_par = -(R @ u_par).reshape(-1, 3).sum(0)[0]
    f_perp = -(R @ u_perp).reshape(-1, 3).sum(0)[1]
    # Lighthill's own leading order for a uniform force density (evaluated mid-rod, so the
    # ends, which carry more force per length, make the totals somewhat larger)
    log = math.log(length / (2 * DELTA))
    f_par_sbt = -2 * math.pi * MU * length * 1e-3 / log
    f_perp_sbt = -4 * math.pi * MU * length * 1e-3 / (1 + log)
    assert f_par_sbt * 1.2 < f_par < f_par_sbt
    assert f_perp_sbt * 1.2 < f_perp < f_perp_sbt
    ratio = f_perp / f_par
    assert 1.5 < ratio < 2.0  # the textbook "close to 2" for a slender rod (exactly 2 as L/r0 -> inf)
    assert ratio == pytest.approx(f_perp_sbt / f_par_sbt, rel=0.05)


def test_lower_blocks_are_the_upper_blocks_and_tangents_are_normalised_edge_sums():
    """``lsbt_mobility`` writes each pair's values into both of its node blocks: block (i, j) is block (j, i)
    itself, not its transpose (bit for bit, also in the near field, where c_iso I + c_rr r r is symmetric only
    up to rounding; every entry is written, the matrix starts uninitialised); ``node_tangents`` is the normalised
    sum of the adjacent unit edges."""
    from physics.hydro.lsbt import lsbt_mobility, node_tangents

    r0 = P.rod_radius
    m = 40
    s = np.arange(m) * 2 * DELTA
    x = np.zeros((m, 3))  # a hairpin: two strands 2.5 r0 apart, joined by a half turn
    half = m // 2
    x[:half, 0] = s[:half]
    bend = np.linspace(-np.pi / 2, np.pi / 2, 5)[1:-1]
    x[half:, 0] = s[half - 1] - s[:m - half]
    x[half:, 1] = 2.5 * r0
    x[half - 1 + np.arange(1, 4), 0] = s[half - 1] + 1.25 * r0 * np.cos(bend)
    x[half - 1 + np.arange(1, 4), 1] = 1.25 * r0 + 1.25 * r0 * np.sin(bend)
    x = np.ascontiguousarray(x)
    e = np.diff(x, axis=0)
    u = e / np.linalg.norm(e, axis=1)[:, None]
    ref = np.zeros((m, 3))
    ref[1:] += u
    ref[:-1] += u
    ref /= np.linalg.norm(ref, axis=1)[:, None]
    t = node_tangents(x)
    np.testing.assert_allclose(t, ref, rtol=1e-14, atol=1e-14)
    a = lsbt_mobility(x, t, MU, DELTA, 0.0, 1.5 * r0)
    plain = lsbt_mobility(x, t, MU, DELTA, 0.0, 0.0)
    assert not np.array_equal(a, plain)  # the near field is in use
    for i in range(m):
        for j in range(i):
            assert np.array_equal(a[3 * i:3 * i + 3, 3 * j:3 * j + 3], a[3 * j:3 * j + 3, 3 * i:3 * i + 3])
