"""Time integration: implicit Euler and variable-step BDF2-4 with a local error estimate and a step-size
controller (``time_integrator``)."""
