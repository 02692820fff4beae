"""NumericProblem: the constrained equations of motion in numbers, and nothing else.

    M q̈ + Φ_qᵀ λ = Q(t, q, v),    Φ(q, t) = 0,    Φ_q q̈ = γ(q, v, t)

Formulations and integrators see only this object (as scipy's solvers see only `fun`): they
never touch a Body or a Joint. For rigid bodies in absolute coordinates M is constant and
diagonal, so it is stored once as `mass_diagonal` and never rebuilt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def frame_point(q: np.ndarray, start: int | None, s) -> np.ndarray:
    """Global position of body-fixed point `s` of the body whose (x, y, angle) start at
    index `start` of `q` (None: the ground). `q` has shape (..., n); result (..., 2)."""
    s = np.asarray(s, float)
    if start is None:
        return np.broadcast_to(s, q.shape[:-1] + (2,)).copy()
    th = q[..., start + 2]
    c, sn = np.cos(th), np.sin(th)
    return np.stack([q[..., start] + c * s[0] - sn * s[1],
                     q[..., start + 1] + sn * s[0] + c * s[1]], axis=-1)


def frame_point_velocity(q: np.ndarray, v: np.ndarray, start: int | None, s) -> np.ndarray:
    """Velocity of body-fixed point `s`: ṙ + ω × (A s). Shapes as in `frame_point`."""
    s = np.asarray(s, float)
    if start is None:
        return np.zeros(q.shape[:-1] + (2,))
    th, w = q[..., start + 2], v[..., start + 2]
    c, sn = np.cos(th), np.sin(th)
    return np.stack([v[..., start] - w * (sn * s[0] + c * s[1]),
                     v[..., start + 1] + w * (c * s[0] - sn * s[1])], axis=-1)


@dataclass(frozen=True)
class SpringData:
    name: str
    a: int | None
    b: int | None
    sa: tuple[float, float]
    sb: tuple[float, float]
    stiffness: float
    damping: float
    rest_length: float


@dataclass(frozen=True)
class PointLoad:
    """A force (constant 2-vector or callable of t) at body-fixed point `s`, or a torque."""
    name: str
    body: int
    s: tuple[float, float] | None
    value: object          # ndarray (2,), float, or callable of t
    is_torque: bool


@dataclass
class Counters:
    """Work counters, incremented by whoever does the work (scipy's nfev/njev/nlu)."""
    rhs: int = 0
    constraint_terms: int = 0
    factorizations: int = 0
    projections: int = 0
    partitions: int = 0
    switches: int = 0


class NumericProblem:
    """Compiled model plus parameter values.

    Parameters
    ----------
    model : module
        Generated functions (see `mechsim.codegen`).
    parameters : sequence of float
        Values of the model's parameter symbols, in order.
    mass_diagonal : ndarray, shape (n,)
    gravity : ndarray, shape (2,)
    body_starts : dict name -> index of the body's x in q
    coordinate_names, constraint_names : list of str (one per coordinate / per row of Φ)
    constraint_owners : list of str, the joint or driver that owns each row of Φ
    constraint_kinds : list of str, "joint" or "driver" for each row of Φ
    springs, loads : tuples of SpringData / PointLoad
    """

    constant_mass = True

    def __init__(self, model, parameters, mass_diagonal, gravity, body_starts,
                 coordinate_names, constraint_names, constraint_owners,
                 springs=(), loads=(), title="mechanism", constraint_kinds=None):
        self.model = model
        self.p = tuple(float(x) for x in parameters)
        self.mass_diagonal = np.asarray(mass_diagonal, float)
        self.inverse_mass_diagonal = 1.0 / self.mass_diagonal
        self.n = self.mass_diagonal.size
        self.m = int(model.M)
        self.gravity = np.asarray(gravity, float)
        self.body_starts = dict(body_starts)
        self.coordinate_names = list(coordinate_names)
        self.constraint_names = list(constraint_names)
        self.constraint_owners = list(constraint_owners)
        self.constraint_kinds = list(constraint_kinds or ["joint"] * len(self.constraint_names))
        self.springs = tuple(springs)
        self.loads = tuple(loads)
        self.title = title
        self.counters = Counters()
        # Gravity's generalized force is constant: m g on the x and y of every body.
        self._gravity_force = np.zeros(self.n)
        for start in self.body_starts.values():
            if start is not None:
                self._gravity_force[start:start + 2] = self.mass_diagonal[start] * self.gravity

    # --- constraints -----------------------------------------------------------------------
    def phi(self, q, t):
        return self.model.phi(q, t, self.p)

    def phi_q(self, q, t):
        return self.model.phi_q(q, t, self.p)

    def phi_t(self, q, t):
        return self.model.phi_t(q, t, self.p)

    def gamma(self, q, v, t):
        return self.model.gamma(q, v, t, self.p)

    def position_terms(self, q, t):
        """(Φ, Φ_q) sharing their subexpressions."""
        return self.model.position_terms(q, t, self.p)

    def terms(self, q, v, t):
        """(Φ, Φ_q, Φ_t, γ) sharing their subexpressions."""
        self.counters.constraint_terms += 1
        return self.model.terms(q, v, t, self.p)

    def worst_constraint(self, phi) -> str:
        """'<residual> in '<equation>' of '<joint or driver>'' for the largest |Φ_i|: how
        failures name the model object at fault."""
        phi = np.asarray(phi, float)
        i = int(np.nanargmax(np.abs(phi))) if phi.size and np.all(np.isfinite(phi)) else 0
        value = abs(phi[i]) if phi.size else 0.0
        return (f"{value:.3g} in '{self.constraint_names[i]}' of "
                f"'{self.constraint_owners[i]}'")

    # --- mass and forces -------------------------------------------------------------------
    def mass(self, q=None) -> np.ndarray:
        return np.diag(self.mass_diagonal)

    def forces(self, t, q, v) -> np.ndarray:
        """Generalized applied forces Q(t, q, v), shape (n,)."""
        Q = self._gravity_force.copy()
        self._add_loads(t, q, v, Q, elastic=True)
        return Q

    def nonconservative_forces(self, t, q, v) -> np.ndarray:
        """The part of Q with no potential: spring damping, point forces and torques."""
        Q = np.zeros(self.n)
        self._add_loads(t, q, v, Q, elastic=False)
        return Q

    def _add_loads(self, t, q, v, Q, elastic: bool):
        for sp in self.springs:
            if not elastic and not sp.damping:
                continue
            pa = _point(q, sp.a, sp.sa)
            pb = _point(q, sp.b, sp.sb)
            dx, dy = pb[0] - pa[0], pb[1] - pa[1]
            length = math.hypot(dx, dy)
            if length == 0.0:
                continue  # direction undefined; a zero-length spring carries no force
            ex, ey = dx / length, dy / length
            tension = sp.stiffness * (length - sp.rest_length) if elastic else 0.0
            if sp.damping:
                va = _velocity(q, v, sp.a, sp.sa)
                vb = _velocity(q, v, sp.b, sp.sb)
                tension += sp.damping * ((vb[0] - va[0]) * ex + (vb[1] - va[1]) * ey)
            _add_point_force(Q, q, sp.a, sp.sa, tension * ex, tension * ey)
            _add_point_force(Q, q, sp.b, sp.sb, -tension * ex, -tension * ey)
        for load in self.loads:
            value = load.value(t) if callable(load.value) else load.value
            if load.is_torque:
                Q[load.body + 2] += value
            else:
                fx, fy = value
                _add_point_force(Q, q, load.body, load.s, fx, fy)

    @property
    def has_nonconservative(self) -> bool:
        """Whether anything can do work besides gravity and elastic springs."""
        return bool(self.loads) or any(sp.damping for sp in self.springs) or \
            bool(self.rheonomic_rows)

    @property
    def rheonomic_rows(self) -> list[int]:
        """Rows of Φ that depend on time explicitly (drivers): they can do work."""
        return [i for i, name in enumerate(self.constraint_kinds) if name == "driver"]

    def power(self, t, q, v) -> tuple[float, float]:
        """(applied, driver) power: Q_ncᵀ v and λᵀ Φ_t. The constraint force −Φ_qᵀλ has
        power −λᵀ Φ_q v = λᵀ Φ_t, non-zero only on rows with explicit time dependence."""
        applied = float(self.nonconservative_forces(t, q, v) @ v)
        driver = 0.0
        if self.rheonomic_rows:
            _, J, phi_t, gamma = self.terms(q, v, t)
            _, lam = self.accelerations(J, self.forces(t, q, v), gamma)
            driver = float(lam @ phi_t)
        return applied, driver

    # --- energies (vectorized over leading dimensions) ---------------------------------------
    def kinetic_energy(self, q, v) -> np.ndarray:
        return 0.5 * np.einsum("...i,i,...i->...", v, self.mass_diagonal, v)

    def gravity_potential(self, q) -> np.ndarray:
        return -np.einsum("...i,i->...", q, self._gravity_force)

    def spring_potential(self, q) -> np.ndarray:
        total = np.zeros(np.shape(q)[:-1])
        for sp in self.springs:
            d = frame_point(q, sp.b, sp.sb) - frame_point(q, sp.a, sp.sa)
            total = total + 0.5 * sp.stiffness * (np.linalg.norm(d, axis=-1) - sp.rest_length) ** 2
        return total

    def potential_energy(self, q) -> np.ndarray:
        return self.gravity_potential(q) + self.spring_potential(q)

    def strain_energy(self, q) -> np.ndarray:
        return np.zeros(np.shape(q)[:-1])

    # --- projections onto the constraint manifold (mass metric) -------------------------------
    def project_positions(self, q, t, tol=1e-12, max_iter=20):
        """Newton steps Δq = −W Φ_qᵀ (Φ_q W Φ_qᵀ)⁺ Φ with W = M⁻¹: the smallest correction in
        the kinetic metric. Returns (q, iterations, final ‖Φ‖∞)."""
        q = np.array(q, float)
        w = self.inverse_mass_diagonal
        for k in range(max_iter + 1):
            phi, J = self.position_terms(q, t)
            err = float(np.max(np.abs(phi))) if phi.size else 0.0
            if err <= tol or k == max_iter or not np.isfinite(err):
                return q, k, err
            q -= w * (J.T @ _solve_psd((J * w) @ J.T, phi))
            self.counters.projections += 1
        return q, max_iter, err

    def project_velocities(self, q, v, t):
        """v − W Φ_qᵀ (Φ_q W Φ_qᵀ)⁺ (Φ_q v + Φ_t): the nearest consistent velocity."""
        J = self.phi_q(q, t)
        r = J @ v + self.phi_t(q, t)
        w = self.inverse_mass_diagonal
        return v - w * (J.T @ _solve_psd((J * w) @ J.T, r))

    def accelerations(self, J, Q, c):
        """Solve [M Φ_qᵀ; Φ_q 0][q̈; λ] = [Q; c] by the Schur complement of the diagonal M.
        Redundant constraints (a singular Φ_q M⁻¹ Φ_qᵀ) fall back to the least-squares λ."""
        w = self.inverse_mass_diagonal
        wq = w * Q
        lam = _solve_psd((J * w) @ J.T, J @ wq - c)
        self.counters.factorizations += 1
        return wq - w * (J.T @ lam), lam


def _solve_psd(S, r):
    try:
        return np.linalg.solve(S, r)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(S, r, rcond=None)[0]


def _point(q, start, s):
    if start is None:
        return s
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    return (q[start] + c * s[0] - sn * s[1], q[start + 1] + sn * s[0] + c * s[1])


def _velocity(q, v, start, s):
    if start is None:
        return (0.0, 0.0)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    w = v[start + 2]
    return (v[start] - w * (sn * s[0] + c * s[1]), v[start + 1] + w * (c * s[0] - sn * s[1]))


def _add_point_force(Q, q, start, s, fx, fy):
    if start is None:
        return
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    rx, ry = c * s[0] - sn * s[1], sn * s[0] + c * s[1]
    Q[start] += fx
    Q[start + 1] += fy
    Q[start + 2] += rx * fy - ry * fx
