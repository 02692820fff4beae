"""Coordinate bases of a partition, q = q_ref + B z + D w, and the factored dependent block
Φ_q D that the partitioned formulations solve with."""

from __future__ import annotations

import numpy as np

from ..linalg import dense, sparse

# Dependent blocks Φ_q D at least this large are factored sparse (`BandBlock`, else
# `SparseBlock`).
SPARSE_MIN = 40
# Band layouts kept by their pattern (`band_layout`), at most.
LAYOUTS_KEPT = 64
_LAYOUTS: dict = {}


class ConstraintSolveError(RuntimeError):
    """Newton on the dependent coordinates did not converge; names the worst joint."""


def solve(A, b):
    if A.shape[0] == A.shape[1]:
        return dense.solve(A, b)
    return np.linalg.lstsq(A, b, rcond=None)[0]


def condition_number(A, inv=None) -> float:
    """1-norm condition number ‖A‖₁ ‖A⁻¹‖₁ (inf if singular); an explicit inverse of the
    small Φ_u is cheaper than the SVD behind np.linalg.cond. Pass `inv` if it is known."""
    if A.size == 0:
        return 1.0                      # no constraints: nothing to condition
    if A.shape[0] != A.shape[1]:
        return float(np.linalg.cond(A))
    if inv is None:
        try:
            inv = dense.inv(A)
        except np.linalg.LinAlgError:
            return np.inf
    return float(np.abs(A).sum(axis=0).max() * np.abs(inv).sum(axis=0).max())


class DenseBlock:
    """Φ_q D as a dense matrix. `solve` is LAPACK's (least squares when the block is not
    square: redundant constraints); the chord iteration and the condition number use the
    explicit inverse, formed once: one small matmul per chord iteration instead of a
    solve through scipy's wrapper."""

    def __init__(self, A, inverse=False, sign=None, condition=None, reduced=None):
        """A = Φ_q D; its inverse, the sign of det A, cond₁ A and A⁻¹ Φ_q B (`reduced`)
        where they were computed together already (the compiled end of a step)."""
        self.A, self._inv, self._sign = A, inverse, sign
        self._condition, self.reduced = condition, reduced

    def solve(self, b):
        return solve(self.A, b)

    def inverse(self):
        """A⁻¹, formed once; None if A is singular or not square."""
        if self._inv is False:
            self._factor()
        return self._inv

    def _factor(self):
        """A⁻¹ and the sign of det A from one LU factorisation (a square A; a non-square
        one has neither)."""
        if self.A.shape[0] != self.A.shape[1]:
            self._inv, self._sign = None, 0
        else:
            self._inv, self._sign = dense.inv_and_sign(self.A)

    def chord(self, b):
        inv = self.inverse()
        return self.solve(b) if inv is None else inv @ b

    def condition(self) -> float:
        if self._condition is None:
            self._condition = condition_number(self.A, self.inverse())
        return self._condition

    def sign(self) -> int:
        """The sign of det A (0 where A is singular or not square), computed once."""
        if self._sign is None:
            self._factor()
        return self._sign


class SparseBlock:
    """Φ_q D of a long chain (hundreds of dependent coordinates, four non-zeros a row)
    factored by SuperLU, an order of magnitude cheaper than the dense inverse there. The
    condition
    number is the 1-norm estimate of Hager and Higham (as LAPACK's condition estimators),
    with one probe vector: more would be drawn from numpy's global random generator, which
    would make re-partitioning, and so whole runs, depend on the caller's random state."""

    def __init__(self, A):
        from scipy.sparse.linalg import splu
        self.A = A
        try:
            self.lu = splu(A)
        except RuntimeError:                 # exactly singular
            self.lu = None

    def solve(self, b):
        if self.lu is None:
            raise np.linalg.LinAlgError("Singular matrix")
        return self.lu.solve(np.asarray(b, float))

    chord = solve

    def sign(self) -> int:
        """The sign of det A from SuperLU's factors P_r A P_c = L U (L unit diagonal)."""
        if self.lu is None:
            return 0
        u = np.sign(self.lu.U.diagonal())
        return int(np.prod(u) * _parity(self.lu.perm_r) * _parity(self.lu.perm_c))

    def condition(self) -> float:
        if self.lu is None:
            return np.inf
        from scipy.sparse.linalg import LinearOperator, onenormest
        lu = self.lu
        op = LinearOperator(self.A.shape, matvec=lu.solve, dtype=float,
                            rmatvec=lambda x: lu.solve(x, trans="T"))
        return float(abs(self.A).sum(axis=0).max() * onenormest(op, t=1))


