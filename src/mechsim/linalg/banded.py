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
three solves settle it), the largest by Lanczos from the previous call's vector, certified
by a Cholesky factor of a shifted S, else from LAPACK's banded eigensolver. This is what the
projection method and the singularity monitor need; near a singular configuration the
smallest comes from a factor of S shifted by round-off (`BandedAlgebra.extremes`), and
where the iteration does not settle the callers use the dense SVD.
"""

from __future__ import annotations

import numpy as np

from . import sparse

# Below this many constraints the dense LAPACK path (`mechsim.linalg.dense`) is as fast.
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
        self._pairs = (first, second, col)
        self._pattern, self._where = (rows, cols), where
        self._lu_layout = None                # see `pivoted_coordinates`
        self._ia, self._ib = first * n + col, second * n + col
        self._csr = None                   # the pairs' slots in a CSR Φ_q's data
        self._slot = (self.kd + where[first] - where[second]) * m + where[second]
        self.weights = np.asarray(weights, float)
        self._wpair = self.weights[col]
        self._low = self._high = None      # latest eigenvectors (warm starts)

    def forget(self):
        """Drop the warm starts, so that a run does not depend on the runs before it."""
        self._low = self._high = None

    def assemble(self, J, scaled=False):
        """S in band storage ((kd + 1) × m); `scaled`: J is already J̃ = J W^{1/2}. J is
        dense or a CSR array of its pattern (`mechsim.linalg.sparse`)."""
        if isinstance(J, np.ndarray):
            v, ia, ib = J.ravel(), self._ia, self._ib
        else:
            if self._csr is None:
                first, second, col = self._pairs
                self._csr = (sparse.positions(J, first, col), sparse.positions(J, second, col))
            v, (ia, ib) = J.data, self._csr
        prod = v[ia] * v[ib]
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

    def shifted_factor(self, delta, sign=1.0):
        """The banded Cholesky factor of the latest sign · S + δ I, or None where that is
        not positive definite."""
        shifted = sign * self._band
        shifted[self.kd] += delta
        c, info = self._pbtrf(shifted)
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
        kd, m, ab = self.kd, self.m, np.abs(self._band)
        # the column sums of |S| as `_full_band`'s rows add them, in its order: the upper
        # triangle's diagonals, then the lower's (each the upper one shifted)
        total = ab[0].copy()
        for d in range(1, kd + 1):
            total += ab[d]
        for d in range(1, kd + 1):
            total[:m - d] += ab[kd - d, d:]
        return float(total.max())

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

    def _matvec(self, x):
        """S x for x in the band's (permuted) order."""
        kd, m, ab = self.kd, self.m, self._band
        y = ab[kd] * x
        for d in range(1, kd + 1):
            row = ab[kd - d, d:]                      # S[i, i + d]
            y[:m - d] += row * x[d:]
            y[d:] += row * x[:m - d]
        return y

    def largest(self, rtol=1e-3):
        """(λ_max, u) of the latest S, to `rtol` relative (what the singularity monitor's
        ratios σ_min/σ_max need). From the previous call's vector, Lanczos (`top_pair`,
        O(m kd) a product) settles in a few products, consecutive calls being close; its
        value θ is certified the largest to `rtol` by the banded Cholesky factor of
        θ (1 + rtol) I − S (O(m kd²)), which exists only if no eigenvalue of S is above
        θ (1 + rtol) (the top of a long chain's spectrum is crowded with alike joints, and
        where two of its eigenvalues cross, the previous vector leads Lanczos to one below
        the top). The first call, or one not so settled, takes the eigenvalue from
        LAPACK's banded solver (dsbevx, that one value only: its reduction to tridiagonal
        form is O(m² kd)) and its vector by inverse iteration shifted just past it (two
        steps, more until its residual is under `rtol` λ_max). Lanczos from a cold start,
        or power iteration, would crawl."""
        if self._high is not None:
            found = top_pair(self._matvec, self._high[self.perm], rtol)
            if found is not None and self._all_below(found[0] * (1.0 + rtol)):
                u = np.empty(self.m)
                u[self.perm] = found[1]
                self._high = u
                return found[0], u
        from scipy.linalg import eigvals_banded, solve_banded
        kd, m = self.kd, self.m
        lam = float(eigvals_banded(self._band, select="i", select_range=(m - 1, m - 1),
                                   check_finite=False)[0])
        full = self._full_band()
        full[kd] -= lam * (1.0 + 1e-10) + 1e-300
        u = self._high if self._high is not None else np.ones(m) / np.sqrt(m)
        # Rows of the band are in the permuted order.
        x = u[self.perm]
        for k in range(8):
            x = solve_banded((kd, kd), full, x, check_finite=False)
            x /= np.linalg.norm(x)
            # Two steps settle it from a start with a part along the top eigenvector;
            # from one without (the next eigenvector's, where they crossed), round-off
            # brings that part in and a few more do.
            if k and np.linalg.norm(self._matvec(x) - lam * x) <= rtol * lam:
                break
        u = np.empty_like(x)
        u[self.perm] = x
        self._high = u
        return lam, u

    def _all_below(self, mu) -> bool:
        """Are all eigenvalues of the latest S below `mu`? (μ I − S has a Cholesky factor.)"""
        return self.shifted_factor(mu, -1.0) is not None

    def _layout(self):
        """Jᵀ (n × m) as a band: its columns (the constraints) in the order of S, its rows
        (the coordinates) by the first of their constraints in that order; (row order,
        where each pattern entry goes in LAPACK's general band storage, kl, ku)."""
        if self._lu_layout is None:
            rows, cols = self._pattern
            b = self._where[rows]                           # column of Jᵀ
            first = np.full(self.n, self.m, np.intp)
            np.minimum.at(first, cols, b)
            order = np.lexsort((np.arange(self.n), first))  # row order of Jᵀ
            a = np.empty(self.n, np.intp)
            a[order] = np.arange(self.n)
            a = a[cols]
            kl, ku = int(max(np.max(a - b, initial=0), 0)), int(max(np.max(b - a, initial=0), 0))
            self._lu_layout = (order, (kl + ku + a - b, b), kl, ku)
        return self._lu_layout

    def pivoted_coordinates(self, J) -> np.ndarray:
        """The coordinates in the order LU with partial pivoting of Φ_qᵀ = Jᵀ picks them
        (the first rank of them are a partition's dependent ones, as
        `scipy.linalg.lu_factor` of the dense Jᵀ gives them), from LAPACK's banded LU
        (dgbtrf) of Jᵀ laid out as a band: O(n kl (kl + ku)) where the dense LU is
        O(n m²). The constraints are taken in the band's order, so
        the pivots may differ from the dense LU's; they are as good a choice."""
        from scipy.linalg import lapack
        order, (slot_row, slot_col), kl, ku = self._layout()
        ab = np.zeros((2 * kl + ku + 1, self.m))
        ab[slot_row, slot_col] = sparse.values(J, *self._pattern)
        _, ipiv, info = lapack.dgbtrf(ab, kl, ku, m=self.n, n=self.m)
        if info < 0:
            raise ValueError(f"dgbtrf: argument {-info} is illegal")
        perm = np.arange(self.n)
        for i, p in enumerate(ipiv):
            perm[i], perm[p] = perm[p], perm[i]
        return order[perm]


