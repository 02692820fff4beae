"""Inertia shape integrals of a modal beam in a floating frame, and the numbers they give.

A material point of the beam (frame origin at the start node, x̄ along the undeformed axis)
is at

    r = R + A(θ) ū,    ū = N(ξ) (d₀ + Φ η)

with N the element shape functions (linear axial, Hermite cubic transverse), d₀ the nodal
coordinates of the undeformed beam (axial entries ξᵢ, the rest zero; linear axial shape
functions reproduce x̄ = ξ exactly) and Φ the mass-normalised modes. With ω = θ̇, e = η̇ and
J̃ the 90° rotation, the kinetic energy ½ ∫ρ ṙᵀṙ gives the mass matrix over (R, θ, η)

    [ m I₂    A J̃ S̄(η)          A S_η        ]
    [  ·      I₀ + 2cᵀη + ηᵀη   b₀ᵀ + ηᵀ B   ]
    [  ·            ·           I            ]

and the virtual work of the velocity-dependent part of r̈ = … + A(−ū ω² + 2 ω J̃ N Φ e) the
quadratic-velocity forces

    Q_R = A (S̄ ω² − 2 ω J̃ S_η e),  Q_θ = −2 ω (c + η)ᵀ e,  Q_η = ω² (c + η) + 2 ω B e,

where, from the constant integrals S₁ = ∫ρ N dV (2 × n_dof), M_fe = ∫ρ NᵀN dV (the consistent
mass matrix) and M̃ = ∫ρ Nᵀ J̃ᵀ N dV (skew):

    S̄(η) = S₁ d₀ + S_η η,  S_η = S₁ Φ,  I₀ = d₀ᵀ M_fe d₀,  c = Φᵀ M_fe d₀,
    b₀ = Φᵀ M̃ᵀ d₀,  B = Φᵀ M̃ Φ.

These are Shabana's inertia shape integrals for the planar floating frame; they are computed
once per beam and every evaluation is a few small products. Geometric stiffening (the
centrifugal stiffening of a fast-spinning beam) is not modelled: it matters when the spin
rate approaches the first bending frequency, far from the mechanisms this is meant for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(4)    # exact to degree 7


def element_shapes(s, length):
    """(N_u, N_v, N_v') of one element at s ∈ [0, 1] along it, each (..., 6) over the element
    DOFs [u₁, v₁, θ₁, u₂, v₂, θ₂] (θ = dv/dx)."""
    s = np.asarray(s, float)[..., None]
    z = np.zeros_like(s)
    L = length
    nu = np.concatenate([1 - s, z, z, s, z, z], axis=-1)
    nv = np.concatenate([z, 1 - 3 * s**2 + 2 * s**3, L * (s - 2 * s**2 + s**3), z,
                         3 * s**2 - 2 * s**3, L * (-s**2 + s**3)], axis=-1)
    dnv = np.concatenate([z, (-6 * s + 6 * s**2) / L, 1 - 4 * s + 3 * s**2, z,
                          (6 * s - 6 * s**2) / L, -2 * s + 3 * s**2], axis=-1)
    return nu, nv, dnv


def interpolation(xi, length, n_elements):
    """(N_u, N_v, N_v') at axial positions `xi` (k,), each (k, 3(N+1)) over the beam's DOFs."""
    xi = np.atleast_1d(np.asarray(xi, float))
    Le = length / n_elements
    e = np.clip(np.floor(xi / Le).astype(int), 0, n_elements - 1)
    s = xi / Le - e
    nu_e, nv_e, dn_e = element_shapes(s, Le)
    n = 3 * (n_elements + 1)
    out = [np.zeros((xi.size, n)) for _ in range(3)]
    rows = np.arange(xi.size)[:, None]
    cols = 3 * e[:, None] + np.arange(6)
    for o, loc in zip(out, (nu_e, nv_e, dn_e)):
        o[rows, cols] = loc
    return out


def shape_integrals(length, density, area, n_elements):
    """(S₁ (2, n_dof), M̃ (n_dof, n_dof)) by Gauss quadrature over each element."""
    Le = length / n_elements
    s = 0.5 * (_GAUSS_X + 1.0)
    w = 0.5 * _GAUSS_W * Le * density * area
    nu, nv, _ = element_shapes(s, Le)
    s1_e = np.stack([w @ nu, w @ nv])
    mt_e = (nu * w[:, None]).T @ nv
    mt_e = mt_e - mt_e.T
    n = 3 * (n_elements + 1)
    S1, Mt = np.zeros((2, n)), np.zeros((n, n))
    for e in range(n_elements):
        idx = slice(3 * e, 3 * e + 6)
        S1[:, idx] += s1_e
        Mt[idx, idx] += mt_e
    return S1, Mt


@dataclass(frozen=True)
class BeamInvariants:
    """The constant integrals of one modal beam (see the module docstring)."""
    mass: float
    s0: np.ndarray          # S₁ d₀ (2,): first moment of mass of the undeformed beam
    s_eta: np.ndarray       # S_η (2, k)
    inertia0: float         # I₀ about the frame origin
    c: np.ndarray           # (k,)
    b0: np.ndarray          # (k,)
    B: np.ndarray           # (k, k), skew
    stiffness: np.ndarray   # ω² (k,)
    damping: np.ndarray     # 2 ζ ω (k,)

    @classmethod
    def of(cls, basis, density, area, damping_ratio=0.0):
        n_el = basis.node_positions.size - 1
        length = float(basis.node_positions[-1])
        S1, Mt = shape_integrals(length, density, area, n_el)
        Phi = basis.matrix()
        d0 = np.zeros(Phi.shape[0])
        d0[0::3] = basis.node_positions
        w = basis.frequencies
        return cls(mass=density * area * length, s0=S1 @ d0, s_eta=S1 @ Phi,
                   inertia0=float(d0 @ basis.M @ d0), c=Phi.T @ basis.M @ d0,
                   b0=Phi.T @ Mt.T @ d0, B=Phi.T @ Mt @ Phi, stiffness=w**2,
                   damping=2.0 * damping_ratio * w)

    @property
    def n_modes(self) -> int:
        return self.c.size

    def kernel_parameters(self, gravity) -> tuple[float, ...]:
        """The parameter vector of the generated kernel (`mechsim.flexible.kernel`)."""
        return tuple(float(x) for x in np.concatenate([
            [self.mass], self.s0, self.s_eta.ravel(), [self.inertia0], self.c, self.b0,
            self.B.ravel(), self.stiffness, self.damping, np.asarray(gravity, float)]))

    # --- energies (vectorized over leading dimensions) ---------------------------------------
    def _moments(self, x, v):
        """Shared terms of a block state (..., 3 + k): A S̄ (first moment of mass about the
        frame origin, global), A (J̃ S̄ ω + S_η η̇) (its rate from rotation and modes), the
        moment of inertia I(η) and the coupling (b₀ + Bᵀη)·η̇."""
        th, eta = x[..., 2], x[..., 3:]
        w, e = v[..., 2], v[..., 3:]
        c, s = np.cos(th), np.sin(th)
        sbar = self.s0 + eta @ self.s_eta.T
        se = e @ self.s_eta.T
        jx, jy = -sbar[..., 1] * w + se[..., 0], sbar[..., 0] * w + se[..., 1]
        first = (c * sbar[..., 0] - s * sbar[..., 1], s * sbar[..., 0] + c * sbar[..., 1])
        rate = (c * jx - s * jy, s * jx + c * jy)
        inertia = self.inertia0 + 2.0 * eta @ self.c + np.sum(eta * eta, axis=-1)
        coupling = np.sum((self.b0 + eta @ self.B) * e, axis=-1)
        return first, rate, inertia, coupling

    def kinetic(self, x, v):
        """½ vᵀ M v for block states x, v of shape (..., 3 + k)."""
        _, rate, inertia, coupling = self._moments(x, v)
        w, e = v[..., 2], v[..., 3:]
        return (0.5 * self.mass * (v[..., 0] ** 2 + v[..., 1] ** 2)
                + v[..., 0] * rate[0] + v[..., 1] * rate[1]
                + 0.5 * inertia * w * w + w * coupling + 0.5 * np.sum(e * e, axis=-1))

    def gravity_potential(self, x, gravity):
        """−gᵀ (m R + A S̄)."""
        th, eta = x[..., 2], x[..., 3:]
        c, s = np.cos(th), np.sin(th)
        sbar = self.s0 + eta @ self.s_eta.T
        px = self.mass * x[..., 0] + c * sbar[..., 0] - s * sbar[..., 1]
        py = self.mass * x[..., 1] + s * sbar[..., 0] + c * sbar[..., 1]
        return -(gravity[0] * px + gravity[1] * py)

    def strain(self, x):
        eta = x[..., 3:]
        return 0.5 * np.sum(self.stiffness * eta * eta, axis=-1)

    def angular_momentum(self, x, v):
        """∫ρ r × ṙ dV about the global origin, for block states of shape (..., 3 + k)."""
        first, rate, inertia, coupling = self._moments(x, v)
        X, Y, VX, VY = x[..., 0], x[..., 1], v[..., 0], v[..., 1]
        return (self.mass * (X * VY - Y * VX) + (X * rate[1] - Y * rate[0])
                + (first[0] * VY - first[1] * VX) + inertia * v[..., 2] + coupling)


def inverse_cholesky(Mb) -> np.ndarray:
    """L⁻¹ of the Cholesky factor Mb = L Lᵀ (LAPACK directly: numpy's wrappers cost more
    than the factorisation of a 5 × 5 block)."""
    from scipy.linalg.lapack import dpotrf, dtrtri      # loaded once a simulation runs
    L, info = dpotrf(Mb, lower=1)
    if info == 0:
        L, info = dtrtri(L, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("the mass matrix of a flexible beam is not positive "
                                    "definite (modal amplitudes far beyond small deformation?)")
    return L
