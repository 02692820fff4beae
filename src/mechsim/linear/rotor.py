"""Rotor–bearing systems: Timoshenko shaft elements with gyroscopic terms, rigid disks,
bearings and unbalance, assembled into a `LinearSystem` (seed 000, example 2).

Degrees of freedom, 4 per station: [u_x, u_y, φ_x, φ_y] with φ_x = ∂u_x/∂z, φ_y = ∂u_y/∂z
(cross-section rotations in the two bending planes; the shaft runs along z and spins at Ω).
Both bending planes use the same element matrices. The rotation a section makes about x is
α = −φ_y and about y is β = φ_x; the polar inertia's kinetic energy −Ω I_p α̇ β couples the
planes through the skew gyroscopic matrix G: M q̈ + (C + Ω G) q̇ + K q = f.

Shaft elements use Timoshenko's interdependent interpolation (Friedman & Kosmatka's shape
functions with the shear parameter Φ = 12 E I / (κ G A L²); Φ = 0 gives Euler–Bernoulli
Hermite elements). K, M (translational and rotary inertia) and G are integrated by 4-point
Gauss quadrature, exact for these polynomial integrands. κ = 6(1 + ν)/(7 + 6ν) for a solid
circular section (Cowper).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..fem import timoshenko_element
from .system import LinearSystem

@dataclass(frozen=True)
class ShaftElement:
    length: float      # m
    diameter: float    # m (solid circular section)


@dataclass(frozen=True)
class Disk:
    station: int       # 1-based station number
    mass: float        # kg
    It: float          # transverse moment of inertia, kg·m²
    Ip: float          # polar moment of inertia, kg·m²


@dataclass(frozen=True)
class Bearing:
    station: int
    kxx: float
    kyy: float
    cxx: float = 0.0
    cyy: float = 0.0


@dataclass(frozen=True)
class Unbalance:
    station: int
    me: float          # mass × eccentricity, kg·m
    angle: float = 0.0  # rad


@dataclass
class Rotor:
    """A rotor on bearings. Stations are numbered 1 … len(elements)+1 from the left."""
    elements: list
    E: float
    rho: float
    nu: float = 0.3
    disks: list = field(default_factory=list)
    bearings: list = field(default_factory=list)
    unbalances: list = field(default_factory=list)
    shear: bool = True

    def __post_init__(self):
        if not self.elements:
            raise ValueError("a rotor needs at least one shaft element")
        for name in ("E", "rho"):
            if not getattr(self, name) > 0:
                raise ValueError(f"rotor: `{name}` must be positive, got {getattr(self, name)}")
        for k, el in enumerate(self.elements, 1):
            if not (el.length > 0 and el.diameter > 0):
                raise ValueError(f"rotor: shaft element {k} needs positive length and diameter, "
                                 f"got {el}")
        n_st = len(self.elements) + 1
        for item in [*self.disks, *self.bearings, *self.unbalances]:
            if not 1 <= item.station <= n_st:
                raise ValueError(f"rotor: {type(item).__name__} at station {item.station}, "
                                 f"stations are 1 … {n_st}")
        self.n_stations = n_st
        self.n = 4 * n_st
        self._assemble()

    def dof(self, station: int, which: str) -> int:
        """Index of 'ux', 'uy', 'phix' or 'phiy' at a 1-based station."""
        return 4 * (station - 1) + ("ux", "uy", "phix", "phiy").index(which)

    def _assemble(self):
        n = self.n
        K, M, G, C = (np.zeros((n, n)) for _ in range(4))
        Gs = self.E / (2 * (1 + self.nu))
        kappa = 6 * (1 + self.nu) / (7 + 6 * self.nu)
        for e, el in enumerate(self.elements):
            A = math.pi * el.diameter**2 / 4
            I = math.pi * el.diameter**4 / 64
            Ke, Me, Gt = timoshenko_element(el.length, self.E, Gs, self.rho, A, I, kappa,
                                            self.shear)
            base = 4 * e
            x = [base + 0, base + 2, base + 4, base + 6]      # [u_x1, φ_x1, u_x2, φ_x2]
            y = [base + 1, base + 3, base + 5, base + 7]      # [u_y1, φ_y1, u_y2, φ_y2]
            for idx in (x, y):
                K[np.ix_(idx, idx)] += Ke
                M[np.ix_(idx, idx)] += Me
            G[np.ix_(x, y)] -= Gt
            G[np.ix_(y, x)] += Gt
        for d in self.disks:
            ux, uy, px, py = (self.dof(d.station, w) for w in ("ux", "uy", "phix", "phiy"))
            M[ux, ux] += d.mass
            M[uy, uy] += d.mass
            M[px, px] += d.It
            M[py, py] += d.It
            G[px, py] -= d.Ip
            G[py, px] += d.Ip
        for b in self.bearings:
            ux, uy = self.dof(b.station, "ux"), self.dof(b.station, "uy")
            K[ux, ux] += b.kxx
            K[uy, uy] += b.kyy
            C[ux, ux] += b.cxx
            C[uy, uy] += b.cyy
        self.K, self.M, self.G, self.C = K, M, G, C

    def unbalance_force(self, speed: float):
        """f(t) of the unbalances at spin speed Ω (rad/s): m e Ω² (cos, sin)(Ωt + angle)."""
        items = [(self.dof(u.station, "ux"), self.dof(u.station, "uy"), u.me * speed**2,
                  u.angle) for u in self.unbalances]
        n = self.n

        def f(t):
            out = np.zeros(n)
            for ux, uy, amp, ang in items:
                out[ux] += amp * math.cos(speed * t + ang)
                out[uy] += amp * math.sin(speed * t + ang)
            return out
        return f

    def linear_system(self, speed: float, unbalance: bool = True) -> LinearSystem:
        """M q̈ + (C + Ω G) q̇ + K q = f_unbalance(t) at spin speed Ω (rad/s)."""
        return LinearSystem(self.M, self.C + speed * self.G, self.K,
                            force=self.unbalance_force(speed) if unbalance and self.unbalances
                            else None)

    def modes(self, speed: float = 0.0):
        """(damped frequencies ω_d in rad/s, damping ratios ζ) of all modes with ω_d > 0,
        ascending in frequency."""
        lam = np.linalg.eigvals(self.linear_system(speed, unbalance=False).A)
        lam = lam[lam.imag > 0]
        lam = lam[np.argsort(lam.imag)]
        return lam.imag, -lam.real / np.abs(lam)

    def natural_frequencies(self, speed: float = 0.0, count: int | None = None,
                            max_damping: float = 0.5) -> np.ndarray:
        """Damped natural frequencies (rad/s) of the vibration modes, ascending; `count` of
        them. Modes with damping ratio above `max_damping` are left out: bearing dampers
        make some light modes overdamped, and gyroscopic coupling gives those a tiny
        imaginary part (e.g. −2741 + 0.7i /s for the seed's compressor) that is no vibration."""
        w, zeta = self.modes(speed)
        w = w[zeta < max_damping]
        return w[:count] if count else w

    def campbell(self, speeds, count: int = 6) -> np.ndarray:
        """Natural frequencies over spin speeds, shape (len(speeds), count)."""
        return np.array([self.natural_frequencies(s, count) for s in speeds])

    def steady_unbalance_response(self, speed: float) -> np.ndarray:
        """Complex amplitudes X with q(t) = Re(X e^{iΩt}) of the harmonic steady state:
        (K − Ω² M + iΩ (C + Ω G)) X = F, F the complex unbalance forces."""
        F = np.zeros(self.n, complex)
        for u in self.unbalances:
            a = u.me * speed**2 * np.exp(1j * u.angle)
            F[self.dof(u.station, "ux")] += a
            F[self.dof(u.station, "uy")] += -1j * a        # sin(Ωt + ψ) = Re(−i e^{i(Ωt+ψ)})
        D = self.K - speed**2 * self.M + 1j * speed * (self.C + speed * self.G)
        return np.linalg.solve(D, F)


def turbo_compressor(unbalance_me: float = 7.2e-6) -> Rotor:
    """Example 2 (Table 2) of Lee, Kim, Kim and Kim, "A Transient Response Analysis in the
    State-space Applying the Average Velocity Concept": a one-stage turbo-compressor rotor.
    Layout (not given in the paper's text; chosen here): disk D1 at station 1, bearing 1 at 2, bearing 2 at 6, disk D2 at
    7; unbalance 7.2 g·mm on each disk at 0° and 180°. ν = 0.3 (not given)."""
    mm = 1e-3
    lengths = [127, 50.8, 76.2, 76.2, 50.8, 50.8]
    diameters = [38.1, 38.1, 63.5, 63.5, 38.1, 38.1]
    return Rotor(elements=[ShaftElement(L * mm, D * mm) for L, D in zip(lengths, diameters)],
                 E=2.0e11, rho=7833.48, nu=0.3,
                 disks=[Disk(1, 4.536, 0.0183, 0.0366), Disk(7, 4.536e-5, 0.0, 0.0)],
                 bearings=[Bearing(2, 2.189e8, 2.277e8, 8.494e4, 8.756e4),
                           Bearing(6, 2.189e8, 2.189e8, 8.581e4, 8.581e4)],
                 unbalances=[Unbalance(1, unbalance_me, 0.0), Unbalance(7, unbalance_me, math.pi)])
