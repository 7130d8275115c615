"""The compiled banded Newton iteration of the RFT model (``chord_iteration.chord_loop`` with the banded increment)
against the Python iteration it replaces (``Simulator._chord_python`` with ``BandedNewtonSolver.increment``), bit for
bit; and the compiled LAPACK dgbsv against ``scipy.linalg.solve_banded``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_banded

from physics.linalg.compiled_lapack import gbsv


@pytest.mark.parametrize("n", [11, 40, 159, 487])
def test_compiled_gbsv_is_solve_banded_bit_for_bit(n):
    """Random diagonally heavy band matrices of the elastic Hessian's width (kl = ku = 10), and a singular one."""
    rng = np.random.default_rng(n)
    for _ in range(4):
        ab = rng.normal(size=(21, n))
        ab[10] += 30.0
        b = rng.normal(size=n)
        ab0, b0 = ab.copy(), b.copy()
        x, info = gbsv(ab, 10, 10, b)
        assert info == 0 and np.array_equal(x, solve_banded((10, 10), ab, b, check_finite=False))
        assert np.array_equal(ab, ab0) and np.array_equal(b, b0)  # inputs untouched
    x, info = gbsv(np.zeros((21, n)), 10, 10, np.ones(n))
    assert info == 1  # solve_banded: LinAlgError("singular matrix")
