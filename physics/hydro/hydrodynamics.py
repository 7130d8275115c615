"""Generalised hydrodynamic resistance of head + flagellum (eqns 8-13 of Huang & Jawed 2020).

Generalised velocity V = [u_0, u_1, ..., u_{n-1}, s] (node velocities of the whole rod,
node 0 being the head centre U_h when there is a head, then the head spin rate s about the
head axis a = t^0 when the head spins). The hydrodynamic generalised force (forces on the
nodes, then the axial torque on the head) is G = -R V with

    R = D + B^T C B,   C = A_reg^{-1} (LSBT resistance, eqn 9),   B = [-H | I | -g],
    D = diag(6 pi mu b I_3, 0, 8 pi mu b^3).

This is eqns (9)-(13) solved together: the flagellum forces F = -C (u - H U - g s) follow from
eqn (8) with the head flow of eqn (10) subtracted, the head force f_0 = -6 pi mu b U - H^T F
is eqn (12) with eqn (11), and the head's axial torque -8 pi mu b^3 s - g^T F is the axial
part of eqn (13)'s head terms. With the reciprocal head forms of ``higdon_head`` R is
symmetric positive definite (the system can only dissipate energy).

With the head forms as printed in the paper (``printed_head``, the paper's reading) the head
force is f_h = K F with K != -H^T, so R = [[D - K C H, K C], [-C H, C]] is not symmetric.

In the literal lab-driven reading (``spin_from_balance``: theta^0 = omega t in the lab frame) the head spins at
the rate s = w . y that eqn (13) gives for the flagellum's forces y = -F (``higdon_head.head_spin_map``), and its
rotlet g s enters the flagellum's flow (eqn 10): A y = u - H U - g (w . y), i.e. the mobility A is replaced by
A' = A + g w^T and s is not a generalised velocity. A' is not symmetric: C' = A'^{-1} is formed explicitly (LU),
and R = [[D + H^T C' H, -H^T C'], [-C' H, C']].
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.linalg import lapack

from physics.hydro.higdon_head import (head_flow_operators, head_operators_as_printed, head_spin_map,
                                 sphere_rotational_drag, sphere_translational_drag)
from physics.hydro.lsbt import lsbt_mobility, node_tangents


@njit(cache=True)
def _mirror_upper(a: np.ndarray) -> np.ndarray:
    """The symmetric matrix whose upper triangle is a's (in place; LAPACK potri fills only that one)."""
    n = a.shape[0]
    for i in range(n):
        for j in range(i):
            a[i, j] = a[j, i]
    return a


class HydroError(RuntimeError):
    """The hydrodynamic mobility could not be inverted (geometry degenerate)."""


# An explicit inverse costs about as much as 50-60 Cholesky solves and makes later solves ~3x
# cheaper: form it once an operator has been used this often (i.e. when it is being reused).
INVERSE_AFTER_SOLVES = 60


