"""The Lagrange multipliers λ at many states: what joint reactions and driver efforts are.

At a consistent state (q, v, t) the equations of motion M q̈ + Φ_qᵀ λ = Q, Φ_q q̈ = γ give

    (Φ_q M⁻¹ Φ_qᵀ) λ = Φ_q M⁻¹ Q − γ,

one Cholesky solve per state where Φ_q has full row rank. Where it has not (redundant
constraints; a singular configuration) λ is not unique: any λ + null(Φ_qᵀ) satisfies the
equations. There the minimum-norm λ is given (from the SVD of J̃ = Φ_q M^{-1/2}: components
along the left singular vectors of the dropped singular values are zero) and the rows of
Φ that share those directions are flagged.

A state counts as rank deficient where σ_min/σ_max of J̃ is below `INDETERMINATE`, that is
where S = J̃J̃ᵀ is singular to working precision (its condition beyond 1/(machine ε)); above
it λ is unique and accurate to about ε (σ_max/σ_min)² relative. Inside a singular passage
the cut is `BAND` instead, the projection method's truncation cut: there the motion itself
was computed without the directions under it, and λ along them, unique only at the exact
configuration's neighbourhood and there amplified by 1/σ², is left out the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# σ_min/σ_max of Φ_q M^{-1/2} below which λ is not unique to working precision.
INDETERMINATE = 1e-8
# The same inside a singular passage (the projection method's truncation cut, `rcond`).
BAND = 1e-4
# A row belongs to an undetermined direction where its entry in the left singular vector
# exceeds this (unit vectors; rows outside the direction hold round-off).
ROW_WEIGHT = 1e-6


@dataclass
class Multipliers:
    """λ at N states: `lam` (N, m); `indeterminate` (N, m) bool, the rows whose share of λ
    is not unique at each state (all False where Φ_q has full row rank); `dropped` (N,)
    the number of directions left out at each."""
    lam: np.ndarray
    indeterminate: np.ndarray
    dropped: np.ndarray | None = None

    def __post_init__(self):
        if self.dropped is None:
            self.dropped = np.zeros(len(self.lam), dtype=int)

    @property
    def flagged(self) -> np.ndarray:
        """(N,) bool: states where some reactions are not unique."""
        return self.indeterminate.any(axis=1)


def multipliers(problem, T, Q, V, passages=None) -> Multipliers:
    """λ at the consistent states (T[i], Q[i], V[i]) of `problem`, shapes (N,), (N, n),
    (N, n). `passages`: (t_start, t_end) of the singular passages a run's monitor recorded
    (their samples are cut at `BAND`), or None where no monitor watched the states (a
    kinematic analysis). The problem's constraint algebra solves, where it is compiled
    (`ConstraintAlgebra.multipliers`), the states where S is positive definite and
    clearly conditioned in one call; the rest, and every state where it is not compiled,
    are solved here."""
    T = np.asarray(T, float)
    N, m = len(T), problem.m
    lam = np.zeros((N, m))
    flags = np.zeros((N, m), dtype=bool)
    dropped = np.zeros(N, dtype=int)
    if m == 0 or N == 0:
        return Multipliers(lam, flags, dropped)
    F = problem.forces_at(T, Q, V)
    inside = np.zeros(N, dtype=bool)
    for t_start, t_end in passages or ():
        inside |= (T >= t_start) & (T <= t_end)
    algebra = problem.algebra
    done = np.zeros(N, dtype=bool)
    for group, cut, estimate in _groups(problem, T, Q, inside, passages is not None):
        k = np.flatnonzero(group)
        if k.size:
            part = np.zeros((k.size, m))
            # 1/κ₁ of S under-estimates 1/κ₂ = (σ_min/σ_max)² by at most a factor m;
            # a Cholesky pivot is never below S's smallest eigenvalue.
            rcond = m * cut ** 2 if estimate else -1.0
            ok = algebra.multipliers(T[k], Q[k], V[k], F[k], rcond, cut ** 2, part)
            if ok is None:                    # not compiled: every state is solved below
                break
            done[k] = ok
            lam[k] = part
    todo = np.flatnonzero(~done)
    for i in todo:
        cut = BAND if inside[i] else INDETERMINATE
        lam[i], flags[i], dropped[i] = _one(problem, T[i], Q[i], V[i], F[i], cut)
    return Multipliers(lam, flags, dropped)


def _groups(problem, T, Q, inside, watched):
    """(samples, cut, whether their condition must be estimated) for the compiled path:
    inside the passages at `BAND`, with LAPACK's estimate; outside at `INDETERMINATE`. There
    the monitor saw S clear of singular configurations all along, and its Cholesky pivots
    are checked only, unless Φ_q is rank deficient at the first sample (redundant
    constraints) or no monitor watched the states. (A generator: Φ_q's rank is computed
    only if the first group was solved compiled.)"""
    yield inside, BAND, True
    J = problem.phi_q(Q[0], T[0])
    s = np.linalg.svd(J, compute_uv=False)
    full = s.size == J.shape[0] and s[-1] > INDETERMINATE * s[0]
    yield ~inside, INDETERMINATE, not (full and watched)


def _one(problem, t, q, v, F, cut):
    """(λ, indeterminate rows, directions dropped) at one state, cut at σ < cut σ_max."""
    from .mass import dense
    J, gamma = problem.dynamics_terms(q, v, t)
    f = problem.mass_factor(q)
    Jt, x = f.cols(J), f.left(F)
    b = Jt @ x - gamma
    band = problem.solver.band
    none = np.zeros(problem.m, dtype=bool)
    if band is not None and cut == INDETERMINATE:
        c = band.factor(J)
        if c is not None:
            return band.solve(c, b), none, 0
    elif band is None:
        # 1/κ₁ of S under-estimates 1/κ₂ = (σ_min/σ_max)² by at most a factor m.
        c, rcond = dense().cholesky_rcond(Jt @ Jt.T)
        if c is not None and rcond > problem.m * cut ** 2:
            return dense().cho_solve(c, b), none, 0
    return minimum_norm(Jt, b, cut)


def static(problem, t, q) -> Multipliers:
    """λ of a mechanism at rest in equilibrium at (t, q): Φ_qᵀ λ = Q(t, q, 0), the least-
    squares λ of least norm where Φ_q has not full row rank (rows flagged as in
    `multipliers`), one state."""
    J = problem.phi_q(q, t)
    Q = problem.forces(t, q, np.zeros_like(q))
    U, s, Vt = np.linalg.svd(J, full_matrices=True)
    k, rows = _kept(U, s, INDETERMINATE)
    lam = U[:, :k] @ ((Vt[:k] @ Q) / s[:k])
    return Multipliers(lam[None], rows[None], np.array([U.shape[1] - k]))


def minimum_norm(Jt, b, cut=INDETERMINATE):
    """(λ, rows, count) of J̃J̃ᵀ λ = b with the least ‖λ‖ (the directions of the SVD of J̃
    with σ < cut σ_max, `count` of them, get no share) and the rows of those directions."""
    U, s, _ = np.linalg.svd(Jt, full_matrices=True)
    k, rows = _kept(U, s, cut)
    Uk = U[:, :k]
    lam = Uk @ ((Uk.T @ b) / s[:k] ** 2)
    return lam, rows, U.shape[1] - k


def _kept(U, s, cut):
    """(k, rows) of an SVD U diag(s) …: the count of singular values above
    cut σ_max, and the rows (m,) with a share above `ROW_WEIGHT` in the directions past
    them (the left singular vectors U[:, k:])."""
    k = int(np.sum(s > cut * (s[0] if s.size else 0.0)))
    dropped = U[:, k:]
    rows = np.max(np.abs(dropped), axis=1) > ROW_WEIGHT if dropped.size else \
        np.zeros(U.shape[0], dtype=bool)
    return k, rows