class BandBlock:
    """Φ_q D of a long chain as a band: its constraints and dependent coordinates taken in
    an order that makes it one (`CoordinateBasis`: a window's few constraints and
    coordinates next to its neighbours'), factored by LAPACK's banded LU with partial
    pivoting (dgbtrf), O(r kl (kl + ku)): a few times cheaper than SuperLU's ordering and
    factorisation at a chain's kl, ku of a few. Its solves (dgbtrs), the sign of det A
    (U's diagonal, the pivots' and both orders' parities) and cond₁ A (LAPACK's estimate,
    dgbcon, with ‖A‖₁ from the entries) as `SparseBlock`'s."""

    def __init__(self, band, kl, ku, rows, cols, parity, values, columns):
        """`band`: the permuted A in LAPACK's banded storage (2 kl + ku + 1 rows, kl of
        them for the pivots' fill); `rows`, `cols`: the orders (A's rows `rows` and
        columns `cols` are the band's); `parity` theirs together; `values`, `columns`: A's
        entries and their columns (for ‖A‖₁)."""
        from scipy.linalg import lapack
        self._lapack = lapack
        self.kl, self.ku, self._rows, self._cols = kl, ku, rows, cols
        self._parity, self._values, self._columns = parity, values, columns
        self._lu, self._piv, info = lapack.dgbtrf(band, kl, ku, overwrite_ab=1)
        self.singular = info != 0
        self._condition = None

    def solve(self, b):
        if self.singular:
            raise np.linalg.LinAlgError("Singular matrix")
        b = np.asarray(b, float)
        x, info = self._lapack.dgbtrs(self._lu, self.kl, self.ku, b[self._rows], self._piv)
        if info != 0:
            raise np.linalg.LinAlgError(f"dgbtrs: info {info}")
        out = np.empty_like(x)
        out[self._cols] = x
        return out

    chord = solve

    def sign(self) -> int:
        """The sign of det A: P A' = L U (L unit lower) for the permuted A'."""
        if self.singular:
            return 0
        swaps = int(np.count_nonzero(self._piv != np.arange(self._piv.size)))
        u = np.sign(self._lu[self.kl + self.ku])
        return int(np.prod(u)) * (-1 if swaps % 2 else 1) * self._parity

    def condition(self) -> float:
        if self._condition is None:
            if self.singular:
                self._condition = np.inf
            else:
                anorm = float(np.bincount(self._columns, np.abs(self._values)).max())
                rcond, info = self._lapack.dgbcon(self.kl, self.ku, self._lu, self._piv,
                                                  anorm)
                self._condition = 1.0 / rcond if info == 0 and rcond > 0.0 else np.inf
        return self._condition


def band_layout(rows, cols, r, row_order):
    """An order of the columns of an r × r sparse matrix with entries at (rows, cols) that
    makes it a narrow band with its rows in `row_order` (a long chain's constraints in the
    order that makes its Schur complement a band, `BandedSchur.perm`): each column after
    the first of its rows. (row order, column order, kl, ku, each entry's place in the
    column-major banded storage of 2 kl + ku + 1 rows, the orders' parity together), or
    None where the band is not narrow (the banded LU's work r kl (kl + ku) above a
    sixteenth of the dense LU's r³/3). Kept by its pattern (`_LAYOUTS`): a chain's
    partitions recur (the hybrid tests one at every step of its way back to LU); the
    arrays returned are shared, never changed."""
    if not len(rows):
        return None
    key = (r, rows.tobytes(), cols.tobytes(), row_order.tobytes())
    if key in _LAYOUTS:
        return _LAYOUTS[key]
    if len(_LAYOUTS) >= LAYOUTS_KEPT:
        _LAYOUTS.clear()
    _LAYOUTS[key] = layout = _band_layout(rows, cols, r, np.asarray(row_order, np.intp))
    return layout


def _band_layout(rows, cols, r, row_order):
    at = np.empty(r, np.intp)
    at[row_order] = np.arange(r)
    first = np.full(r, r, np.intp)
    np.minimum.at(first, cols, at[rows])
    col_order = np.lexsort((np.arange(r), first)).astype(np.intp)
    col_at = np.empty(r, np.intp)
    col_at[col_order] = np.arange(r)
    i, j = at[rows], col_at[cols]
    kl, ku = int(max((i - j).max(), 0)), int(max((j - i).max(), 0))
    if 48 * kl * (kl + ku) > r * r:
        return None
    height = 2 * kl + ku + 1
    flat = (kl + ku + i - j) + j * height
    return row_order, col_order, kl, ku, flat, _parity(row_order) * _parity(col_order)


def _parity(perm) -> int:
    """+1 for an even permutation, −1 for an odd one (from its cycles)."""
    perm = np.asarray(perm)
    seen = np.zeros(perm.size, bool)
    odd = 0
    for start in range(perm.size):
        if seen[start]:
            continue
        length, k = 0, start
        while not seen[k]:
            seen[k], k, length = True, perm[k], length + 1
        odd += length - 1
    return -1 if odd % 2 else 1


