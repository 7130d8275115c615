"""The RFT calibration factors (NumericsConfig.rft_scale_perp, rft_scale_par, rft_head_drag_scale): validated,
refused with LSBT, and applied to the local resistance (physics/hydro/rft.py, force_terms.Hydrodynamics)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics import configure
from physics.hydro.rft import rft_coefficients
from physics.params import NumericsConfig, SwimmerParams, check_combination
from physics.simulator import Simulator


@pytest.mark.parametrize("name", ["rft_scale_perp", "rft_scale_par", "rft_head_drag_scale"])
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), 1e3])
def test_factor_out_of_range_is_refused(name, value):
    with pytest.raises(ValueError, match=name):
        NumericsConfig(hydro_model="rft", **{name: value})


@pytest.mark.parametrize("name", ["rft_scale_perp", "rft_scale_par", "rft_head_drag_scale"])
def test_factor_with_lsbt_is_refused(name):
    with pytest.raises(ValueError, match=f"{name}=2.0 with hydro_model='lsbt'"):
        check_combination(SwimmerParams(), NumericsConfig(hydro_model="lsbt", **{name: 2.0}))
    with pytest.raises(ValueError, match=name):
        configure("faithful", {name: 2.0})


def test_factors_scale_the_local_resistance():
    p, n = configure("faithful", {"n_nodes": 20, "hydro_model": "rft", "rft_scale_perp": 1.5,
                                  "rft_scale_par": 0.5, "rft_head_drag_scale": 3.0})
    sim = Simulator(p, n)
    hyd = sim.scene.term("hydrodynamics")
    zp, zl = rft_coefficients(p, "lighthill")
    assert hyd.zeta == pytest.approx((1.5 * zp, 0.5 * zl), rel=1e-15)
    res = hyd.resistance_at(sim.nodes.copy())
    assert res.drag_t == pytest.approx(3.0 * 6.0 * math.pi * p.viscosity * p.head_radius, rel=1e-15)
    # a node's block: ell [zeta_perp (I - t t) + zeta_par t t]; its trace is ell (2 zeta_perp + zeta_par)
    p1, n1 = configure("faithful", {"n_nodes": 20, "hydro_model": "rft"})
    base = Simulator(p1, n1).scene.term("hydrodynamics").resistance_at(sim.nodes.copy())
    tr, tr1 = np.trace(res.blocks, axis1=1, axis2=2), np.trace(base.blocks, axis1=1, axis2=2)
    ell = tr1 / (2 * zp + zl)
    np.testing.assert_allclose(tr, ell * (3.0 * zp + 0.5 * zl), rtol=1e-12)
