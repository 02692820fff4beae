"""Stability and accuracy of the fixed-step methods on the damped oscillator
ẍ + 2ζω ẋ + ω² x = 0 (seed 000, section 2).

The amplification matrix A_m (q_{n+1} = A_m q_n, q = [ẋ; x]) of every method is obtained by
stepping the unit states with the method itself, so the analysis and the integrator can
never disagree. For "ss-newmark" it equals eq. 11, (I − h/2 A)⁻¹ (I + h/2 A).

From the eigenvalues λ = R e^{±iφ} of A_m::

  spectral radius  ρ = max abs(λ)                        (≤ 1: stable)
  period error     e_p = (T̄ − T)/T · 100 %, T = 2π/ω_d, T̄ = 2π h/φ       (eq. 23)
  amplitude error  e_A = Rⁿ − e^{−ζω n h}                                  (eq. 26)

These are exact for any h (the Taylor series of eqs. 22 and 24 are their small-step limits).
"""

from __future__ import annotations

import math

import numpy as np

from .system import LINEAR_METHODS, LinearSystem


def _check(method, omega, zeta, h):
    if method not in LINEAR_METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(LINEAR_METHODS)}")
    for name, val in (("omega", omega), ("h", h)):
        if not (math.isfinite(val) and val > 0):
            raise ValueError(f"`{name}` must be positive, got {val!r}")
    if not (math.isfinite(zeta) and zeta >= 0):
        raise ValueError(f"`zeta` must be non-negative, got {zeta!r}")


def amplification_matrix(method: str, omega: float, zeta: float, h: float) -> np.ndarray:
    """A_m of `method` for the oscillator (ω, ζ) at step h: shape (2, 2) on q = [ẋ; x]."""
    _check(method, omega, zeta, h)
    sys1 = LinearSystem([[1.0]], [[2.0 * zeta * omega]], [[omega**2]])
    Am = np.empty((2, 2))
    for j, (v0, x0) in enumerate(((1.0, 0.0), (0.0, 1.0))):
        r = sys1.simulate(h, h, method, x0=[x0], v0=[v0])
        Am[:, j] = [r.v[1, 0], r.x[1, 0]]
    return Am


def spectral_radius(method: str, omega: float, zeta: float, h: float) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(amplification_matrix(method, omega, zeta, h)))))


def period_error(method: str, omega: float, zeta: float, h: float) -> float:
    """Percent period elongation (eq. 23); nan when the numerical solution does not oscillate
    (real eigenvalues: ζ ≥ 1 or a step past the method's oscillation limit)."""
    lam = np.linalg.eigvals(amplification_matrix(method, omega, zeta, h))
    phi = float(np.max(np.abs(np.angle(lam))))
    if zeta >= 1.0 or phi == 0.0 or np.all(np.abs(lam.imag) < 1e-300):
        return math.nan
    wd = omega * math.sqrt(1.0 - zeta**2)
    return (wd * h / phi - 1.0) * 100.0


def amplitude_error(method: str, omega: float, zeta: float, h: float, n: int) -> float:
    """Rⁿ − e^{−ζω n h} (eq. 26), R = abs(λ) of the oscillating eigenpair."""
    if int(n) != n or n < 0:
        raise ValueError(f"`n` must be a non-negative whole number of steps, got {n!r}")
    lam = np.linalg.eigvals(amplification_matrix(method, omega, zeta, h))
    R = float(np.max(np.abs(lam)))
    return R**n - math.exp(-zeta * omega * n * h)
