"""Linearized equations of motion and modes about a consistent state.

In the independent coordinates z of `ReducedCoordinates` the reduced equations
z̈ = F(z, ż, t) hold all of the constraints' effect, the dependent coordinates' second-order
terms included (the lesson of sympy's `Linearizer`: linearize in independent coordinates,
never the full equations with their multipliers). About a state (z₀, ż₀):

    A = ∂(ż, F)/∂(z, ż) = [[0, I], [−M⁻¹K, −M⁻¹C]],   M = Rᵀ M R,  K = −M ∂F/∂z,  C = −M ∂F/∂ż,

the Jacobians by central differences with Richardson extrapolation. Modes: where C is zero
(to working precision) the undamped problem K φ = ω² M φ (real, mass-normalized shapes;
ω² < 0 is an unstable mode, reported with damping ratio −1); else the eigenvalues s of A,
one mode per conjugate pair with ω = abs(s) and ζ = −Re s / abs(s) (and one per real eigenvalue,
ζ = ±1), with complex shapes. Shapes are mapped to all coordinates by R.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .equilibrium import STEP, jacobian
from .reduced import ReducedCoordinates


@dataclass
class Linearization:
    """A mechanism linearized about (q, v, t) (`Mechanism.linearize`).

    Attributes
    ----------
    coordinates : list of str
        Names of the f independent coordinates z.
    M, C, K : ndarray (f, f)
        Mass, damping and stiffness in z.
    A : ndarray (2f, 2f)
        The first-order form.
    tangent : ndarray (n, f)
        R = dq/dz, which maps shapes in z to all coordinates.
    eigenvalues : ndarray (2f,)
        Complex eigenvalues of A.
    frequencies : ndarray (k,)
        Natural angular frequencies [rad/s], ascending.
    damping_ratios : ndarray (k,)
        ζ of each (−1: an unstable, divergent mode).
    modes : ndarray (k, n)
        Shapes in all coordinates (real and mass-normalized in z for an undamped system;
        complex, largest entry 1, for a damped one).
    equilibrium : bool
        Whether (q, v) is at rest in equilibrium (F and ż vanish there).
    """
    q: np.ndarray
    v: np.ndarray
    t: float
    coordinates: list
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    A: np.ndarray
    tangent: np.ndarray
    eigenvalues: np.ndarray
    frequencies: np.ndarray
    damping_ratios: np.ndarray
    modes: np.ndarray
    equilibrium: bool
    coordinate_names: list = field(repr=False, default_factory=list)

    @property
    def stable(self) -> bool:
        """No eigenvalue of A with a positive real part (beyond round-off)."""
        scale = max(np.max(np.abs(self.eigenvalues), initial=0.0), 1e-300)
        return bool(np.all(self.eigenvalues.real <= 1e-9 * scale))

    def linear_system(self, force=None):
        """The same equations as a `mechsim.LinearSystem` in z (for its solvers, such as
        the state-space Newmark method)."""
        from ..linear import LinearSystem
        return LinearSystem(self.M, self.C, self.K, force=force)


def linearize(problem, q, v, t: float = 0.0) -> Linearization:
    """The linearization of `problem` about the consistent state (q, v) at t."""
    reduced = ReducedCoordinates(problem, q, t)
    f = reduced.f
    zd0 = np.asarray(v, float)[reduced.ind]
    z_steps = STEP * reduced.units
    zd_steps = z_steps * max(np.max(np.abs(zd0), initial=0.0), 1.0)     # per second
    q0 = reduced.positions(np.zeros(f))
    R = reduced.tangent(q0)
    if f == 0:
        empty = np.zeros((0, 0))
        return Linearization(q, v, t, [], empty, empty, empty, empty, R, np.zeros(0),
                             np.zeros(0), np.zeros(0), np.zeros((0, problem.n)), True,
                             list(problem.coordinate_names))
    z0 = np.zeros(f)
    F0 = reduced.accelerations(z0, zd0)
    dFdz = jacobian(lambda z: reduced.accelerations(z, zd0), z0, z_steps)
    dFdzd = jacobian(lambda zd: reduced.accelerations(z0, zd), zd0, zd_steps)
    M = reduced.mass(q0, R)
    K, C = -M @ dFdz, -M @ dFdzd
    A = np.block([[np.zeros((f, f)), np.eye(f)], [dFdz, dFdzd]])
    from scipy.linalg import eig
    eigenvalues, vectors = eig(A)
    frequencies, ratios, shapes = _modes(M, C, K, eigenvalues, vectors)
    scale = max(np.max(np.abs(dFdz)), 1e-300) * reduced.size
    at_rest = np.max(np.abs(zd0), initial=0.0) == 0.0 and \
        np.max(np.abs(F0), initial=0.0) <= 1e-8 * scale
    return Linearization(np.asarray(q, float), np.asarray(v, float), t, list(reduced.names),
                         M, C, K, A, R, eigenvalues, frequencies, ratios, shapes @ R.T,
                         bool(at_rest), list(problem.coordinate_names))


def _modes(M, C, K, s, vectors):
    """(frequencies, damping ratios, shapes in z (k, f)) as the module docstring says, from
    the eigenvalues s and eigenvectors of A where the system is damped."""
    from scipy.linalg import eigh
    f = M.shape[0]
    Ks = 0.5 * (K + K.T)
    # Undamped where C is round-off against critical damping's scale 2 √(‖K‖ ‖M‖).
    critical = 2.0 * np.sqrt(np.max(np.abs(Ks)) * np.max(np.abs(M)))
    if np.max(np.abs(C), initial=0.0) <= 1e-9 * critical:
        w2, phi = eigh(Ks, 0.5 * (M + M.T))
        order = np.argsort(np.abs(w2))
        w2, phi = w2[order], phi[:, order]
        return np.sqrt(np.abs(w2)), np.where(w2 < 0.0, -1.0, 0.0), phi.T
    keep = [k for k in range(2 * f) if s[k].imag > 0.0 or s[k].imag == 0.0]
    s, vectors = s[keep], vectors[:f, keep]
    order = np.argsort(np.abs(s))
    s, vectors = s[order], vectors[:, order]
    omega = np.abs(s)
    ratios = np.where(omega > 0.0, -s.real / np.where(omega > 0.0, omega, 1.0), 0.0)
    big = vectors[np.argmax(np.abs(vectors), axis=0), np.arange(vectors.shape[1])]
    return omega, ratios, (vectors / big).T
