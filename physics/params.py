"""Physical and numerical parameters of the swimmer (SI units inside).

Defaults are the paper's values (Huang & Jawed 2020, Sec. 2.1, 2.3, 2.4). Every field
carries its unit, meaning and allowed range in ``dataclasses.field(metadata=...)`` so the
CLI can list and validate them (``flagellum params``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from physics.validation import finite_range, require_finite

RPM_TO_RAD_S = 2.0 * math.pi / 60.0
#: the readings of the head's rotation (``SwimmerParams.head_rotation``; docs/validation.md)
HEAD_ROTATIONS = ("torque_free", "fixed", "literal", "paper")


def _f(default: Any, unit: str, help: str, lo: float | None = None, hi: float | None = None,
       lo_open: bool = False, choices: tuple | None = None) -> Any:
    return field(default=default, metadata={"unit": unit, "help": help, "lo": lo, "hi": hi,
                                            "lo_open": lo_open, "choices": choices})


def _validate_fields(obj: Any) -> None:
    """Check every field against its metadata; raise ValueError naming value and range."""
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        meta = f.metadata
        choices = meta.get("choices")
        if choices is not None:
            if value not in choices:
                raise ValueError(f"{f.name}={value!r} is not allowed; choose one of {list(choices)}")
            continue
        if isinstance(value, bool):
            continue
        require_finite(f.name, value, meta.get("lo"), meta.get("hi"), lo_open=meta.get("lo_open", False),
                       unit="" if meta["unit"] == "-" else meta["unit"])


@dataclass(frozen=True)
class SwimmerParams:
    """Physical parameters of head, flagellum and fluid (paper Sec. 2.1-2.4)."""

    pitch: float = _f(32.6e-3, "m", "helix pitch lambda", 0.0, None, True)
    helix_radius: float = _f(6.04e-3, "m", "helix radius R", 0.0, None, True)
    axial_length: float = _f(0.13, "m", "axial length L of the flagellum (used for the nondimensional groups)", 0.0, None, True)
    rod_radius: float = _f(1e-3, "m", "rod cross-section radius r0", 0.0, None, True)
    youngs_modulus: float = _f(10e6, "Pa", "Young's modulus E", 0.0, None, True)
    shear_modulus: float = _f(10e6 / 3.0, "Pa", "shear modulus G (paper: E/3)", 0.0, None, True)
    density: float = _f(1273.0, "kg/m^3", "rod density = fluid density rho", 0.0, None, True)
    viscosity: float = _f(2.7, "Pa s", "fluid viscosity mu", 0.0, None, True)
    head_radius: float = _f(0.012, "m", "head radius b (0 = no head)", 0.0, 0.1)
    n_nodes: int = _f(122, "-", "number of DER nodes N including the head node (paper: 122)", 8, 2000)
    head_rotation: str = _f("fixed", "-",
                            "fixed (default): head held against rotation, flagellum base turns at omega in the lab "
                            "frame, reciprocal head flow forms; torque_free: head spins per the torque balance, "
                            "eqn (13), omega relative to the head; "
                            "literal: flagellum base turns at omega in the lab frame, the head spins per eqn (13) "
                            "and its rotlet (eqn 10) acts on the flagellum (needs head_model=higdon, hydro_model="
                            "lsbt); paper: as fixed, with the head flow and force of eqns (10)-(11) as printed "
                            "(docs/validation.md)",
                            choices=HEAD_ROTATIONS)

    def __post_init__(self) -> None:
        if isinstance(self.n_nodes, float) and self.n_nodes.is_integer():
            object.__setattr__(self, "n_nodes", int(self.n_nodes))
        if not isinstance(self.n_nodes, int):
            raise ValueError(f"n_nodes={self.n_nodes!r} must be an integer >= 8")
        _validate_fields(self)
        if self.rod_radius >= self.helix_radius:
            raise ValueError(f"rod_radius={self.rod_radius} m must be smaller than helix_radius={self.helix_radius} m")

    # Derived quantities -------------------------------------------------------------
    @property
    def has_head(self) -> bool:
        return self.head_radius > 0.0

    @property
    def area(self) -> float:
        """Cross-section area A = pi r0^2, m^2."""
        return math.pi * self.rod_radius**2

    @property
    def bending_stiffness(self) -> float:
        """EI with I = pi r0^4 / 4, N m^2 (7.854e-6 for the paper)."""
        return self.youngs_modulus * math.pi * self.rod_radius**4 / 4.0

    @property
    def twisting_stiffness(self) -> float:
        """GJ with J = pi r0^4 / 2, N m^2."""
        return self.shear_modulus * math.pi * self.rod_radius**4 / 2.0

    @property
    def stretching_stiffness(self) -> float:
        """EA, N."""
        return self.youngs_modulus * self.area

    @property
    def cutoff_length(self) -> float:
        """LSBT natural cutoff delta = r0 sqrt(e) / 2, m (Sec. 2.3)."""
        return self.rod_radius * math.sqrt(math.e) / 2.0

    @property
    def viscous_time(self) -> float:
        """Viscous-elastic time scale mu L^4 / EI, s (98.19 s for the paper)."""
        return self.viscosity * self.axial_length**4 / self.bending_stiffness

    def omega_bar(self, omega_rad_s: float) -> float:
        """Nondimensional motor speed omega_bar = omega mu L^4 / EI."""
        return omega_rad_s * self.viscous_time

    def t_bar(self, t_s: float) -> float:
        """Nondimensional time t_bar = t EI / (mu L^4)."""
        return t_s / self.viscous_time

    def reynolds(self, omega_rad_s: float) -> float:
        """Paper's Reynolds number rho omega R r0 / mu (Sec. 2.1)."""
        return self.density * abs(omega_rad_s) * self.helix_radius * self.rod_radius / self.viscosity

    def replace(self, **changes: Any) -> "SwimmerParams":
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class NumericsConfig:
    """Numerical settings of the implicit integrator."""

    dt: float = _f(1e-3, "s", "time step h (paper: 1 ms); with step_tol > 0 the step of the simulator's "
                   "step() (sampling and motor updates), inside which the adaptive steps are taken", 0.0, 1.0, True)
    integrator: str = _f("euler", "-", "implicit scheme of eqn (6): euler (implicit Euler, first order, as in the "
                         "paper), or variable-step BDF up to order 2, 3 or 4: bdf2 (L-stable), bdf3, bdf4 (stable on the "
                         "overdamped modes of this rod; the order ramps up after every restart; "
                         "physics/integrate/time_integrator.py)",
                         choices=("euler", "bdf2", "bdf3", "bdf4"))
    step_tol: float = _f(0.0, "-", "adaptive time stepping: the local error of each step is kept below this "
                         "fraction of the rod radius (positions) and radians (twists); 0 = fixed steps of dt",
                         0.0, 1.0)
    h_start: float = _f(1e-3, "s", "adaptive stepping: first step after a start or a motor-speed change (where "
                        "the motion has a kink, so no error estimate exists yet)", 0.0, 1.0, True)
    h_min: float = _f(1e-6, "s", "adaptive stepping: smallest step before SimulationError", 0.0, 1.0, True)
    newton_tol: float = _f(1e-6, "-", "Newton tolerance on the relative force residual", 0.0, 1e-2, True)
    newton_max_iter: int = _f(25, "-", "Newton iterations before the Jacobian is refreshed / the step fails", 2, 500)
    hydro_refresh_tol: float = _f(0.03, "-",
                                  "refresh the hydrodynamic resistance when the non-rigid deformation since the last "
                                  "refresh exceeds this fraction of the rod radius (0 = every step)", 0.0, 10.0)
    hydro_refresh_max_steps: int = _f(200, "-", "refresh the hydrodynamic resistance at least every this many steps", 1, 100000)
    lsbt_smoothing: float = _f(20.0, "-",
                               "strength of the force-smoothness regularisation of the LSBT inverse, in units of "
                               "1/(8 pi mu 2 delta) (0 = plain eqn (8), which is indefinite)", 0.0, 1e3)
    max_substeps: int = _f(6, "-", "times a failing step may be halved before SimulationError", 0, 20)
    jacobian_refresh: str = _f("stall", "-", "when the dense Newton Jacobian is refactorised besides a changed step: "
                               "stall (only when the chord iteration stops contracting) or resistance (also "
                               "whenever the hydrodynamic resistance is rebuilt, i.e. the shape has changed)",
                               choices=("stall", "resistance"))
    newton_krylov: bool = _f(False, "-", "solve the steps at which the hydrodynamic resistance is rebuilt (the shape "
                             "has changed: buckling, relaxation) by Newton-Krylov in the mobility form "
                             "(physics/solvers/newton_krylov.py: no dense factorisation); the other steps keep the "
                             "chord iteration on the reused factorisation (lsbt only)")
    single_iteration: bool = _f(False, "-", "take exactly one Newton iteration per step (linearly implicit "
                                "Euler): fastest, first-order accurate, no convergence check")
    hydro_model: str = _f("lsbt", "-", "flagellum hydrodynamics: lsbt (nonlocal, eqn 8, dense) or rft "
                          "(local resistive-force theory, O(N), banded)", choices=("lsbt", "rft"))
    head_model: str = _f("higdon", "-", "head hydrodynamics: higdon (flow coupling with the flagellum, "
                         "eqns 10-11) or stokes (own drag and torque only); with hydro_model=rft the head is "
                         "always a Stokes sphere (the local model has no coupling)", choices=("higdon", "stokes"))
    rft_coefficients: str = _f("lighthill", "-", "drag coefficients of the rft model",
                               choices=("lighthill", "gray_hancock"))
    rft_scale_perp: float = _f(1.0, "-", "rft only: factor on the normal drag coefficient zeta_perp of "
                               "rft_coefficients (N s/m^2), fitted against the LSBT swimmer (scripts/"
                               "calibrate_reduced.py); 1 = the published coefficient", 0.0, 100.0, True)
    rft_scale_par: float = _f(1.0, "-", "rft only: factor on the tangential drag coefficient zeta_par of "
                              "rft_coefficients (N s/m^2), fitted like rft_scale_perp; 1 = the published "
                              "coefficient", 0.0, 100.0, True)
    rft_head_drag_scale: float = _f(1.0, "-", "rft only: factor on the head's translational Stokes drag 6 pi mu b "
                                    "(N s/m) in the rft model, which has no head-flagellum flow coupling; an effective "
                                    "stand-in for the Higdon head's coupling (eqns 10-11), fitted to the onset of "
                                    "buckling (scripts/calibrate_reduced.py); 1 = a plain Stokes sphere",
                                    0.0, 100.0, True)
    contact: bool = _f(True, "-", "head-rod and rod-rod contact (penalty energies in the implicit step, "
                       "physics/forces/contact.py); false only for comparison: the rod can then pass through the "
                       "head and itself")
    contact_stiffness: float = _f(0.1, "N", "contact force at zero gap (the penalty's scale)", 0.0, None, True)
    contact_margin: float = _f(0.25, "-", "activation distance of the contact penalty, in units of the rod "
                               "radius r0 (the force rises from 0 at this gap)", 0.0, 10.0, True)
    near_field_radius: float = _f(1.5, "-", "radius a of the RPY near-field kernel that replaces eqn (8)'s "
                                  "Stokeslet between strands that come close, in units of r0 (0 = plain eqn 8; "
                                  "physics/hydro/lsbt.py)", 0.0, 10.0)

    def __post_init__(self) -> None:
        for name in ("newton_max_iter", "hydro_refresh_max_steps", "max_substeps"):
            v = getattr(self, name)
            if isinstance(v, float) and v.is_integer():
                object.__setattr__(self, name, int(v))
            if not isinstance(getattr(self, name), int):
                raise ValueError(f"{name}={v!r} must be an integer")
        _validate_fields(self)

    def replace(self, **changes: Any) -> "NumericsConfig":
        return dataclasses.replace(self, **changes)


