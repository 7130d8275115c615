"""Physics core of the uniflagellar swimmer (Huang & Jawed, Soft Matter 2020).

Plain NumPy/SciPy with Numba kernels; imports nothing from the layers above it.
"""

import os as _os

# The dense linear algebra here is on ~500x500 matrices, where multi-threaded BLAS only adds
# overhead and oversubscribes the cores when simulations run in parallel (sweeps, vectorised
# environments). Takes effect when physics is imported before NumPy; override by setting it.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
_os.environ.setdefault("OMP_NUM_THREADS", "1")
_os.environ.setdefault("MKL_NUM_THREADS", "1")
