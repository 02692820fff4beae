"""Generalized coordinate partitioning (Wehage–Haug) and its QR and SVD variants.

The coordinates are split as q = q_ref + B z + D w: B spans the independent directions
(integrated), D the dependent ones (solved for). Only z and ż are integrated; then

    w  from  Φ(q_ref + B z + D w, t) = 0        by Newton–Raphson (seed 001, eq. 6)
    ẇ  from  Φ_q D ẇ = −Φ_q B ż − Φ_t
    q̈, λ from the augmented system (eq. 3), and z̈ = Bᵀ q̈.

The bases come from a factorisation of Φ_q at the partition point (the `choose` hook):
  "lu":  LU with pivoting of Φ_qᵀ — the pivot columns of Φ_q are dependent coordinates;
  "qr":  QR with column pivoting of Φ_q (Kim–Vanderploeg's choice of the dependent set);
  "svd": D and B are the row space and null space of Φ_q from its SVD (tangent-space
         coordinates rather than a subset of q).
For "lu" and "qr", B and D are columns of the identity, so z are real coordinates.

A new partition is taken (and the integrator restarted) when cond(Φ_q D) exceeds `cond_max`
or Newton needs more than `newton_repartition` iterations. At a true singular configuration
no partition is well conditioned: Newton may then converge to another branch. That is the
method's known weakness, which "hybrid" removes.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .base import Formulation


class ConstraintSolveError(RuntimeError):
    """Newton on the dependent coordinates did not converge; names the worst joint."""


def _solve(A, b):
    if A.shape[0] == A.shape[1]:
        return np.linalg.solve(A, b)
    return np.linalg.lstsq(A, b, rcond=None)[0]


def _numerical_rank(J) -> int:
    if J.shape[0] == 0:
        return 0
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(s > max(J.shape) * np.finfo(float).eps * 1e3 * s[0]))


class Partitioned(Formulation):
    name = "lu"
    default_integrator = "DOP853"
    options = {"cond_max": 1e4, "newton_tol": None, "max_newton": 12, "newton_repartition": 4}

    def __init__(self, problem, rtol, atol, **options):
        super().__init__(problem, rtol, atol, **options)
        if self.newton_tol is None:
            self.newton_tol = max(1e-13, 1e-3 * atol)
        self.n = problem.n
        self._cache = None
        self.independent = ()

    # --- the hook ----------------------------------------------------------------------------
    def choose(self, J) -> tuple[np.ndarray, np.ndarray]:
        """(B, D): independent and dependent bases, shapes (n, n−r) and (n, r)."""
        r = _numerical_rank(J)
        _, piv = sla.lu_factor(J.T, check_finite=False)
        perm = np.arange(self.n)
        for i, p in enumerate(piv):
            perm[i], perm[p] = perm[p], perm[i]
        return self._coordinate_bases(perm[r:], perm[:r])

    def _coordinate_bases(self, independent, dependent):
        eye = np.eye(self.n)
        self.independent = tuple(sorted(int(i) for i in independent))
        return eye[:, np.sort(independent)], eye[:, np.sort(dependent)]

    # --- partitioning --------------------------------------------------------------------------
    def partition(self, t, q, v):
        J = self.problem.phi_q(q, t)
        self.B, self.D = self.choose(J)
        self.q_ref = np.array(q, float)
        self.w_last = np.zeros(self.D.shape[1])
        self.wd_last = self.D.T @ v
        self.t_last = t
        self._cache = None
        self.problem.counters.partitions += 1
        return np.concatenate([np.zeros(self.B.shape[1]), self.B.T @ v])

    def initial_state(self, t, q, v):
        return self.partition(t, q, v)

    # --- state reconstruction ------------------------------------------------------------------
    def _positions(self, z, t):
        prob, D = self.problem, self.D
        base = self.q_ref + self.B @ z
        w = self.w_last + self.wd_last * (t - self.t_last)
        for k in range(self.max_newton + 1):
            q = base + D @ w
            phi, J = prob.position_terms(q, t)
            err = float(np.max(np.abs(phi))) if phi.size else 0.0
            if err <= self.newton_tol:
                return q, J, k
            if k == self.max_newton or not np.isfinite(err):
                break
            w = w - _solve(J @ D, phi)
        i = int(np.nanargmax(np.abs(phi))) if np.all(np.isfinite(phi)) else 0
        self.failure = (f"Newton on the dependent coordinates did not converge at t = {t:.9g} "
                        f"(residual {err:.3g} in '{prob.constraint_names[i]}' of joint "
                        f"'{prob.constraint_owners[i]}')")
        raise ConstraintSolveError(self.failure)

    def full_state(self, t, y):
        """(q, v, Φ_q, Newton iterations) of the integrated state y = [z; ż]."""
        c = self._cache
        if c is not None and c[0] == t and np.array_equal(c[1], y):
            return c[2]
        f = self.B.shape[1]
        z, zd = y[:f], y[f:]
        q, J, it = self._positions(z, t)
        JD = J @ self.D
        wd = _solve(JD, -(J @ (self.B @ zd)) - self.problem.phi_t(q, t))
        v = self.B @ zd + self.D @ wd
        out = (q, v, J, it)
        self._cache = (t, y.copy(), out)
        return out

    def state(self, t, y):
        q, v, _, _ = self.full_state(t, y)
        return q, v

    def rhs(self, t, y):
        prob = self.problem
        prob.counters.rhs += 1
        try:
            q, v, J, _ = self.full_state(t, y)
        except ConstraintSolveError:
            # A trial step too far for Newton: NaN makes the integrator reject and shrink it.
            return np.full(y.shape, np.nan)
        qdd, _ = prob.accelerations(J, prob.forces(t, q, v), prob.gamma(q, v, t))
        f = self.B.shape[1]
        return np.concatenate([y[f:], self.B.T @ qdd])

    def after_step(self, t, y):
        q, v, J, it = self.full_state(t, y)
        self.w_last, self.wd_last, self.t_last = self.D.T @ (q - self.q_ref), self.D.T @ v, t
        if it > self.newton_repartition or np.linalg.cond(J @ self.D) > self.cond_max:
            before = self.independent
            y_new = self.partition(t, q, v)
            if self.name == "svd" or self.independent != before:
                return y_new
        return None


class QRPartitioned(Partitioned):
    name = "qr"

    def choose(self, J):
        r = _numerical_rank(J)
        _, P = sla.qr(J, pivoting=True, mode="r", check_finite=False)
        return self._coordinate_bases(P[r:], P[:r])


class SVDPartitioned(Partitioned):
    name = "svd"

    def choose(self, J):
        r = _numerical_rank(J)
        _, _, Vt = np.linalg.svd(J)
        self.independent = ()
        return Vt[r:].T, Vt[:r].T
