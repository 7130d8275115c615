"""Compiled linear algebra of the step: banded Cholesky (``banded_cholesky``) and banded LU (``banded_lu``), the
banded Newton matrices (``banded_jacobian``), and the BLAS / LAPACK routines callable from Numba code
(``compiled_lapack``), and 3-vector arithmetic for compiled kernels rounded as NumPy rounds it (``vec3``)."""