#: Parameters that were removed, with why: naming one anywhere (overrides, ``--set``, sweeps, turn maps) raises a
#: one-line ValueError (``removed_message``) instead of the generic unknown-parameter one.
REMOVED_PARAMETERS = {
    "anderson_depth": "Anderson mixing of the chord iteration cost more CPU than it saved; the chord and Newton "
                      "iterations run compiled without it (docs/time_integration.md)",
}


def removed_message(name: str) -> str:
    """What the removed parameter ``name`` was and why it went (``REMOVED_PARAMETERS``), on one line."""
    return f"parameter {name!r} was removed ({REMOVED_PARAMETERS[name]}); drop it"


def refuse_removed(names: Any) -> None:
    """ValueError (``removed_message``) for the first of ``names`` (parameter names) that was removed."""
    for name in names:
        if name in REMOVED_PARAMETERS:
            raise ValueError(removed_message(name))


def check_combination(params: SwimmerParams, numerics: NumericsConfig) -> None:
    """ValueError naming the values when a reading of the head is combined with a model it does not support:
    ``head_rotation=literal`` acts through the Higdon head's rotlet on the LSBT flagellum (eqns 8, 10, 13); the
    RFT factors (``rft_scale_perp``, ``rft_scale_par``, ``rft_head_drag_scale``) other than 1 need
    ``hydro_model=rft``."""
    if numerics.hydro_model != "rft":
        for name in ("rft_scale_perp", "rft_scale_par", "rft_head_drag_scale"):
            if getattr(numerics, name) != 1.0:
                raise ValueError(f"{name}={getattr(numerics, name)!r} with hydro_model={numerics.hydro_model!r} is "
                                 f"not allowed; allowed: {name}=1 (the factor acts only on the rft model), or "
                                 "hydro_model='rft'")
    if params.head_rotation == "literal" and (numerics.head_model != "higdon" or numerics.hydro_model != "lsbt"):
        bad = (f"head_model={numerics.head_model!r}" if numerics.head_model != "higdon"
               else f"hydro_model={numerics.hydro_model!r}")
        raise ValueError(f"head_rotation='literal' with {bad} is not allowed; allowed: head_model='higdon' and "
                         "hydro_model='lsbt' (the head's spin acts on the flagellum through eqn (10)'s rotlet), or "
                         "another head_rotation (torque_free, fixed, paper)")


