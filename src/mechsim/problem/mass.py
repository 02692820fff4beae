"""The mass matrix M(q) and the constraint forces' Schur complement Φ_q M⁻¹ Φ_qᵀ.

For rigid bodies in absolute coordinates M is constant and diagonal, so it is stored once
and never rebuilt; a flexible beam adds a dense block that depends on its angle and modal
amplitudes (`mechsim.flexible.invariants`). The Schur complement is solved by a banded
Cholesky factor for long rigid chains (`mechsim.linalg.banded`), else densely, with the
least-squares solution where it is singular (redundant constraints).
"""

from __future__ import annotations

import functools

import numpy as np

from ..linalg import sparse


class MassFactor:
    """M = L Lᵀ at one configuration, applied as L⁻¹ and L⁻ᵀ. For constant diagonal mass
    L⁻¹ is the vector `s` = M^{-1/2}; otherwise the dense block-diagonal `Linv`."""
    __slots__ = ("s", "Linv")

    def __init__(self, s=None, Linv=None):
        self.s, self.Linv = s, Linv

    def cols(self, J):
        """J L⁻ᵀ: the mass-scaled Jacobian (CSR where J is: `mechsim.linalg.sparse`)."""
        if self.Linv is None:
            return sparse.scale_columns(J, self.s)
        return J @ self.Linv.T

    def left(self, x):
        """L⁻¹ x (x of shape (n,) or (n, K))."""
        return (x.T * self.s).T if self.Linv is None else self.Linv @ x

    def right(self, x):
        """L⁻ᵀ x (x of shape (n,) or (n, K))."""
        return (x.T * self.s).T if self.Linv is None else self.Linv.T @ x

    def inverse(self, x):
        """M⁻¹ x = L⁻ᵀ L⁻¹ x (x of shape (n,) or (n, K))."""
        return (x.T * (self.s * self.s)).T if self.Linv is None else \
            self.Linv.T @ (self.Linv @ x)

    def unright(self, x):
        """Lᵀ x, the inverse of `right`: accelerations q̈ into the scaled x = Lᵀ q̈."""
        return (x.T / self.s).T if self.Linv is None else np.linalg.solve(self.Linv.T, x)


class MassModel:
    """M(q): `diagonal` (n,) holds the rigid bodies' masses and inertias (and nominal values
    on flexible blocks); `flexible` the beams (`FlexibleData`) whose blocks depend on q."""

    def __init__(self, diagonal, flexible=()):
        self.diagonal = np.asarray(diagonal, float)
        self.inverse_diagonal = 1.0 / self.diagonal
        self.flexible = tuple(flexible)
        self.constant = not self.flexible
        # Rigid bodies only: their mass is constant and diagonal.
        self.rigid = self.diagonal.copy()
        for fb in self.flexible:
            self.rigid[fb.slice] = 0.0
        self.constant_factor = MassFactor(s=1.0 / np.sqrt(self.diagonal)) if self.constant \
            else None
        self._rigid_factor = np.diag(np.sqrt(1.0 / np.where(self.rigid > 0.0, self.rigid, 1.0)))
        self._last_factor = None          # (key, MassFactor) of the latest flexible state

    def matrix(self, q=None) -> np.ndarray:
        """M(q), shape (n, n); q may be None for a rigid mechanism."""
        M = np.diag(self.rigid)
        for fb in self.flexible:
            if q is None:
                raise ValueError("the mass matrix of a flexible mechanism depends on q")
            M[fb.slice, fb.slice] = fb.kernel.mass_block(q[fb.slice], fb.parameters)
        return M

    def factor(self, q) -> MassFactor:
        """M(q) = L Lᵀ (shared and constant for rigid mechanisms; the latest flexible
        state's is kept)."""
        if self.constant_factor is not None:
            return self.constant_factor
        key = np.concatenate([q[fb.slice][2:] for fb in self.flexible]).tobytes()
        if self._last_factor is not None and self._last_factor[0] == key:
            return self._last_factor[1]
        from ..flexible.invariants import inverse_cholesky
        Linv = self._rigid_factor.copy()
        for fb in self.flexible:
            Linv[fb.slice, fb.slice] = inverse_cholesky(fb.kernel.mass_block(q[fb.slice],
                                                                             fb.parameters))
        f = MassFactor(Linv=Linv)
        self._last_factor = (key, f)
        return f

    def action_derivative(self, q, a, dq) -> np.ndarray:
        """∂(M(q) a)/∂q dq for the directions dq (n, K): zero but on the flexible blocks,
        from their kernels (the rigid bodies' M is constant)."""
        out = np.zeros_like(dq)
        for fb in self.flexible:
            out[fb.slice] = fb.kernel.mass_action_q(q[fb.slice], a[fb.slice],
                                                    fb.parameters) @ dq[fb.slice]
        return out

    def kinetic_energy(self, q, v) -> np.ndarray:
        """½ vᵀ M(q) v over leading dimensions of q and v."""
        T = 0.5 * np.einsum("...i,i,...i->...", v, self.rigid, v)
        for fb in self.flexible:
            T = T + fb.invariants.kinetic(q[..., fb.slice], v[..., fb.slice])
        return T