def takes(m: int, constant_mass: bool) -> bool:
    """Does the banded path take a mechanism of `m` constraint equations (with a constant
    diagonal mass, or not)? Where it does not, the dense one serves (and the compiled
    engine with it)."""
    return constant_mass and m >= MIN_CONSTRAINTS


def for_problem(problem):
    """The problem's BandedSchur, or None where the dense path serves (`takes`; or a model
    without the pattern)."""
    model = problem.model
    if not takes(problem.m, problem.constant_mass) or not hasattr(model, "JACOBIAN_ROWS"):
        return None
    return BandedSchur(model.JACOBIAN_ROWS, model.JACOBIAN_COLS, (problem.m, problem.n),
                       problem.inverse_mass_diagonal)


def top_pair(matvec, start, rtol=1e-3, max_products=24):
    """(λ_max, its unit eigenvector) of the symmetric operator `matvec` by Lanczos from
    `start`, every new basis vector orthogonalized against all before it (the basis is a
    few vectors): the top Ritz pair (θ, x) once its residual ‖A x − θ x‖, read from the
    recurrence as β_j |s_j|, is at most `rtol` θ (ARPACK's test); None where it is not
    within `max_products` products. Unlike a restarted Lanczos it keeps every product's
    information, so a start near the top eigenvector settles in a few."""
    m = start.size
    V = np.empty((max_products + 1, m))
    norm = np.linalg.norm(start)
    if not norm > 0.0:
        return None
    V[0] = start / norm
    T = np.zeros((max_products, max_products))
    for j in range(max_products):
        w = matvec(V[j])
        T[j, j] = w @ V[j]
        w -= V[:j + 1].T @ (V[:j + 1] @ w)
        w -= V[:j + 1].T @ (V[:j + 1] @ w)          # twice is enough (Kahan)
        beta = float(np.linalg.norm(w))
        theta, S = np.linalg.eigh(T[:j + 1, :j + 1])
        top, s = float(theta[-1]), S[:, -1]
        if top > 0.0 and (beta * abs(s[-1]) <= rtol * top or beta <= 1e-300):
            x = V[:j + 1].T @ s
            return top, x / np.linalg.norm(x)
        if j + 1 < max_products:
            V[j + 1] = w / beta
            T[j, j + 1] = T[j + 1, j] = beta
    return None

