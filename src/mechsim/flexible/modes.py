"""Planar two-node beam elements (axial + Euler–Bernoulli bending, 3 DOFs per node
[u, v, θ]: axial and transverse displacement in the beam frame, and rotation), consistent
mass and stiffness, and the modal basis of the assembled beam under stated reference
conditions of the floating frame.

Reference conditions (which DOFs the frame takes, i.e. are zero in the elastic field):
  "pinned-pinned"  frame along the chord: v = 0 at both ends, u = 0 at the start;
  "clamped-free"   u = v = θ = 0 at the start;
  "free-free"      nothing fixed; the three rigid-body modes (ω ≈ 0) are removed.
Modes are mass-normalised (Φᵀ M Φ = I) and sorted by frequency.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from ..fem import timoshenko_element

BOUNDARIES = ("pinned-pinned", "clamped-free", "free-free")


def beam_fe_matrices(length, youngs_modulus, density, area, second_moment, n_elements):
    """Global (K, M), each (3(N+1), 3(N+1)) for N equal elements, DOFs [u, v, θ] per node."""
    L = length / n_elements
    E, rho, A, I = youngs_modulus, density, area, second_moment
    Kb, Mb, _ = timoshenko_element(L, E, 1.0, rho, A, I, 1.0, shear=False, rotary=False)
    Ka = E * A / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    Ma = rho * A * L / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
    n = 3 * (n_elements + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e in range(n_elements):
        a = [3 * e, 3 * e + 3]                                   # axial DOFs
        b = [3 * e + 1, 3 * e + 2, 3 * e + 4, 3 * e + 5]         # [v1, θ1, v2, θ2]
        K[np.ix_(a, a)] += Ka
        M[np.ix_(a, a)] += Ma
        K[np.ix_(b, b)] += Kb
        M[np.ix_(b, b)] += Mb
    return K, M


@dataclass(frozen=True)
class ModalBasis:
    """Retained modes of a beam: `shapes` (n_nodes, 3, n_modes) of [u, v, θ] at each node,
    `frequencies` (n_modes,) in rad/s, the boundary kind, the nodes' positions along the
    beam, and the full FE matrices they came from."""
    shapes: np.ndarray
    frequencies: np.ndarray
    boundary: str
    node_positions: np.ndarray
    K: np.ndarray
    M: np.ndarray

    @property
    def n_modes(self) -> int:
        return self.frequencies.size

    def matrix(self) -> np.ndarray:
        """Φ as a (3 n_nodes, n_modes) matrix on the FE DOFs."""
        return self.shapes.reshape(-1, self.n_modes)


def beam_modes(length, youngs_modulus, density, area, second_moment, n_elements=10,
               n_modes=2, boundary="pinned-pinned", owner="beam") -> ModalBasis:
    """The lowest `n_modes` elastic modes of a uniform beam (see the module docstring)."""
    for name, value in (("length", length), ("youngs_modulus", youngs_modulus),
                        ("density", density), ("area", area), ("second_moment", second_moment)):
        if not (isinstance(value, numbers.Real) and math.isfinite(value) and value > 0):
            raise ValueError(f"{owner}: `{name}` must be positive, got {value!r}")
    if boundary not in BOUNDARIES:
        raise ValueError(f"{owner}: unknown boundary {boundary!r}; choose one of "
                         f"{', '.join(BOUNDARIES)}")
    if not (isinstance(n_elements, int) and n_elements >= 1):
        raise ValueError(f"{owner}: `n_elements` must be a positive whole number, got {n_elements!r}")
    K, M = beam_fe_matrices(length, youngs_modulus, density, area, second_moment, n_elements)
    n = K.shape[0]
    last = n - 3
    fixed = {"pinned-pinned": [0, 1, last + 1], "clamped-free": [0, 1, 2],
             "free-free": []}[boundary]
    free = np.setdiff1d(np.arange(n), fixed)
    rigid = 3 if boundary == "free-free" else 0
    available = free.size - rigid
    if not (isinstance(n_modes, int) and 1 <= n_modes <= available):
        raise ValueError(f"{owner}: `n_modes` must be between 1 and {available} for "
                         f"{n_elements} element(s) {boundary}, got {n_modes!r}")
    # K φ = ω² M φ through M = L Lᵀ: (L⁻¹ K L⁻ᵀ) y = ω² y, φ = L⁻ᵀ y is mass-normalised.
    # (numpy alone: a scene with beams should not pay for importing scipy.linalg.)
    L = np.linalg.cholesky(M[np.ix_(free, free)])
    Li = np.linalg.inv(L)
    A = Li @ K[np.ix_(free, free)] @ Li.T
    w2, y = np.linalg.eigh(0.5 * (A + A.T))
    vec = Li.T @ y
    keep = slice(rigid, rigid + n_modes)
    shapes = np.zeros((n, n_modes))
    shapes[free] = vec[:, keep]                     # Φᵀ M Φ = I
    freqs = np.sqrt(np.maximum(w2[keep], 0.0))
    return ModalBasis(shapes.reshape(n_elements + 1, 3, n_modes), freqs, boundary,
                      np.linspace(0.0, length, n_elements + 1), K, M)
