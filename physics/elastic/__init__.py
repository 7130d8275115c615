"""Discrete Elastic Rods elastic core: stretch, bend and twist energies with their
gradients and Hessians (Section 2.2 of Huang & Jawed 2020; Bergou et al. 2008, 2010)."""

from __future__ import annotations

from physics.elastic.bend import bend_energy_grad_hess, material_curvatures
from physics.elastic.rod_energy import (
    BANDWIDTH,
    RodRest,
    banded_to_dense,
    elastic_energy,
    elastic_energy_grad_hess_banded,
    elastic_energy_grad_hess_banded_kernel,
    elastic_energy_kernel,
    elastic_gradient,
    elastic_gradient_kernel,
    elastic_hessian_banded,
    elastic_hessian_banded_kernel,
    rest_from_configuration,
    rod_frames,
)
from physics.elastic.stretch import stretch_energy_grad_hess
from physics.elastic.twist import twist_energy_grad_hess

__all__ = [
    "BANDWIDTH",
    "RodRest",
    "banded_to_dense",
    "bend_energy_grad_hess",
    "elastic_energy",
    "elastic_energy_grad_hess_banded",
    "elastic_energy_grad_hess_banded_kernel",
    "elastic_energy_kernel",
    "elastic_gradient",
    "elastic_gradient_kernel",
    "elastic_hessian_banded",
    "elastic_hessian_banded_kernel",
    "material_curvatures",
    "rest_from_configuration",
    "rod_frames",
    "stretch_energy_grad_hess",
    "twist_energy_grad_hess",
]