def parameter_table() -> list[dict[str, Any]]:
    """Every settable parameter with its default, unit, help and allowed range."""
    rows = []
    for cls, group in ((SwimmerParams, "physics"), (NumericsConfig, "numerics")):
        for f in dataclasses.fields(cls):
            m = f.metadata
            if m.get("choices") is not None:
                allowed = "one of " + ", ".join(m["choices"])
            else:
                allowed = finite_range(m.get("lo"), m.get("hi"), lo_open=m.get("lo_open", False)) or "any finite"
            if isinstance(f.default, bool):
                allowed = "true or false"
            rows.append({"name": f.name, "group": group, "default": f.default, "unit": m["unit"],
                         "help": m["help"], "allowed": allowed})
    return rows


def apply_overrides(params: SwimmerParams, numerics: NumericsConfig,
                    overrides: dict[str, str]) -> tuple[SwimmerParams, NumericsConfig]:
    """Apply ``NAME=VALUE`` overrides (strings) to the right dataclass; clear errors on unknown names."""
    p_names = {f.name: f for f in dataclasses.fields(SwimmerParams)}
    n_names = {f.name: f for f in dataclasses.fields(NumericsConfig)}
    p_changes: dict[str, Any] = {}
    n_changes: dict[str, Any] = {}
    refuse_removed(overrides)
    for name, raw in overrides.items():
        if name in p_names:
            target, fld = p_changes, p_names[name]
        elif name in n_names:
            target, fld = n_changes, n_names[name]
        else:
            known = ", ".join(sorted(list(p_names) + list(n_names)))
            raise ValueError(f"unknown parameter {name!r}; known parameters: {known}")
        if fld.metadata.get("choices") is not None:
            target[name] = raw
        elif isinstance(fld.default, bool):
            low = str(raw).strip().lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError(f"{name}={raw!r} must be true or false")
            target[name] = low in ("true", "1", "yes")
        else:
            try:
                val = float(raw)
            except ValueError:
                raise ValueError(f"{name}={raw!r} is not a number") from None
            target[name] = int(val) if isinstance(fld.default, int) and val.is_integer() else val
    return params.replace(**p_changes), numerics.replace(**n_changes)
