"""The BLAS and LAPACK routines the Python step calls, callable from compiled (Numba) code.

So that a compiled loop gives the same bits as the NumPy / SciPy calls it replaces, it calls the very same
routines, not look-alikes:

* ``getrs`` / ``potrs_upper``: SciPy's LAPACK ``dgetrs`` / ``dpotrs`` (the ones ``scipy.linalg.lapack.dgetrs`` /
  ``dpotrs`` wrap), through ``scipy.linalg.cython_lapack``.
* ``gbsv``: SciPy's LAPACK ``dgbsv``, which ``scipy.linalg.solve_banded`` calls for a square banded system with
  more than one diagonal on either side (``scipy.linalg._basic._solve_banded``: the band copied below kl zero rows
  into an array of 2 kl + ku + 1 rows, then ``lapack.dgbsv``), on the same array, so the same bits.
* ``numpy_matvec`` / ``numpy_dot``: ``A @ x`` and ``x @ y`` as NumPy computes them for float64 arrays: its own
  (bundled) OpenBLAS ``cblas_dgemv`` / ``cblas_ddot``, with the storage order and transposition NumPy's matmul
  chooses for a C- or F-contiguous matrix. Found only where NumPy ships scipy-openblas (the PyPI wheels):
  ``NUMPY_BLAS`` tells; where it is False they are Numba's products (SciPy's BLAS: the same up to rounding) and
  the compiled Newton-Krylov span is not used (its Python step runs).

The symbols are registered with LLVM by name (``llvmlite.binding.add_symbol``) at import, so the kernels that
call them can be cached (``cache=True``): an address is never frozen into the cache.
"""

from __future__ import annotations

import ctypes
import glob
import os

import llvmlite.binding as ll
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

_P = types.voidptr
ll.add_symbol("physics_dgetrs", get_cython_function_address("scipy.linalg.cython_lapack", "dgetrs"))
ll.add_symbol("physics_dpotrs", get_cython_function_address("scipy.linalg.cython_lapack", "dpotrs"))
ll.add_symbol("physics_dgbsv", get_cython_function_address("scipy.linalg.cython_lapack", "dgbsv"))
# (trans, n, nrhs, a, lda, ipiv, b, ldb, info) and (uplo, n, nrhs, a, lda, b, ldb, info): Fortran, all pointers
_dgetrs = types.ExternalFunction("physics_dgetrs", types.void(_P, _P, _P, _P, _P, _P, _P, _P, _P))
_dpotrs = types.ExternalFunction("physics_dpotrs", types.void(_P, _P, _P, _P, _P, _P, _P, _P))
# (n, kl, ku, nrhs, ab, ldab, ipiv, b, ldb, info)
_dgbsv = types.ExternalFunction("physics_dgbsv", types.void(_P, _P, _P, _P, _P, _P, _P, _P, _P, _P))


def _numpy_openblas() -> ctypes.CDLL | None:
    """NumPy's bundled OpenBLAS (scipy-openblas64, ILP64), or None if this NumPy has another BLAS."""
    here = os.path.dirname(np.__file__)
    for pattern in (os.path.join(here, os.pardir, "numpy.libs", "libscipy_openblas64_*"),
                    os.path.join(here, ".dylibs", "libscipy_openblas64_*")):
        for path in glob.glob(pattern):
            try:
                lib = ctypes.CDLL(path)
                lib.scipy_cblas_dgemv64_, lib.scipy_cblas_ddot64_  # noqa: B018  (both must exist)
                return lib
            except (OSError, AttributeError):
                continue
    return None


_lib = _numpy_openblas()
#: True where NumPy's own cblas_dgemv / cblas_ddot were found (``numpy_matvec`` / ``numpy_dot`` usable)
NUMPY_BLAS = _lib is not None
if NUMPY_BLAS:
    ll.add_symbol("physics_np_dgemv", ctypes.cast(_lib.scipy_cblas_dgemv64_, ctypes.c_void_p).value)
    ll.add_symbol("physics_np_ddot", ctypes.cast(_lib.scipy_cblas_ddot64_, ctypes.c_void_p).value)
_I, _L, _D = types.int32, types.int64, types.float64
# cblas_dgemv(order, trans, M, N, alpha, A, lda, X, incX, beta, Y, incY), ILP64; cblas_ddot(N, X, incX, Y, incY)
_np_dgemv = types.ExternalFunction("physics_np_dgemv", types.void(_I, _I, _L, _L, _D, _P, _L, _P, _L, _D, _P, _L))
_np_ddot = types.ExternalFunction("physics_np_ddot", _D(_L, _P, _L, _P, _L))
_COL_MAJOR, _NO_TRANS, _TRANS = 102, 111, 112


