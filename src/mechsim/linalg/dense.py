"""Small dense linear algebra straight from LAPACK (through scipy's wrappers).

The matrices of a mechanism's right-hand side are small (Φ_q of the double four-bar is
14 × 15), so `np.linalg`'s per-call bookkeeping (type dispatch, error-state context,
stacked-array checks) costs as much as the factorisation (docs/design-notes.md). These
functions have the `np.linalg`
meaning and raise `np.linalg.LinAlgError` where it does.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

_gesv, _posv, _getrf, _getri = lapack.dgesv, lapack.dposv, lapack.dgetrf, lapack.dgetri
_gesdd = lapack.dgesdd
_potrf, _pocon, _potrs = lapack.dpotrf, lapack.dpocon, lapack.dpotrs


def solve(A, b):
    """x with A x = b, A square; LinAlgError if A is exactly singular."""
    if A.size == 0:
        return np.zeros(np.shape(b))
    _, _, x, info = _gesv(A, b)
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    if info < 0:
        return np.linalg.solve(A, b)          # an argument LAPACK refused (never expected)
    return x


def solve_psd(S, r):
    """x with S x = r for symmetric positive semi-definite S (a Schur complement
    Φ_q M⁻¹ Φ_qᵀ): Cholesky, or the least-squares solution when S is singular (redundant
    constraints)."""
    if S.size == 0:
        return np.zeros(np.shape(r))
    _, x, info = _posv(S, r)
    if info == 0:
        return x
    return np.linalg.lstsq(S, r, rcond=None)[0]


def cholesky_conditioned(S, min_rcond):
    """The upper Cholesky factor of a symmetric positive definite S whose reciprocal
    condition number exceeds `min_rcond`, else None (see `cholesky_rcond`)."""
    c, rcond = cholesky_rcond(S)
    return c if c is not None and rcond > min_rcond else None


def cholesky_rcond(S):
    """(upper Cholesky factor, estimate of 1/κ₁) of a symmetric S; (None, 0) where S is not
    numerically positive definite. The condition is LAPACK's estimate (dpocon) with ‖S‖₁
    bounded above by m·max Sᵢᵢ (|Sᵢⱼ| ≤ max Sᵢᵢ for a positive definite S), which errs
    towards ill-conditioning; for symmetric S, 1/κ₂ ≥ 1/κ₁."""
    c = cho_factor_or_none(S)
    if c is None:
        return None, 0.0
    rcond, info = _pocon(c, S.shape[0] * max(S.diagonal().tolist()))
    return (c, float(rcond)) if info == 0 else (None, 0.0)


def cho_factor_or_none(S):
    """The upper Cholesky factor of S, or None if S is not numerically positive definite."""
    c, info = _potrf(S)
    return c if info == 0 else None


def cho_solve(c, r):
    """x with S x = r from the upper Cholesky factor c of S."""
    x, _ = _potrs(c, r)
    return x


def inv(A):
    """A⁻¹ of a square matrix; LinAlgError if A is exactly singular."""
    Ai, _, _ = _lu_inverse(A)
    if Ai is None:
        raise np.linalg.LinAlgError("Singular matrix")
    return Ai


def inv_and_sign(A):
    """(A⁻¹, sign of det A) of a square matrix from one LU factorisation, P A = L U:
    det A = (−1)^(row swaps) ∏ Uᵢᵢ (as `np.linalg.slogdet`'s sign). (None, 0) where A is
    exactly singular."""
    Ai, lu, piv = _lu_inverse(A)
    if Ai is None:
        return None, 0
    swaps = int(np.count_nonzero(piv != np.arange(len(piv))))
    negative = int(np.count_nonzero(np.diagonal(lu) < 0.0))
    return Ai, -1 if (swaps + negative) % 2 else 1


def _lu_inverse(A):
    """(A⁻¹, LU factors, pivots) of a square A by getrf and getri; A⁻¹ None where A is
    exactly singular."""
    if A.size == 0:
        return np.zeros(A.shape), np.zeros(A.shape), np.zeros(0, dtype=int)
    lu, piv, info = _getrf(A)
    if info == 0:
        Ai, info = _getri(lu, piv)
        if info == 0:
            return Ai, lu, piv
    return None, lu, piv


def svd(A):
    """Thin SVD (U, σ, Vᵀ) like `np.linalg.svd(A, full_matrices=False)`."""
    if 0 in A.shape:
        return np.linalg.svd(A, full_matrices=False)
    U, s, Vt, info = _gesdd(A, compute_uv=1, full_matrices=0)
    if info != 0:              # divide and conquer did not converge: numpy's own path
        return np.linalg.svd(A, full_matrices=False)
    return U, s, Vt


def svdvals(A):
    """The singular values only, largest first."""
    if 0 in A.shape:
        return np.zeros(0)
    _, s, _, info = _gesdd(A, compute_uv=0)
    if info != 0:
        return np.linalg.svd(A, compute_uv=False)
    return s


def extreme_bounds(J) -> tuple[float, float] | None:
    """(a lower bound of σ_min, an upper bound of σ_max) of J (m × n, m ≤ n) without an
    SVD, as the engine's `extreme_bounds` (C) takes them: with G = J Jᵀ and H = G⁻¹ (from
    G's Cholesky factor), the largest eigenvalue of each is at most its ‖·‖_F and ‖·²‖_F^½
    (within m^¼), σ_min lowered by 1e-6 and σ_max raised by 1e-12 of itself for
    round-off; None where G is not positive definite in floating point or so
    ill-conditioned that round-off could reach that margin."""
    J = np.asarray(J, dtype=float)
    m, n = J.shape
    G = J @ J.T
    U = cho_factor_or_none(G) if m else None          # G = Uᵀ U, so H = U⁻¹ U⁻ᵀ
    if U is None:
        return None
    X = lapack.dtrtri(np.triu(U))[0]
    H = X @ X.T
    with np.errstate(over="ignore", invalid="ignore"):
        top, inverse_top = (min(float(np.linalg.norm(S)), float(np.linalg.norm(S @ S)) ** 0.5)
                            for S in (G, H))
    if not (0.0 < inverse_top < math.inf and top > 0.0) or \
            not 4.0 * (m + n) * np.finfo(float).eps * top * inverse_top <= 1e-7:
        return None
    return (1.0 - 1e-6) / math.sqrt(inverse_top), (1.0 + 1e-12) * math.sqrt(top)


def fall_basis(sig, V, k) -> np.ndarray:
    """P = σ_k V_r Σ_r⁻¹ (n × r, r = k + 1) from a matrix A's singular values `sig`
    (descending) and right singular vectors V (columns): for any A' of A's shape,
    σ_k(A') ≥ σ_k(A) − ‖(A' − A) P‖₂. (σ_k(A') ≥ σ_k(A' V_r), as V_r has orthonormal
    columns, and A' V_r = (I + (A' − A) V_r Σ_r⁻¹ U_rᵀ) U_r Σ_r, whose r-th singular value
    is at least σ_k (1 − ‖(A' − A) V_r Σ_r⁻¹‖₂).) Unlike Weyl's ‖A' − A‖₂ it weighs a
    change along each singular direction l by σ_k/σ_l: what moves the larger singular
    values, or turns A out of its row space, barely counts (the singularity monitor's
    bound on how fast σ_min of J̃ can fall). A zero singular value's direction weighs 1."""
    r = k + 1
    if sig[k] > 0.0:
        return V[:, :r] * (sig[k] / sig[:r])
    return V[:, :r] * (sig[:r] <= 0.0)


class Fall:
    """What the singularity monitor keeps of a measured observation for `fall_rates`: its
    time `t`, J̃ and D = dJ̃/dt there, P (`fall_basis`), σ_min, σ_max and ‖D‖_F
    (`rise`)."""

    __slots__ = ("t", "J", "D", "P", "smin", "smax", "rise")

    def __init__(self, t, J, fall, smin, smax, rise):
        self.t, self.J, self.D = t, J, fall[0]
        self.P = np.ascontiguousarray(fall[1])
        self.smin, self.smax, self.rise = smin, smax, rise


def fall_rates(a: Fall, b: Fall) -> tuple[float, float]:
    """How fast σ_min/σ_max (not normalized) of J̃ can fall along a step from its end a to
    its end b (the singularity monitor's `Fall`s), from each end's values: J̃ along the step taken as the cubic through J̃ and D at both ends, whose rate is D_a + (D_b − D_a) x + c x (1 − x) (x from 0 to 1, c = 6 C,
    C = (J̃_b − J̃_a)/h − (D_a + D_b)/2: its mean is the chord's), so ‖rate · P‖ ≤
    max(‖D_a P‖, ‖D_b P‖) + 1.5 ‖C P‖ for any P. Seen from end e, σ_min falls at most at
    that with P = P_e (`fall_basis`; Frobenius norms), σ_max rises
    at most at max(‖D_a‖_F, ‖D_b‖_F) + 1.5 ‖C‖_F (Weyl), and s = σ_min/σ_max falls at
    most at (fall + s_e rise)/σ_max,e."""
    C = (b.J - a.J) * (1.0 / (b.t - a.t)) - 0.5 * (a.D + b.D)
    m, r = a.D.shape[0], a.P.shape[1]
    # ‖X P_e‖_F² for X = D_a, D_b, C and e = a, b, from one product.
    X = np.concatenate((a.D, b.D, C)) @ np.concatenate((a.P, b.P), axis=1)
    (da_a, da_b), (db_a, db_b), (c_a, c_b) = \
        np.square(X).reshape(3, m, 2, r).sum(axis=(1, 3)).tolist()
    rise = max(a.rise, b.rise) + 1.5 * math.sqrt(float(np.dot(C.ravel(), C.ravel())))
    fall_a = math.sqrt(max(da_a, db_a)) + 1.5 * math.sqrt(c_a)
    fall_b = math.sqrt(max(da_b, db_b)) + 1.5 * math.sqrt(c_b)
    return ((fall_a + a.smin / a.smax * rise) / a.smax,
            (fall_b + b.smin / b.smax * rise) / b.smax)