class SchurSolver:
    """Solves with S = Φ_q M⁻¹ Φ_qᵀ: banded Cholesky where `band` (a `BandedSchur`) serves,
    dense Cholesky otherwise, least squares where S is singular (redundant constraints).
    The dense S is formed from the mass-scaled J̃ = f.cols(J), or as (J W) Jᵀ, W = M⁻¹,
    when no factor `f` is given (constant mass)."""

    def __init__(self, mass: MassModel, build_band=None):
        self.mass = mass
        self._build_band = build_band     # () -> BandedSchur or None, called on first use
        self._band = False                # not yet decided

    @property
    def band(self):
        """The banded form where it serves (constant mass only), built on first use; None
        where the dense path serves. Assign to force either path."""
        if not self.mass.constant:
            return None
        if self._band is False:
            self._band = self._build_band() if self._build_band is not None else None
        return self._band

    @band.setter
    def band(self, value):
        self._band = value

    def decided_band(self):
        """The banded form if it has been built (without building it)."""
        return None if self._band is False else self._band

    def complement(self, J, f=None):
        """The dense S."""
        J = sparse.dense(J)
        if f is None:
            return (J * self.mass.inverse_diagonal) @ J.T
        Jt = f.cols(J)
        return Jt @ Jt.T

    def solve(self, J, r, f=None, factor=None):
        """S⁻¹ r (`factor`: the banded factor at J, if the caller has it)."""
        band = self.band
        if band is not None:
            c = band.factor(J) if factor is None else factor
            if c is not None:
                return band.solve(c, r)
        return dense().solve_psd(self.complement(J, f), r)

    def factored(self, J, f):
        """r ↦ S⁻¹ r from one Cholesky factor at Φ_q = J (`f`: the mass factor there);
        None if S is not numerically positive definite (a singular configuration,
        redundancy)."""
        band = self.band
        if band is not None:
            c = band.factor(J)
            return None if c is None else (lambda r: band.solve(c, r))
        d = dense()
        c = d.cho_factor_or_none(self.complement(J, f))
        return None if c is None else (lambda r: d.cho_solve(c, r))

    def accelerations(self, J, Q, c, q=None, factor=None):
        """(q̈, λ) of [M Φ_qᵀ; Φ_q 0][q̈; λ] = [Q; c] (`q` is needed only where M depends on
        it; `factor` as in `solve`)."""
        if self.mass.constant:
            w = self.mass.inverse_diagonal
            wq = w * Q
            lam = self.solve(J, J @ wq - c, factor=factor)
            return wq - w * sparse.transpose_times(J, lam), lam
        f = self.mass.factor(q)
        Jt, x = f.cols(J), f.left(Q)
        lam = dense().solve_psd(Jt @ Jt.T, Jt @ x - c)
        return f.right(x - sparse.transpose_times(Jt, lam)), lam


@functools.cache
def dense():
    """`mechsim.linalg.dense`, imported on first use (scipy: not needed to build a scene). An
    import statement in the function that solves would cost as much as the small
    Cholesky solve it imports."""
    from ..linalg import dense as module
    return module
