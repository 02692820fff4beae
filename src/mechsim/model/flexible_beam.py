"""FlexibleBeam: a uniform elastic beam with modal coordinates in a floating frame."""

from __future__ import annotations

import numpy as np

from .checks import ModelError, rotation, scalar, vector2
from .bodies import Body

# The most finite elements a beam may have: its modes come from a dense eigensolve of
# 3 (elements + 1) unknowns (2000 elements: 6003, a few seconds and 1 GiB).
MAX_ELEMENTS = 2000


class FlexibleBeam(Body):
    """A planar beam (axial + Euler–Bernoulli bending) whose small elastic deformation is
    the sum of its lowest `n_modes` modes, carried by a floating reference frame.

    Coordinates: (x, y, angle) of the frame — at the start node, along the undeformed axis —
    and the modal amplitudes eta1 … eta_k. A material point at ξ along the beam is at
    r = R + A(θ)((ξ, 0) + Φ(ξ) η). The modes come from `n_elements` finite elements under the
    reference conditions `boundary` (see `mechsim.flexible.modes`): "pinned-pinned" makes the
    frame the chord between the end nodes — the natural choice for a link pinned at both
    ends, such as a coupler — "clamped-free" the tangent at the start, "free-free" the mean
    axis. They are mass-normalised, so η has units of √kg·m.

    Parameters
    ----------
    name : str
    length, youngs_modulus, density, area, second_moment : float, SI, > 0
    n_elements : int, finite elements along the beam (n_elements + 1 nodes)
    n_modes : int, retained modes
    start : 2-vector, position of the start node;  angle : float, direction of the beam
    boundary : "pinned-pinned", "clamped-free" or "free-free"
    damping_ratio : float ≥ 0, modal damping ratio ζ (force −2ζω η̇ on every mode)
    velocity, angular_velocity : initial velocity of the frame origin and its rate
    eta, eta_velocity : initial modal amplitudes and rates (default zero)

    Joints, springs and forces attach at nodes, given as global points in the initial
    configuration (node i at start + i·length/n_elements along the beam).
    """

    def __init__(self, name: str, length: float, youngs_modulus: float, density: float,
                 area: float, second_moment: float, n_elements: int = 10, n_modes: int = 2,
                 start=(0.0, 0.0), angle: float = 0.0, boundary: str = "pinned-pinned",
                 damping_ratio: float = 0.0, velocity=(0.0, 0.0),
                 angular_velocity: float = 0.0, eta=None, eta_velocity=None):
        super().__init__(name)
        owner = f"beam '{name}'"
        self.length = scalar(length, "length", owner, positive=True)
        self.youngs_modulus = scalar(youngs_modulus, "youngs_modulus", owner, positive=True)
        self.density = scalar(density, "density", owner, positive=True)
        self.area = scalar(area, "area", owner, positive=True)
        self.second_moment = scalar(second_moment, "second_moment", owner, positive=True)
        self.damping_ratio = scalar(damping_ratio, "damping_ratio", owner, nonnegative=True)
        if isinstance(n_elements, bool) or not isinstance(n_elements, (int, np.integer)) \
                or n_elements < 1:
            raise ModelError(f"{owner}: `n_elements` must be a positive whole number, "
                             f"got {n_elements!r}")
        self.n_elements = int(n_elements)
        if self.n_elements > MAX_ELEMENTS:
            dofs = 3 * (self.n_elements + 1)
            raise ModelError(f"{owner}: `n_elements` = {self.n_elements} asks for dense "
                             f"finite-element matrices of {dofs} × {dofs} "
                             f"({4 * dofs * dofs * 8 / 2**30:.3g} GiB and an eigensolve of "
                             f"that size); the lowest modes converge with tens of elements "
                             f"(10 give two pinned–pinned modes to 0.1 %): use at most "
                             f"{MAX_ELEMENTS}")
        from ..flexible.modes import BOUNDARIES, beam_modes
        if boundary not in BOUNDARIES:
            raise ModelError(f"{owner}: unknown `boundary` {boundary!r}; choose one of "
                             f"{', '.join(BOUNDARIES)}")
        if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)):
            raise ModelError(f"{owner}: `n_modes` must be a whole number, got {n_modes!r}")
        try:
            self.modes = beam_modes(self.length, self.youngs_modulus, self.density, self.area,
                                    self.second_moment, self.n_elements, int(n_modes),
                                    boundary, owner=owner)
        except ValueError as exc:
            raise ModelError(str(exc)) from None
        self.boundary = boundary
        self.n_modes = int(n_modes)
        self.coordinate_names = ("x", "y", "angle") + tuple(f"eta{k + 1}"
                                                            for k in range(self.n_modes))
        self.position = vector2(start, "start", owner)
        self.angle = scalar(angle, "angle", owner)
        self.velocity = vector2(velocity, "velocity", owner)
        self.angular_velocity = scalar(angular_velocity, "angular_velocity", owner)
        self.eta = self._modal_vector(eta, "eta", owner)
        self.eta_velocity = self._modal_vector(eta_velocity, "eta_velocity", owner)
        self.mass = self.density * self.area * self.length

    def _modal_vector(self, value, what, owner):
        if value is None:
            return np.zeros(self.n_modes)
        a = np.asarray(value, float).ravel()
        if a.shape != (self.n_modes,) or not np.all(np.isfinite(a)):
            raise ModelError(f"{owner}: `{what}` must be {self.n_modes} finite numbers, "
                             f"got {value!r}")
        return a

    # --- modal data ----------------------------------------------------------------------------
    @property
    def frequencies(self) -> np.ndarray:
        """Natural angular frequencies (rad/s) of the retained modes."""
        return self.modes.frequencies

    @property
    def nodes(self) -> np.ndarray:
        """Positions of the nodes along the beam, (n_elements + 1,)."""
        return self.modes.node_positions

    def invariants(self):
        """The inertia shape integrals (`mechsim.flexible.invariants.BeamInvariants`)."""
        from ..flexible.invariants import BeamInvariants
        return BeamInvariants.of(self.modes, self.density, self.area, self.damping_ratio)

    def node_index(self, local, who: str) -> int:
        """Index of the node at body point `local`; a clear error if there is none."""
        local = np.asarray(local, float)
        tol = 1e-6 * self.length
        i = int(np.argmin(np.abs(self.nodes - local[0])))
        if abs(self.nodes[i] - local[0]) > tol or abs(local[1]) > tol:
            g = self.position + rotation(self.angle) @ local
            raise ModelError(
                f"{who}: point ({g[0]:.6g}, {g[1]:.6g}) is not a node of beam '{self.name}' "
                f"(it lies {local[0]:.6g} m along and {local[1]:.3g} m off its axis); its "
                f"{self.n_elements + 1} nodes are every {self.length / self.n_elements:.6g} m "
                f"along the axis from the start {tuple(self.position.round(9).tolist())}")
        return i

    def point_modes(self, local, who: str = "") -> np.ndarray:
        """(2, k): the body-frame displacement of the point at (ξ, y) per unit η — from the
        element shape functions, with the section rotation for a point off the axis."""
        from ..flexible.invariants import interpolation
        local = np.asarray(local, float)
        nu, nv, dnv = interpolation(np.clip(local[0], 0.0, self.length), self.length,
                                    self.n_elements)
        Phi = self.modes.matrix()
        return np.vstack([(nu - local[1] * dnv) @ Phi, nv @ Phi])

    def rotation_modes(self, local) -> np.ndarray:
        """(k,): the section rotation at (ξ, ·) per unit η."""
        from ..flexible.invariants import interpolation
        _, _, dnv = interpolation(np.clip(local[0], 0.0, self.length), self.length,
                                  self.n_elements)
        return (dnv @ self.modes.matrix())[0]

    # --- hooks for joints and loads ------------------------------------------------------------
    def attachment_parameter_names(self, role: str) -> tuple[str, ...]:
        return tuple(f"{role}_{c}{k + 1}" for k in range(self.n_modes) for c in "uvr")

    def attachment_values(self, local, who: str) -> tuple[float, ...]:
        i = self.node_index(local, who)
        shapes = self.modes.shapes[i]                   # (3, k): u, v, θ per mode
        return tuple(float(shapes[c, k]) for k in range(self.n_modes) for c in range(3))

    def initial_node_rotation(self, local) -> float:
        return float(self.rotation_modes(local) @ self.eta)

    # --- initial state -------------------------------------------------------------------------
    @property
    def initial_coordinates(self) -> np.ndarray:
        return np.concatenate([[self.position[0], self.position[1], self.angle], self.eta])

    @property
    def initial_velocities(self) -> np.ndarray:
        return np.concatenate([[self.velocity[0], self.velocity[1], self.angular_velocity],
                               self.eta_velocity])

    @property
    def mass_diagonal(self) -> np.ndarray:
        """Nominal scales only (M depends on the state): m, m, ml²/3, 1 …"""
        return np.concatenate([[self.mass, self.mass, self.mass * self.length * self.length / 3.0],
                               np.ones(self.n_modes)])

