"""Φ_q of a long chain as a CSR matrix of a fixed pattern.

An assembled model (`mechsim.assembly`) gives Φ_q as a `scipy.sparse.csr_array` whose
entries are its pattern's (`JACOBIAN_ROWS`, `JACOBIAN_COLS`), one per entry, in row-major
order, at every call: structural zeros are kept, so the same (row, column) always sits at
the same place in `data`. A long chain's solvers (`NumericProblem.sparse`) work with it
where a dense m × n array would cost O(mn) to fill, scale and multiply: gathers become
indexing into `data`, products CSR products. These helpers take either form, so that the
code around them reads the same for a four-bar and a chain of hundreds of windows.
"""

from __future__ import annotations

import copy

import numpy as np


def is_dense(J) -> bool:
    return isinstance(J, np.ndarray)


def dense(J) -> np.ndarray:
    """J as a dense array (itself if it is one)."""
    return J if is_dense(J) else J.toarray()


def positions(J, rows, cols) -> np.ndarray:
    """Where the entries (rows[k], cols[k]) of the CSR matrix J sit in `J.data`. Raises
    ValueError if one is not in its pattern."""
    m, n = J.shape
    counts = np.diff(J.indptr)
    keys = np.repeat(np.arange(m, dtype=np.int64), counts) * n + J.indices
    wanted = np.asarray(rows, np.int64) * n + np.asarray(cols, np.int64)
    at = np.searchsorted(keys, wanted)
    if wanted.size and (at.max() >= keys.size or np.any(keys[np.minimum(at, keys.size - 1)]
                                                            != wanted)):
        raise ValueError("an entry is outside the Jacobian's sparsity pattern")
    return at


def values(J, rows, cols, where=None):
    """J[rows, cols] as a 1-d array; `where`: their `positions` in a CSR J, if known."""
    if is_dense(J):
        return J[rows, cols]
    return J.data[positions(J, rows, cols) if where is None else where]


def template(indices, indptr, shape):
    """A CSR array of the pattern (`indices`, `indptr`: sorted within each row, without
    duplicates) holding zeros, its structure checked by scipy once: `with_data` gives each
    evaluation's matrix from it."""
    from scipy.sparse import csr_array
    return csr_array((np.zeros(len(indices)), indices, indptr), shape=shape)


def with_data(J, data):
    """The CSR matrix of J's pattern holding `data` (float, one value per entry of J.data):
    a shallow copy of J, its index arrays shared (never changed in place: the pattern is
    sorted and without duplicates). scipy's constructor checks the whole structure each
    time, and a long chain's run makes thousands of them (docs/benchmarks.md)."""
    out = copy.copy(J)
    out.data = data
    return out


def transpose_times(J, x):
    """Jᵀ x for x of shape (m,), without forming Jᵀ (scipy builds and checks a CSC matrix
    for `J.T`); the sums in the order of J's entries, as scipy's product of Jᵀ."""
    if is_dense(J):
        return J.T @ x
    return np.bincount(J.indices, weights=J.data * x[_entry_rows(J.indptr)],
                       minlength=J.shape[1])


# The row of each entry, for the last few patterns' row pointers (matrices of one pattern
# share theirs: `with_data`): {id(indptr): (indptr, rows)}, the array kept so that its id
# stays its own.
_ROWS: dict = {}


def _entry_rows(indptr) -> np.ndarray:
    kept = _ROWS.get(id(indptr))
    if kept is not None and kept[0] is indptr:
        return kept[1]
    rows = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
    if len(_ROWS) >= 8:
        _ROWS.pop(next(iter(_ROWS)))
    _ROWS[id(indptr)] = (indptr, rows)
    return rows


def scale_columns(J, s):
    """J diag(s)."""
    if is_dense(J):
        return J * s
    return with_data(J, J.data * s[J.indices])


def difference(J1, J0, scale=1.0):
    """(J1 − J0) · scale, for two Jacobians of the same pattern."""
    if is_dense(J1):
        return (J1 - J0) * scale
    return with_data(J1, (J1.data - J0.data) * scale)


def frobenius(J) -> float:
    """‖J‖_F."""
    return float(np.linalg.norm(J if is_dense(J) else J.data))


def columns(J, index) -> np.ndarray:
    """J[:, index] as a dense array."""
    return J[:, index] if is_dense(J) else J[:, index].toarray()
