"""physics/model/geometry.py: the compiled edge-stretch check the step uses to reject a step, against NumPy."""

from __future__ import annotations

import math

import numpy as np

from physics.model.geometry import edge_stretch_extremes, nodes_of


def test_edge_stretch_extremes_match_numpy():
    rng = np.random.default_rng(2)
    n = 30
    q = rng.normal(size=4 * n - 1)
    l_bar = rng.uniform(0.5, 1.5, size=n - 1)
    ratio = np.linalg.norm(np.diff(nodes_of(q), axis=0), axis=1) / l_bar
    finite, i_min, r_min, i_max, r_max = edge_stretch_extremes(q, l_bar)
    assert finite and (i_min, i_max) == (int(np.argmin(ratio)), int(np.argmax(ratio)))
    assert math.isclose(r_min, ratio.min(), rel_tol=1e-15) and math.isclose(r_max, ratio.max(), rel_tol=1e-15)
    q[7] = np.nan
    assert not edge_stretch_extremes(q, l_bar)[0]
