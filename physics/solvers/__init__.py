"""The nonlinear solve of one implicit step: its residual and Jacobian (``implicit_residual``), the per-scene
solvers (``step_solvers``), the compiled chord iteration (``chord_iteration``), Newton-Krylov in the mobility
form (``newton_krylov``) and runs of Newton-Krylov steps in one compiled call (``krylov_span``)."""
