"""The Schur complement S = Φ_q W Φ_qᵀ of a large rigid mechanism, factored as a band.

For rigid bodies W = M⁻¹ is diagonal, and the rows of a joint touch only its own two bodies,
so S_ij is non-zero only where joints i and j share a body. Renumbering the constraints by
reverse Cuthill–McKee (scipy.sparse.csgraph) puts those entries in a narrow band around the
diagonal: half-bandwidth 5 for the 40-window four-bar's 242 constraints, from the generated
code's pattern of Φ_q (`JACOBIAN_ROWS`, `JACOBIAN_COLS`). S is then assembled from the dense
Φ_q by one gather and one `bincount`, and factored by banded Cholesky (LAPACK dpbtrf): work
O(m b²) in place of the O(m³) of a dense Cholesky or SVD.

The same factor gives the extreme eigenvalues of S, which are the squared extreme singular
values of the mass-scaled Jacobian J̃ = Φ_q M^{-1/2}: the smallest by inverse iteration from
the previous call's vector (consecutive evaluations of an integrator are close, so two or
three solves settle it), the largest from LAPACK's banded eigensolver. This is what the
projection method and the singularity monitor need away from a singular configuration; near
one (S nearly singular, or the iteration not settling) the callers use the dense SVD.
"""

from __future__ import annotations

import numpy as np

# Below this many constraints the dense LAPACK path (`mechsim.dense`) is as fast.
MIN_CONSTRAINTS = 40


class BandedSchur:
    """S = J diag(w) Jᵀ in LAPACK's upper band storage, for Jacobians J (m × n, dense
    arrays) whose non-zeros lie within the pattern (`rows`, `cols`)."""

    def __init__(self, rows, cols, shape, weights):
        import scipy.sparse as sp
        from scipy.linalg import lapack
        from scipy.sparse.csgraph import reverse_cuthill_mckee

        self._pbtrf, self._pbtrs = lapack.dpbtrf, lapack.dpbtrs
        m, n = shape
        rows, cols = np.asarray(rows, np.intp), np.asarray(cols, np.intp)
        pattern = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=shape)
        graph = (pattern @ pattern.T).tocsr()
        self.perm = np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), np.intp)
        where = np.empty(m, np.intp)
        where[self.perm] = np.arange(m)            # new position of each constraint
        # Every pair of entries in one column of J adds to one entry of S.
        by_col = [[] for _ in range(n)]
        for i, j in zip(rows.tolist(), cols.tolist()):
            by_col[j].append(i)
        first, second, col = [], [], []
        for j, members in enumerate(by_col):
            for a in members:
                for b in members:
                    if where[a] <= where[b]:
                        first.append(a)
                        second.append(b)
                        col.append(j)
        first, second, col = (np.array(x, np.intp) for x in (first, second, col))
        self.m, self.n = m, n
        self.kd = int(np.max(where[second] - where[first], initial=0))
        self._ia, self._ib = first * n + col, second * n + col
        self._slot = (self.kd + where[first] - where[second]) * m + where[second]
        self.weights = np.asarray(weights, float)
        self._wpair = self.weights[col]
        self._low = self._high = None      # latest eigenvectors (warm starts)

    def forget(self):
        """Drop the warm starts, so that a run does not depend on the runs before it."""
        self._low = self._high = None

    def assemble(self, J, scaled=False):
        """S in band storage ((kd + 1) × m); `scaled`: J is already J̃ = J W^{1/2}."""
        v = J.ravel()
        prod = v[self._ia] * v[self._ib]
        if not scaled:
            prod *= self._wpair
        return np.bincount(self._slot, prod, minlength=(self.kd + 1) * self.m).reshape(
            self.kd + 1, self.m)

    def factor(self, J, scaled=False):
        """The banded Cholesky factor of S, or None when S is not numerically positive
        definite (a singular configuration or redundant constraints). S itself is kept for
        `largest` and `largest_bound`."""
        self._band = self.assemble(J, scaled)
        c, info = self._pbtrf(self._band)
        return c if info == 0 else None

    def solve(self, c, r):
        """S⁻¹ r from the factor `c`, in the original order of the constraints."""
        x, _ = self._pbtrs(c, r[self.perm])
        out = np.empty_like(x)
        out[self.perm] = x
        return out

    def _full_band(self):
        """The latest S with both triangles, in `solve_banded`'s (kd, kd) storage."""
        kd, ab = self.kd, self._band
        full = np.zeros((2 * kd + 1, self.m))
        full[:kd + 1] = ab
        for d in range(1, kd + 1):
            full[kd + d, :self.m - d] = ab[kd - d, d:]
        return full

    def largest_bound(self) -> float:
        """An upper bound of λ_max of the latest S (Gershgorin: the largest absolute column
        sum), for tests that must not under-rate it."""
        return float(np.abs(self._full_band()).sum(axis=0).max())

    def smallest(self, c, rtol=1e-3, max_iter=12):
        """(λ_min, u) of S by inverse iteration with its factor `c`, from the previous call's
        vector; None if it does not settle to `rtol` within `max_iter` (nearly equal
        smallest eigenvalues). u is a unit vector in the original order."""
        u = self._low if self._low is not None else np.ones(self.m) / np.sqrt(self.m)
        lam = None
        for _ in range(max_iter):
            y = self.solve(c, u)
            new = 1.0 / float(u @ y)                       # Rayleigh quotient of S⁻¹
            u = y / np.linalg.norm(y)
            if lam is not None and abs(new - lam) <= rtol * new:
                self._low = u
                return new, u
            lam = new
        return None

    def largest(self):
        """(λ_max, u) of the latest S: the eigenvalue from LAPACK's banded solver (dsbevx,
        that one value only), its vector by two steps of inverse iteration shifted just
        past it. The top of a long chain's spectrum is crowded (many alike joints), where
        power iteration would crawl."""
        from scipy.linalg import eigvals_banded, solve_banded
        kd, m = self.kd, self.m
        lam = float(eigvals_banded(self._band, select="i", select_range=(m - 1, m - 1),
                                   check_finite=False)[0])
        full = self._full_band()
        full[kd] -= lam * (1.0 + 1e-10) + 1e-300
        u = self._high if self._high is not None else np.ones(m) / np.sqrt(m)
        # Rows of the band are in the permuted order.
        x = u[self.perm]
        for _ in range(2):
            x = solve_banded((kd, kd), full, x, check_finite=False)
            x /= np.linalg.norm(x)
        u = np.empty_like(x)
        u[self.perm] = x
        self._high = u
        return lam, u


def for_problem(problem):
    """The problem's BandedSchur, or None where the dense path serves (few constraints, a
    mass matrix that is not constant and diagonal, or a model without the pattern)."""
    model = problem.model
    if not problem.constant_mass or problem.m < MIN_CONSTRAINTS or \
            not hasattr(model, "JACOBIAN_ROWS"):
        return None
    return BandedSchur(model.JACOBIAN_ROWS, model.JACOBIAN_COLS, (problem.m, problem.n),
                       problem.inverse_mass_diagonal)
