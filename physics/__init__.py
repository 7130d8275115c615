"""Physics core of the uniflagellar swimmer (Huang & Jawed, Soft Matter 2020).

Plain NumPy/SciPy with Numba kernels; imports nothing from the layers above it. The public API::

    from physics import Simulator, advance, configure
    from physics.params import RPM_TO_RAD_S

    params, numerics = configure("fast", {"head_radius": 0.01})  # preset, then overrides
    sim = Simulator(params, numerics)
    sim.set_motor_speed(10 * RPM_TO_RAD_S)
    advance(sim, 5.0, on_step=lambda sim, k: print(k, sim.time) if k % 100 == 0 else None)

- ``Simulator`` (``physics.simulator``): the swimmer; ``step()``, ``advance(T)``, state and observables.
- ``SwimmerParams``, ``NumericsConfig`` (``physics.params``): the physical and numerical parameters.
- ``configure(preset, overrides)`` (``physics.presets``): the defaults, a preset, then overrides;
  ``preset_names()`` (the live presets: ``reference``, ``paper``, ``faithful``, ``fast``; the retired
  ``coarse`` is refused with a one-line ValueError, ``physics.presets.check_preset``). The commands and the environment use ``physics.presets.DEFAULT_PRESET``
  (``"faithful"``); ``configure()`` without a preset is the bare parameter defaults (the paper's
  model with implicit Euler at h = 1 ms, as ``"paper"``).
- ``MotorSchedule`` (``physics.schedule``): piecewise-constant motor speed.
- ``advance(sim, T, on_step=...)`` (``physics.run``): the run loop with a callback after each step;
  ``run_simulation`` records a trajectory and a summary on top of it.
- ``SimulationError`` (``physics.errors``): a step that cannot be taken.

The run loop holds BLAS at one thread while it steps (``physics.threads``, with threadpoolctl);
importing the package changes no environment variable.

The names load on first use, so ``import physics`` stays light (no NumPy, no Numba).

The model and the numerics behind the API are in subpackages: ``model`` (geometry, frames), ``elastic`` (rod
energies), ``hydro`` (LSBT, RFT, the head), ``forces`` (force terms, step context, contact), ``linalg`` (banded
factorisations, compiled LAPACK), ``solvers`` (the implicit step's nonlinear solve), ``integrate`` (Euler / BDF).
"""

#: Public name -> module that defines it (imported on first access, PEP 562).
_API = {"Simulator": "physics.simulator", "SwimmerParams": "physics.params", "NumericsConfig": "physics.params",
        "configure": "physics.presets", "preset_names": "physics.presets", "MotorSchedule": "physics.schedule",
        "advance": "physics.run", "run_simulation": "physics.run", "RunResult": "physics.run",
        "SimulationError": "physics.errors"}
__all__ = sorted(_API)


def __getattr__(name: str):
    if name in _API:
        import importlib

        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'physics' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