@njit(cache=True)
def getrs(lu: np.ndarray, piv1: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int]:
    """x = A^{-1} b from the LU factors of A (n, n), F-contiguous as ``scipy.linalg.lu_factor`` returns them, and
    its pivots *1-based* (int32, (n,)): LAPACK dgetrs, no transpose. Returns (x (n,), info)."""
    n = lu.shape[0]
    x = b.copy()
    ints = np.array([n, 1, n, n, 0], dtype=np.int32)  # n, nrhs, lda, ldb, info
    trans = np.array([78], dtype=np.uint8)  # 'N'
    _dgetrs(trans.ctypes, ints[0:].ctypes, ints[1:].ctypes, lu.ctypes, ints[2:].ctypes, piv1.ctypes, x.ctypes,
            ints[3:].ctypes, ints[4:].ctypes)
    return x, int(ints[4])


@njit(cache=True)
def potrs_upper(c: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int]:
    """x = A^{-1} b from the upper Cholesky factor c (n, n) of A, F-contiguous as ``lapack.dpotrf`` returns it:
    LAPACK dpotrs with uplo 'U'. Returns (x (n,), info)."""
    n = c.shape[0]
    x = b.copy()
    ints = np.array([n, 1, n, n, 0], dtype=np.int32)  # n, nrhs, lda, ldb, info
    uplo = np.array([85], dtype=np.uint8)  # 'U'
    _dpotrs(uplo.ctypes, ints[0:].ctypes, ints[1:].ctypes, c.ctypes, ints[2:].ctypes, x.ctypes, ints[3:].ctypes,
            ints[4:].ctypes)
    return x, int(ints[4])


@njit(cache=True)
def gbsv(ab: np.ndarray, kl: int, ku: int, b: np.ndarray) -> tuple[np.ndarray, int]:
    """x = A^{-1} b (n,) for the banded A (n, n) with kl sub- and ku superdiagonals, given in the storage
    ``scipy.linalg.solve_banded`` takes (ab (kl + ku + 1, n), ab[ku + i - j, j] = A[i, j], any order): LAPACK
    dgbsv on the (2 kl + ku + 1, n) column-major array ``solve_banded`` builds (kl zero rows, then ab; the LU's
    fill-in goes into the zero rows), so x is ``solve_banded((kl, ku), ab, b)`` bit for bit. ``ab`` and ``b`` are
    not changed. Returns (x, info): info > 0 a zero pivot (``solve_banded``: "singular matrix"), < 0 an illegal
    argument."""
    n = ab.shape[1]
    ldab = 2 * kl + ku + 1
    lab = np.zeros((n, ldab)).T  # column-major (ldab, n)
    lab[kl:, :] = ab
    x = b.copy()
    ipiv = np.empty(n, dtype=np.int32)
    ints = np.array([n, kl, ku, 1, ldab, n, 0], dtype=np.int32)  # n, kl, ku, nrhs, ldab, ldb, info
    _dgbsv(ints[0:].ctypes, ints[1:].ctypes, ints[2:].ctypes, ints[3:].ctypes, lab.ctypes, ints[4:].ctypes,
           ipiv.ctypes, x.ctypes, ints[5:].ctypes, ints[6:].ctypes)
    return x, int(ints[6])


@njit(cache=True)
def _numpy_matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A @ x (m,) for A (m, n) C- or F-contiguous and x (n,) contiguous, float64, as NumPy computes it (its
    cblas_dgemv: a C-contiguous A as the transpose of a column-major (n, m), an F-contiguous one as column-major
    (m, n)). Caller's contract: contiguous arrays (checked)."""
    m, n = A.shape
    y = np.empty(m)
    if m == 0:
        return y
    if n == 0:
        y[:] = 0.0
        return y
    if A.strides[1] == 8 and A.strides[0] == 8 * n:  # C order
        _np_dgemv(_COL_MAJOR, _TRANS, n, m, 1.0, A.ctypes, n, x.ctypes, 1, 0.0, y.ctypes, 1)
    elif A.strides[0] == 8 and A.strides[1] == 8 * m:  # F order
        _np_dgemv(_COL_MAJOR, _NO_TRANS, m, n, 1.0, A.ctypes, m, x.ctypes, 1, 0.0, y.ctypes, 1)
    else:
        raise ValueError("numpy_matvec takes a C- or F-contiguous matrix")
    return y


@njit(cache=True)
def _numpy_dot(x: np.ndarray, y: np.ndarray) -> float:
    """x @ y for contiguous float64 vectors (n,), as NumPy computes it (its cblas_ddot)."""
    return _np_ddot(x.shape[0], x.ctypes, 1, y.ctypes, 1)


@njit(cache=True)
def numba_matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A @ x (m,) as Numba computes it (SciPy's dgemv), for a NumPy without its bundled OpenBLAS."""
    if A.shape[0] == 0 or A.shape[1] == 0:
        return np.zeros(A.shape[0])
    return A @ x


@njit(cache=True)
def numba_dot(x: np.ndarray, y: np.ndarray) -> float:
    """x @ y as Numba computes it (SciPy's ddot), for a NumPy without its bundled OpenBLAS."""
    return np.dot(x, y) if x.shape[0] else 0.0


#: A @ x and x @ y in compiled code: NumPy's own where ``NUMPY_BLAS`` (bit for bit), else Numba's
numpy_matvec = _numpy_matvec if NUMPY_BLAS else numba_matvec
numpy_dot = _numpy_dot if NUMPY_BLAS else numba_dot
