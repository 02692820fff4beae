"""The motions a mechanism's constraints allow, in independent coordinates.

A subset of f coordinates z (picked by LU pivoting of Φ_q at a reference state, as the "lu"
method does, and measured from it) parametrizes the configurations near that state:

    q(z) = q_ref + B z + D w(z),   Φ(q(z), t) = 0                (Newton on w)
    R = dq/dz = B − D (Φ_q D)⁺ Φ_q B                             (the allowed motions)
    v(z, ż) = R ż − D (Φ_q D)⁺ Φ_t
    (Rᵀ M R) z̈ = Rᵀ (Q − M s),   s = D (Φ_q D)⁺ γ                 (Wehage and Haug)

The reduced equations are the "lu" method's own (`partitioned.reduced_accelerations`):
their conditioning is that of the partition and of the reduced inertia, not that of the
constraint forces. Redundant constraints (Φ_q D not square) are solved in the least-squares
sense. Static equilibrium (`mechsim.engineering.equilibrium`), linearization
(`mechsim.engineering.linearize`) and shooting (`mechsim.shooting.mechanism`) work in
these coordinates.
"""

from __future__ import annotations

import numpy as np

from ..linalg.newton import newton


# The dependent coordinates of a z further than this (in radians, or mechanism sizes) from the
# last one solved are found along the straight path between them, in pieces this long: the
# solution stays on the branch and the angles continuous (Newton from a far guess may land on
# the mirror branch, or on the same configuration with angles wound by multiples of 2π).
PIECE = 0.05


def size_of(problem, q) -> float:
    """A mechanism's size: the span of its bodies' frame origins (at least 1 mm)."""
    starts = [s for s in problem.body_starts.values() if s is not None]
    points = np.array([q[s:s + 2] for s in starts] + [np.zeros(2)])
    return float(max(np.ptp(points, axis=0).max(), 1e-3))


