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

Newton is a chord iteration with the factorisation of Φ_q D from the last accepted step,
started from a second-order prediction; it falls back to fresh Jacobians when it stalls. A
new partition is taken (and the integrator restarted) when cond(Φ_q D) exceeds `cond_max` or
Newton needed fresh Jacobians twice, and the pivoting then picks a different independent set. At a true singular configuration
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
    options = {"cond_max": 1e4, "newton_tol": None, "max_newton": 12}

    def __init__(self, problem, rtol, atol, **options):
        super().__init__(problem, rtol, atol, **options)
        if self.newton_tol is None:
            self.newton_tol = max(1e-13, 1e-2 * atol)
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
    def partition(self, t, q, v, bases=None):
        J = self.problem.phi_q(q, t)
        self.B, self.D = bases if bases is not None else self.choose(J)
        self.q_ref = np.array(q, float)
        f = self.B.shape[1]
        self._accept(t, np.zeros(f), self.B.T @ v, np.zeros(self.D.shape[1]), self.D.T @ v, J,
                     first=True)
        self._cache = None
        self.problem.counters.partitions += 1
        return np.concatenate([np.zeros(self.B.shape[1]), self.B.T @ v])

    def _accept(self, t, z, zd, w, wd, J, first=False):
        """Remember an accepted state: the predictor's data and the chord factorisation."""
        self._prev = None if first else (self.t_last, self.z_last, self.w_last)
        self.t_last, self.z_last, self.zd_last, self.w_last, self.wd_last = t, z, zd, w, wd
        JD = J @ self.D
        self._square = JD.shape[0] == JD.shape[1]
        if self._square:
            # An explicit inverse as the chord matrix: one small matmul per iteration, where
            # lu_solve spends ~30 µs in its wrapper. Convergence is judged on ‖Φ‖, so the
            # inverse's conditioning affects only the rate.
            self._chord = np.linalg.inv(JD)
            self._dw_dz = -self._chord @ (J @ self.B)
            self.problem.counters.factorizations += 1
        else:
            self._dw_dz = np.zeros((self.D.shape[1], self.B.shape[1]))

    def initial_state(self, t, q, v):
        return self.partition(t, q, v)

    # --- state reconstruction ------------------------------------------------------------------
    def _predict(self, t, z):
        """Dependent coordinates for (t, z): the path through the last accepted states
        extrapolated in time (tangent at t_last bent through the state before it), then
        corrected to first order for how far z lies off that path (∂w/∂z = −Φ_u⁻¹ Φ_q B).
        Integrator stages lie O(h²) off the smooth path, so the correction matters."""
        d = t - self.t_last
        w = self.w_last + self.wd_last * d
        zp = self.z_last + self.zd_last * d
        if self._prev is not None:
            t0, z0, w0 = self._prev
            e = t0 - self.t_last
            if e != 0.0:
                k = (d / e) ** 2
                w = w + (w0 - self.w_last - self.wd_last * e) * k
                zp = zp + (z0 - self.z_last - self.zd_last * e) * k
        return w + self._dw_dz @ (z - zp)

    def _positions(self, z, t):
        """Chord Newton on Φ(q_ref + B z + D w, t) = 0 with the factorisation of Φ_q D from
        the last accepted step; a fresh Jacobian only if the chord stalls."""
        prob, D = self.problem, self.D
        base = self.q_ref + self.B @ z
        w = self._predict(t, z)
        fresh = not self._square
        n_fresh = 0
        err_prev = np.inf
        for k in range(self.max_newton + 1):
            q = base + D @ w
            phi = prob.phi(q, t)
            err = float(np.max(np.abs(phi))) if phi.size else 0.0
            if err <= self.newton_tol:
                return q, n_fresh
            if k == self.max_newton or not np.isfinite(err):
                break
            if not fresh and err > 0.25 * err_prev:     # chord converging too slowly
                fresh = True
            err_prev = err
            if fresh:
                n_fresh += 1
                w = w - _solve(prob.phi_q(q, t) @ D, phi)
            else:
                w = w - self._chord @ phi
        i = int(np.nanargmax(np.abs(phi))) if np.all(np.isfinite(phi)) else 0
        self.failure = (f"Newton on the dependent coordinates did not converge at t = {t:.9g} "
                        f"(residual {err:.3g} in '{prob.constraint_names[i]}' of joint "
                        f"'{prob.constraint_owners[i]}')")
        raise ConstraintSolveError(self.failure)

    def full_state(self, t, y):
        """(q, v, Φ_q, n_fresh) of the integrated state y = [z; ż]; `n_fresh` counts the Newton
        iterations that needed a fresh Jacobian because the chord stalled (a sign that Φ_q D
        is changing fast)."""
        c = self._cache
        if c is not None and c[0] == t and np.array_equal(c[1], y):
            return c[2]
        f = self.B.shape[1]
        z, zd = y[:f], y[f:]
        q, n_fresh = self._positions(z, t)
        J = self.problem.phi_q(q, t)
        wd = _solve(J @ self.D, -(J @ (self.B @ zd)) - self.problem.phi_t(q, t))
        v = self.B @ zd + self.D @ wd
        out = (q, v, J, n_fresh)
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
        q, v, J, n_fresh = self.full_state(t, y)
        self.layout_changed = False
        if n_fresh >= 2 or np.linalg.cond(J @ self.D) > self.cond_max:
            before = self.independent
            bases = self.choose(J)
            if self.name == "svd" or self.independent != before:
                self.layout_changed = True
                return self.partition(t, q, v, bases)
        f = self.B.shape[1]
        self._accept(t, y[:f].copy(), y[f:].copy(), self.D.T @ (q - self.q_ref), self.D.T @ v, J)
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