class CoordinateBasis:
    """Independent / dependent subsets of q (columns of the identity), applied by indexing:
    no n × n products, which dominate for large mechanisms. With `pattern` (the rows and
    columns where Φ_q can be non-zero) and at least `SPARSE_MIN` dependent coordinates,
    Φ_q D is factored sparse: as a band where `row_order` (the constraints' band order of a
    long chain, `BandedSchur.perm`) makes it a narrow one, else by SuperLU."""

    def __init__(self, independent, dependent, pattern=None, row_order=None):
        self.ind = np.sort(np.asarray(independent, dtype=np.intp))
        self.dep = np.sort(np.asarray(dependent, dtype=np.intp))
        self.f, self.r = self.ind.size, self.dep.size
        # [z; w] in the order of q: one gather instead of two scattered updates.
        self._order = np.argsort(np.concatenate([self.ind, self.dep]))
        self._csc = None
        self._band = None
        self._pattern = pattern
        if pattern is not None and self.r >= SPARSE_MIN:
            rows, cols = (np.asarray(x, np.intp) for x in pattern)
            where = np.full(max(cols.max(initial=-1), self.dep.max(initial=-1)) + 1, -1)
            where[self.dep] = np.arange(self.r)
            keep = where[cols] >= 0
            rows, cols = rows[keep], cols[keep]
            new = where[cols]
            order = np.lexsort((rows, new))            # column-major, as CSC stores
            rows, cols, new = rows[order], cols[order], new[order]
            indptr = np.searchsorted(new, np.arange(self.r + 1))
            self._csc = (rows, cols, rows.copy(), indptr)
            self._value_columns = np.repeat(np.arange(self.r), np.diff(indptr))
            if row_order is not None and len(row_order) == self.r and \
                    rows.max(initial=-1) < self.r:            # a square block
                self._band = band_layout(rows, new, self.r, row_order)
        self._slots = None                 # where Φ_q D's entries sit in a CSR Φ_q
        self._jb = None                    # Φ_q B's entries and their places in a CSR Φ_q

    @property
    def sparse(self) -> bool:
        """Whether Φ_q D is factored sparse (`block`)."""
        return self._csc is not None

    def block(self, J):
        """Φ_q D at Φ_q = J (dense, or CSR: `mechsim.linalg.sparse`), ready to solve with
        (`DenseBlock` or `SparseBlock`)."""
        if self._csc is None or J.shape[0] != self.r:
            return DenseBlock(self.JD(J))
        rows, cols, indices, indptr = self._csc
        if not sparse.is_dense(J) and self._slots is None:
            self._slots = sparse.positions(J, rows, cols)
        values = sparse.values(J, rows, cols, self._slots)
        if self._band is not None:
            row_order, col_order, kl, ku, flat, parity = self._band
            height = 2 * kl + ku + 1
            band = np.zeros(height * self.r)
            band[flat] = values
            return BandBlock(band.reshape(self.r, height).T, kl, ku, row_order, col_order,
                             parity, values, self._value_columns)
        from scipy.sparse import csc_matrix
        return SparseBlock(csc_matrix((values, indices, indptr), shape=(self.r, self.r)))

    def combine(self, base, z, w):
        return base + self.assemble(z, w)

    def assemble(self, z, w):
        """B z + D w."""
        return np.concatenate((z, w))[self._order]

    def JB(self, J):
        """Φ_q B (dense); from a CSR Φ_q by its pattern's entries in B's columns, their
        places found once (`sparse.positions`, as `block`'s), without scipy's column
        indexing."""
        if sparse.is_dense(J):
            return J[..., self.ind]
        if self._pattern is None:
            return sparse.columns(J, self.ind)
        if self._jb is None:
            rows, cols = (np.asarray(x, np.intp) for x in self._pattern)
            on_b = np.isin(cols, self.ind)
            rows, cols = rows[on_b], cols[on_b]
            self._jb = (rows, cols, np.searchsorted(self.ind, cols),
                        sparse.positions(J, rows, cols))
        rows, cols, k, slots = self._jb
        out = np.zeros((J.shape[0], self.f))
        out[rows, k] = sparse.values(J, rows, cols, slots)
        return out

    def JD(self, J):
        return J[..., self.dep] if sparse.is_dense(J) else sparse.columns(J, self.dep)

    def Bt(self, x):
        return x[self.ind]

    def Dt(self, x):
        return x[self.dep]


class MatrixBasis(CoordinateBasis):
    """Orthonormal complementary bases B (n × f) and D (n × r), e.g. from an SVD."""

    def __init__(self, B, D):
        self.B, self.D = B, D
        self.f, self.r = B.shape[1], D.shape[1]
        self._csc = None

    def combine(self, base, z, w):
        return base + self.B @ z + self.D @ w

    def assemble(self, z, w):
        return self.B @ z + self.D @ w

    def JB(self, J):
        return J @ self.B

    def JD(self, J):
        return J @ self.D

    def Bt(self, x):
        return self.B.T @ x

    def Dt(self, x):
        return self.D.T @ x