class ReducedCoordinates:
    """Independent coordinates of `problem` about the consistent configuration `q_ref` at
    time `t` (see the module docstring).

    Attributes
    ----------
    f : number of independent coordinates;  ind, dep : their indices in q and the others'
    names : the independent coordinates' names
    units : (f,) a natural unit of each: 1 rad for an angle, the mechanism's size for a
        length or a modal amplitude
    """

    def __init__(self, problem, q_ref, t: float = 0.0, tol: float = 1e-13):
        from ..formulations.basis import CoordinateBasis
        from ..formulations.partitioned import Partitioned
        self.problem, self.t, self.tol = problem, float(t), tol
        self.q_ref = np.array(q_ref, float)
        J = problem.phi_q(self.q_ref, self.t)
        self.basis = Partitioned(problem, 1e-8, 1e-10).choose(J) if problem.m else \
            CoordinateBasis(np.arange(problem.n), np.zeros(0, dtype=np.intp))
        self.ind, self.dep = self.basis.ind, self.basis.dep
        self.f = self.ind.size
        self.names = [problem.coordinate_names[i] for i in self.ind]
        self.size = size_of(problem, self.q_ref)
        self.units = np.array([1.0 if name.endswith(".angle") else self.size
                               for name in self.names])
        self._last = (np.zeros(self.f), self.q_ref[self.dep].copy())   # (z, w) solved last

    def _dependent_solve(self, J, b):
        """(Φ_q D)⁺ b for the columns `dep` of J (b may have several columns)."""
        A = J[:, self.dep]
        if A.shape[0] == A.shape[1]:
            return self.basis.block(J).solve(b)
        return np.linalg.lstsq(A, b, rcond=None)[0]

    # --- configurations and velocities -------------------------------------------------------
    def positions(self, z, t=None) -> np.ndarray:
        """q(z) on the constraints at time t (default: the reference time), on the branch of
        the configurations solved before. ValueError where Newton finds no configuration (z
        beyond where the mechanism assembles, or across a singular configuration of this
        partition)."""
        t = self.t if t is None else t
        z = np.asarray(z, float)
        if not self.dep.size:
            q = self.q_ref.copy()
            q[self.ind] += z
            return q
        z_last, w = self._last
        pieces = max(1, int(np.ceil(np.max(np.abs(z - z_last) / self.units, initial=0.0)
                                    / PIECE)))
        z_prev = z_last
        for k in range(1, pieces + 1):
            zk = z_last + (z - z_last) * (k / pieces)
            q = self._solve(zk, z_prev, w, t)
            z_prev, w = zk, q[self.dep]
        self._last = (z.copy(), w.copy())
        return q

    def _solve(self, z, z_prev, w, t):
        """q at z by Newton on the dependent coordinates, from the configuration (z_prev, w)
        predicted to first order along its tangent."""
        prob = self.problem
        q = self.q_ref.copy()
        q[self.ind] += z
        guess = w
        if np.any(z != z_prev):
            before = self.q_ref.copy()
            before[self.ind] += z_prev
            J = prob.phi_q(self._with(before, w), t)
            guess = w - self._dependent_solve(J, J[:, self.ind] @ (z - z_prev))

        def residual(w):
            return prob.position_terms(self._with(q, w), t)

        def correct(w, phi, J, slow):
            return w - self._dependent_solve(J, phi)

        done = newton(guess, residual, correct, self.tol, 30, stall=True, extra=1)
        if not done.converged:
            raise ValueError(f"no assembled configuration at {self._where(z)} (residual "
                             f"{prob.worst_constraint(prob.phi(self._with(q, done.x), t))})")
        return self._with(q, done.x)

    def _with(self, q, w):
        out = q.copy()
        out[self.dep] = w
        return out

    def _where(self, z):
        return ", ".join(f"{n} = {x:.6g}" for n, x in
                         zip(self.names, self.q_ref[self.ind] + np.asarray(z, float)))

    def tangent(self, q, t=None, J=None) -> np.ndarray:
        """R = dq/dz at the configuration q, shape (n, f) (`J`: Φ_q there, if known)."""
        t = self.t if t is None else t
        R = np.zeros((self.problem.n, self.f))
        R[self.ind, np.arange(self.f)] = 1.0
        if self.dep.size:
            J = self.problem.phi_q(q, t) if J is None else J
            R[self.dep] = -self._dependent_solve(J, J[:, self.ind])
        return R

    def velocities(self, q, zd, t=None, J=None) -> np.ndarray:
        """v = R ż − D (Φ_q D)⁺ Φ_t at the configuration q (`J`: Φ_q there, if known)."""
        t = self.t if t is None else t
        v = np.zeros(self.problem.n)
        v[self.ind] = zd
        if self.dep.size:
            J = self.problem.phi_q(q, t) if J is None else J
            v[self.dep] = -self._dependent_solve(J, J[:, self.ind] @ np.asarray(zd, float)
                                                 + self.problem.phi_t(q, t))
        return v

    # --- reduced equations -------------------------------------------------------------------
    def mass(self, q, R=None) -> np.ndarray:
        """Rᵀ M R, shape (f, f)."""
        R = self.tangent(q) if R is None else R
        prob = self.problem
        MR = prob.mass_diagonal[:, None] * R if prob.constant_mass else prob.mass(q) @ R
        return R.T @ MR

    def force(self, z, t=None) -> np.ndarray:
        """Rᵀ Q at rest (v = 0) at q(z): the generalized force in z, zero at equilibrium."""
        t = self.t if t is None else t
        q = self.positions(z, t)
        return self.tangent(q, t).T @ self.problem.forces(t, q, np.zeros_like(q))

    def accelerations(self, z, zd, t=None) -> np.ndarray:
        """z̈ of the reduced equations at (z, ż)."""
        from ..formulations.partitioned import reduced_accelerations
        t = self.t if t is None else t
        q = self.positions(z, t)
        J = self.problem.phi_q(q, t)
        v = self.velocities(q, zd, t, J)
        return reduced_accelerations(self.problem, self.basis, t, q, v, J)[self.ind]