class ResistanceOperator:
    """R = D + B^T C B applied matrix-free from the Cholesky factor of A_reg (see module doc).

    Built at one geometry; ``apply(V)`` costs two triangular solves, ``dense()`` forms R. With
    ``factorize_lazily`` the Cholesky factor is only formed when a solve first needs it (the mobility
    form of ``newton_krylov`` uses ``a``, ``H``, ``g``, ``K`` and the drags, and never solves).
    """

    def __init__(self, nodes: np.ndarray, mu: float, delta: float, head_radius: float,
                 head_spins: bool, smoothing: float, head_coupling: bool = True,
                 near_radius: float = 0.0, printed_head: bool = False, factorize_lazily: bool = False,
                 spin_from_balance: bool = False) -> None:
        nodes = np.ascontiguousarray(nodes, dtype=np.float64)
        self.has_head = head_radius > 0.0
        self.spin = head_spins and self.has_head
        self.printed = printed_head and self.has_head
        #: the literal lab-driven reading: the head's spin from eqn (13) acts on the flagellum (module doc)
        self.lab_spin = spin_from_balance and self.has_head
        if self.spin and printed_head:
            raise ValueError("the head forms as printed (eqns 10-11) are for a head that does not spin")
        if self.lab_spin and (self.spin or printed_head or not head_coupling):
            raise ValueError("spin_from_balance needs the reciprocal head coupling and a head that is not a DOF")
        flag = np.ascontiguousarray(nodes[1:]) if self.has_head else nodes
        a = lsbt_mobility(flag, node_tangents(flag), mu, delta, smoothing, near_radius)
        self.m3 = a.shape[0]
        self.a = a  # the mobility A_reg (3M, 3M), m/(N s): all that the mobility form needs
        self.inv: np.ndarray | None = None  # the explicit inverse of a, once formed (``inverse``)
        self.chol: tuple[np.ndarray, bool] | None = None  # (Cholesky factor of a, lower), once ``factorize``d
        self._smoothing = smoothing
        if self.lab_spin:  # A' = A + g w^T (module doc): g is the rotlet's flow, w eqn (13) solved for the spin
            e0 = nodes[1] - nodes[0]
            axis = e0 / math.sqrt(e0 @ e0)
            _, g_spin = head_flow_operators(flag, nodes[0].copy(), axis, head_radius)
            self.spin_map = head_spin_map(flag, nodes[0].copy(), axis, head_radius, mu)
            self.a = a + np.outer(g_spin, self.spin_map)
        if not factorize_lazily:
            self.factorize()
        if self.has_head:
            e0 = nodes[1] - nodes[0]
            axis = e0 / math.sqrt(e0 @ e0)
            if printed_head:
                self.H, self.K = head_operators_as_printed(flag, nodes[0].copy(), head_radius)
                self.g = np.zeros(self.m3)
            else:
                self.H, self.g = head_flow_operators(flag, nodes[0].copy(), axis, head_radius)
                self.K = -self.H.T  # Faxen: the force on the head is the adjoint of its flow
            if not head_coupling:  # "stokes" head: own drag and torque only
                self.H[:] = 0.0
                self.g[:] = 0.0
                self.K = np.zeros_like(self.K)
            self.drag_t = sphere_translational_drag(mu, head_radius)
            self.drag_r = sphere_rotational_drag(mu, head_radius)
        self.nv = self.m3 + (3 if self.has_head else 0) + (1 if self.spin else 0)
        self.applies = 0  # Cholesky solves so far (the inverse is formed after INVERSE_AFTER_SOLVES)

    @classmethod
    def from_parts(cls, a: np.ndarray, H: np.ndarray, g: np.ndarray, drag_t: float, drag_r: float, spin: bool,
                   smoothing: float) -> "ResistanceOperator":
        """The operator ``__init__`` builds with ``factorize_lazily`` for a head with the reciprocal Higdon forms,
        from its parts computed elsewhere (``krylov_span``): the mobility a (3M, 3M) m/(N s), the head's flow H
        (3M, 3) and spin flow g (3M,), its drags (N s/m, N m s)."""
        op = cls.__new__(cls)
        op.has_head, op.spin, op.printed, op.lab_spin = True, spin, False, False
        op.m3 = a.shape[0]
        op.a, op.inv, op.chol, op._smoothing = a, None, None, smoothing
        op.H, op.g, op.K = H, g, -H.T
        op.drag_t, op.drag_r = drag_t, drag_r
        op.nv = op.m3 + 3 + (1 if spin else 0)
        op.applies = 0
        return op

    def factorize(self) -> None:
        """Cholesky of A_reg (or, for the indefinite plain eqn (8) and the non-symmetric A' of the literal reading,
        its explicit inverse)."""
        if self._smoothing > 0.0 and not self.lab_spin:
            c, info = lapack.dpotrf(self.a, lower=0, clean=1, overwrite_a=0)
            if info != 0:
                raise HydroError(f"LSBT mobility is not positive definite (Cholesky failed at pivot {info})")
            self.chol = (c, False)
        else:  # plain eqn (8): indefinite, use an explicit inverse
            self.inv = np.linalg.inv(self.a)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """C b = A_reg^{-1} b (two triangular solves; a matvec once the inverse is kept)."""
        if self.inv is None and self.chol is None:
            self.factorize()
        if self.inv is not None:
            return self.inv @ b
        self.applies += 1
        if self.applies > INVERSE_AFTER_SOLVES:
            return self.inverse() @ b
        # LAPACK potrs directly: what cho_solve calls, without its wrapper (~5 % of a step)
        x, info = lapack.dpotrs(self.chol[0], b, lower=self.chol[1])
        if info != 0:
            raise HydroError(f"LSBT mobility solve failed (potrs info {info})")
        return x

    def inverse(self) -> np.ndarray:
        """C = A_reg^{-1}, (3M,3M); computed once and kept (matvecs are cheaper than solves)."""
        if self.inv is None and self.chol is None:
            self.factorize()
        if self.inv is None:
            inv, info = lapack.dpotri(self.chol[0], lower=0)
            if info != 0:
                raise HydroError(f"LSBT mobility inversion failed (potri info {info})")
            self.inv = _mirror_upper(inv)
        return self.inv

    def apply(self, V: np.ndarray) -> np.ndarray:
        """R V for generalised velocities V (nv,); returns minus the hydrodynamic generalised force."""
        if not self.has_head:
            return self.solve(V)
        m3 = self.m3
        U, u = V[0:3], V[3:3 + m3]
        bv = u - self.H @ U
        if self.spin:
            bv = bv - self.g * V[-1]
        y = self.solve(bv)
        out = np.empty_like(V)
        out[0:3] = self.drag_t * U + self.K @ y if self.printed else self.drag_t * U - self.H.T @ y
        out[3:3 + m3] = y
        if self.spin:
            out[-1] = self.drag_r * V[-1] - self.g @ y
        return out

    def dense(self) -> np.ndarray:
        """R, (nv, nv)."""
        c = self.inverse()
        if not self.has_head:
            return c.copy()
        m3, nv = self.m3, self.nv
        R = np.zeros((nv, nv))
        CH = c @ self.H
        if self.printed:
            R[0:3, 0:3] = self.drag_t * np.eye(3) - self.K @ CH
            R[0:3, 3:3 + m3] = self.K @ c
        elif self.lab_spin:  # C' is not symmetric
            R[0:3, 0:3] = self.drag_t * np.eye(3) + self.H.T @ CH
            R[0:3, 3:3 + m3] = -(self.H.T @ c)
        else:  # K = -H^T (kept in this form: same arithmetic as before the printed option existed)
            R[0:3, 0:3] = self.drag_t * np.eye(3) + self.H.T @ CH
            R[0:3, 3:3 + m3] = -CH.T
        R[3:3 + m3, 0:3] = -CH
        R[3:3 + m3, 3:3 + m3] = c
        if self.spin:
            Cg = c @ self.g
            R[0:3, -1] = self.H.T @ Cg
            R[-1, 0:3] = R[0:3, -1]
            R[3:3 + m3, -1] = -Cg
            R[-1, 3:3 + m3] = -Cg
            R[-1, -1] = self.drag_r + self.g @ Cg
        return R


def resistance_matrix(nodes: np.ndarray, mu: float, delta: float, head_radius: float,
                      head_spins: bool, smoothing: float, near_radius: float = 0.0,
                      printed_head: bool = False, spin_from_balance: bool = False) -> np.ndarray:
    """Generalised resistance R, (3n[+1], 3n[+1]), SI (N s/m, N s, N m s).

    nodes: (n,3) rod nodes, m (node 0 is the head centre if head_radius > 0).
    head_spins: append the head spin rate s as the last generalised velocity.
    near_radius: m, the near-field kernel of ``lsbt`` (0 = plain eqn 8 for every pair).
    printed_head: eqns (10)-(11) as printed (R not symmetric) instead of the reciprocal forms.
    spin_from_balance: the literal lab-driven reading (the head's spin from eqn (13) acts on the flagellum; R not
    symmetric).
    """
    return ResistanceOperator(nodes, mu, delta, head_radius, head_spins, smoothing,
                              near_radius=near_radius, printed_head=printed_head,
                              spin_from_balance=spin_from_balance).dense()
