"""Beam finite elements shared by the rotor models (`mechsim.linear.rotor`) and the flexible
bodies' modal bases (`mechsim.flexible.modes`).

Timoshenko's interdependent interpolation (Friedman & Kosmatka's shape functions with the
shear parameter Φ = 12 E I / (κ G A L²); Φ = 0 gives Euler–Bernoulli Hermite elements). K, M
(translational and rotary inertia) and the polar-inertia block of the gyroscopic matrix are
integrated by 4-point Gauss quadrature, exact for these polynomial integrands.
"""

from __future__ import annotations

import numpy as np

_GX, _GW = np.polynomial.legendre.leggauss(4)
_GX, _GW = 0.5 * (_GX + 1.0), 0.5 * _GW


def _shape(xi, L, phi):
    """Timoshenko (interdependent) shape functions at ξ ∈ [0, 1] for DOFs [w1, θ1, w2, θ2]:
    N_w, N_θ and their z-derivatives."""
    c = 1.0 / (1.0 + phi)
    Nw = c * np.array([2 * xi**3 - 3 * xi**2 - phi * xi + 1 + phi,
                       L * (xi**3 - (2 + phi / 2) * xi**2 + (1 + phi / 2) * xi),
                       -2 * xi**3 + 3 * xi**2 + phi * xi,
                       L * (xi**3 - (1 - phi / 2) * xi**2 - (phi / 2) * xi)])
    dNw = c / L * np.array([6 * xi**2 - 6 * xi - phi,
                            L * (3 * xi**2 - (4 + phi) * xi + 1 + phi / 2),
                            -6 * xi**2 + 6 * xi + phi,
                            L * (3 * xi**2 - (2 - phi) * xi - phi / 2)])
    Nt = c * np.array([6 / L * (xi**2 - xi), 3 * xi**2 - (4 + phi) * xi + 1 + phi,
                       -6 / L * (xi**2 - xi), 3 * xi**2 - (2 - phi) * xi])
    dNt = c / L * np.array([6 / L * (2 * xi - 1), 6 * xi - 4 - phi,
                            -6 / L * (2 * xi - 1), 6 * xi - 2 + phi])
    return Nw, dNw, Nt, dNt


def timoshenko_element(L, E, G, rho, A, I, kappa, shear=True, rotary=True):
    """Single-plane element matrices (K, M, Gθ), each 4 × 4 on [w1, θ1, w2, θ2]. Gθ is
    ∫ ρ J N_θᵀ N_θ dz with J = 2I (polar), the block the gyroscopic matrix is built from.
    `shear=False` gives Euler–Bernoulli (Hermite) elements; `rotary=False` leaves the
    rotary inertia out of M (the classical consistent mass)."""
    phi = 12 * E * I / (kappa * G * A * L**2) if shear else 0.0
    K = np.zeros((4, 4))
    M = np.zeros((4, 4))
    Gt = np.zeros((4, 4))
    for x, w in zip(_GX, _GW):
        Nw, dNw, Nt, dNt = _shape(x, L, phi)
        gamma = dNw - Nt                                  # shear strain per DOF
        K += w * L * (E * I * np.outer(dNt, dNt) + (kappa * G * A * np.outer(gamma, gamma)
                                                    if shear else 0.0))
        M += w * L * (rho * A * np.outer(Nw, Nw) + (rho * I * np.outer(Nt, Nt) if rotary else 0.0))
        Gt += w * L * rho * 2 * I * np.outer(Nt, Nt)
    return K, M, Gt
