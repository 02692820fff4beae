"""NumericProblem: the constrained equations of motion in numbers, and nothing else.

    M q̈ + Φ_qᵀ λ = Q(t, q, v),    Φ(q, t) = 0,    Φ_q q̈ = γ(q, v, t)

Formulations and integrators see only this object (as scipy's solvers see only `fun`): they
never touch a Body or a Joint. For rigid bodies in absolute coordinates M is constant and
diagonal, so it is stored once as `mass_diagonal` and never rebuilt; a flexible beam adds a
dense block that depends on its angle and modal amplitudes (`mechsim.flexible.invariants`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np


def _local(q, start, s, modal):
    """Body-frame position of attachment point `s`, moved by the modal displacement
    `modal` (2, k) · η for a point of a flexible body."""
    s = np.asarray(s, float)
    if modal is None:
        return np.broadcast_to(s, q.shape[:-1] + (2,))
    k = modal.shape[1]
    return s + q[..., start + 3:start + 3 + k] @ modal.T


def frame_point(q: np.ndarray, start: int | None, s, modal=None) -> np.ndarray:
    """Global position of body-fixed point `s` of the body whose (x, y, angle) start at
    index `start` of `q` (None: the ground); on a flexible body `modal` (2, k) adds the
    point's modal displacement. `q` has shape (..., n); result (..., 2)."""
    if start is None:
        return np.broadcast_to(np.asarray(s, float), q.shape[:-1] + (2,)).copy()
    u = _local(q, start, s, modal)
    th = q[..., start + 2]
    c, sn = np.cos(th), np.sin(th)
    return np.stack([q[..., start] + c * u[..., 0] - sn * u[..., 1],
                     q[..., start + 1] + sn * u[..., 0] + c * u[..., 1]], axis=-1)


def frame_point_velocity(q: np.ndarray, v: np.ndarray, start: int | None, s,
                         modal=None) -> np.ndarray:
    """Velocity of body-fixed point `s`: Ṙ + ω × (A ū) + A (modal · η̇). Shapes as in
    `frame_point`."""
    if start is None:
        return np.zeros(q.shape[:-1] + (2,))
    u = _local(q, start, s, modal)
    th, w = q[..., start + 2], v[..., start + 2]
    c, sn = np.cos(th), np.sin(th)
    dx = -w * (sn * u[..., 0] + c * u[..., 1])
    dy = w * (c * u[..., 0] - sn * u[..., 1])
    if modal is not None:
        du = v[..., start + 3:start + 3 + modal.shape[1]] @ modal.T
        dx = dx + c * du[..., 0] - sn * du[..., 1]
        dy = dy + sn * du[..., 0] + c * du[..., 1]
    return np.stack([v[..., start] + dx, v[..., start + 1] + dy], axis=-1)


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
    modal_a: np.ndarray | None = None     # (2, k) modal displacement of a point on a beam
    modal_b: np.ndarray | None = None


@dataclass(frozen=True)
class PointLoad:
    """A force (constant 2-vector or callable of t) at body-fixed point `s`, or a torque."""
    name: str
    body: int
    s: tuple[float, float] | None
    value: object          # ndarray (2,), float, or callable of t
    is_torque: bool
    modal: np.ndarray | None = None


class FlexibleData:
    """A flexible beam's block of coordinates, (x, y, angle, η₁ … η_k) from `start`, with its
    invariants and generated kernel (`mechsim.flexible`); `point_modes(local)` gives the
    (2, k) modal displacement of a body point."""
    __slots__ = ("name", "start", "invariants", "kernel", "parameters", "slice", "point_modes")

    def __init__(self, name, start, invariants, kernel, parameters, point_modes=None):
        self.name, self.start, self.invariants = name, start, invariants
        self.kernel, self.parameters = kernel, tuple(parameters)
        self.point_modes = point_modes
        self.slice = slice(start, start + 3 + invariants.n_modes)


class MassFactor:
    """M = L Lᵀ at one configuration, applied as L⁻¹ and L⁻ᵀ. For constant diagonal mass
    L⁻¹ is the vector `s` = M^{-1/2}; otherwise the dense block-diagonal `Linv`."""
    __slots__ = ("s", "Linv")

    def __init__(self, s=None, Linv=None):
        self.s, self.Linv = s, Linv

    def cols(self, J):
        """J L⁻ᵀ: the mass-scaled Jacobian."""
        return J * self.s if self.Linv is None else J @ self.Linv.T

    def left(self, x):
        """L⁻¹ x."""
        return self.s * x if self.Linv is None else self.Linv @ x

    def right(self, x):
        """L⁻ᵀ x."""
        return self.s * x if self.Linv is None else self.Linv.T @ x

    def unright(self, x):
        """Lᵀ x, the inverse of `right`: accelerations q̈ into the scaled x = Lᵀ q̈."""
        return x / self.s if self.Linv is None else np.linalg.solve(self.Linv.T, x)


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
    flexible : tuple of FlexibleData; their blocks of M depend on q (`mass_diagonal` holds
        only nominal values there, and the rigid-body terms skip them)
    drawing : list of (body name, start, local points (p, 2), modal shapes (p, 2, k) or
        None): the polylines `SimulationResult.export` draws
    driver_laws : list of (driver name, `mechsim.model.expressions.Expression` in t): what
        each driver prescribes, for the failure messages of a run
    """

    def __init__(self, model, parameters, mass_diagonal, gravity, body_starts,
                 coordinate_names, constraint_names, constraint_owners,
                 springs=(), loads=(), title="mechanism", constraint_kinds=None,
                 flexible=(), drawing=(), driver_laws=()):
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
        self.drawing = list(drawing)
        self.driver_laws = list(driver_laws)
        self.counters = Counters()
        self.flexible = tuple(flexible)
        self.constant_mass = not self.flexible
        # Rigid bodies only: their mass is constant and diagonal.
        self._rigid_mass = self.mass_diagonal.copy()
        flex_starts = set()
        for fb in self.flexible:
            self._rigid_mass[fb.slice] = 0.0
            flex_starts.add(fb.start)
        self._factor = MassFactor(s=1.0 / np.sqrt(self.mass_diagonal)) if self.constant_mass \
            else None
        self._rigid_factor = np.diag(np.sqrt(1.0 / np.where(self._rigid_mass > 0.0,
                                                            self._rigid_mass, 1.0)))
        self._last_factor = None          # (key, MassFactor) of the latest flexible state
        self._schur = False               # not yet decided (see `schur`)
        # Gravity's generalized force on rigid bodies is constant: m g on their x and y.
        self._gravity_force = np.zeros(self.n)
        for start in self.body_starts.values():
            if start is not None and start not in flex_starts:
                self._gravity_force[start:start + 2] = self.mass_diagonal[start] * self.gravity

    @property
    def schur(self):
        """The banded Schur complement of a large rigid mechanism (`mechsim.banded`), built
        on first use; None where the dense path serves. Assign None to force the dense
        path, or a `BandedSchur` to force the banded one."""
        if self._schur is False:
            from .banded import for_problem
            self._schur = for_problem(self)
        return self._schur

    def start_run(self):
        """Forget what earlier runs left behind (the banded form's eigenvector warm starts):
        the same run twice gives the same result."""
        if self._schur not in (False, None):
            self._schur.forget()

    @schur.setter
    def schur(self, value):
        self._schur = value

    def _schur_solve(self, J, r, f=None, factor=None):
        """(Φ_q M⁻¹ Φ_qᵀ)⁻¹ r: banded Cholesky where available (`factor`: its factor, if the
        caller has it), else dense Cholesky with the least-squares solution for a singular
        complement (redundant constraints). The dense complement is formed from the
        mass-scaled J̃ = f.cols(J), or as (J W) Jᵀ when `f` is None (constant mass)."""
        band = self._band()
        if band is not None:
            c = band.factor(J) if factor is None else factor
            if c is not None:
                return band.solve(c, r)
        return _solve_psd(self._complement(J, f), r)

    def _band(self):
        """The banded form of Φ_q M⁻¹ Φ_qᵀ where it serves (constant mass), else None."""
        return self.schur if self._factor is not None else None

    def _complement(self, J, f=None):
        """The dense Φ_q M⁻¹ Φ_qᵀ: J̃J̃ᵀ from J̃ = f.cols(J), or (J W) Jᵀ (constant mass)."""
        if f is None:
            return (J * self.inverse_mass_diagonal) @ J.T
        Jt = f.cols(J)
        return Jt @ Jt.T

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

    def dynamics_terms(self, q, v, t):
        """(Φ_q, γ) sharing their subexpressions: what q̈ needs."""
        self.counters.constraint_terms += 1
        return self.model.dynamics_terms(q, v, t, self.p)

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
        """M(q), shape (n, n); constant unless the mechanism has flexible bodies."""
        M = np.diag(self._rigid_mass)
        for fb in self.flexible:
            if q is None:
                raise ValueError("the mass matrix of a flexible mechanism depends on q")
            M[fb.slice, fb.slice] = fb.kernel.mass_block(q[fb.slice], fb.parameters)
        return M

    def mass_factor(self, q) -> MassFactor:
        """M(q) = L Lᵀ as a `MassFactor` (shared and constant for rigid mechanisms)."""
        if self._factor is not None:
            return self._factor
        key = np.concatenate([q[fb.slice][2:] for fb in self.flexible]).tobytes()
        if self._last_factor is not None and self._last_factor[0] == key:
            return self._last_factor[1]
        from .flexible.invariants import inverse_cholesky
        Linv = self._rigid_factor.copy()
        for fb in self.flexible:
            Linv[fb.slice, fb.slice] = inverse_cholesky(fb.kernel.mass_block(q[fb.slice],
                                                                             fb.parameters))
        f = MassFactor(Linv=Linv)
        self._last_factor = (key, f)
        return f

    def forces(self, t, q, v) -> np.ndarray:
        """Generalized applied forces Q(t, q, v), shape (n,): for flexible bodies including
        the quadratic-velocity (centrifugal and Coriolis) terms of M(q)."""
        Q = self._gravity_force.copy()
        for fb in self.flexible:
            Q[fb.slice] += fb.kernel.forces(q[fb.slice], v[fb.slice], fb.parameters)
        self._add_loads(t, q, v, Q, elastic=True)
        return Q

    def nonconservative_forces(self, t, q, v) -> np.ndarray:
        """The part of Q with no potential: spring damping, point forces and torques, and
        the modal damping of flexible beams."""
        Q = np.zeros(self.n)
        self._add_loads(t, q, v, Q, elastic=False)
        for fb in self.flexible:
            modes = slice(fb.start + 3, fb.slice.stop)
            Q[modes] -= fb.invariants.damping * v[modes]
        return Q

    def _add_loads(self, t, q, v, Q, elastic: bool):
        for sp in self.springs:
            if not elastic and not sp.damping:
                continue
            pa = _point(q, sp.a, sp.sa, sp.modal_a)
            pb = _point(q, sp.b, sp.sb, sp.modal_b)
            dx, dy = pb[0] - pa[0], pb[1] - pa[1]
            length = math.hypot(dx, dy)
            if length == 0.0:
                continue  # direction undefined; a zero-length spring carries no force
            ex, ey = dx / length, dy / length
            tension = sp.stiffness * (length - sp.rest_length) if elastic else 0.0
            if sp.damping:
                va = _velocity(q, v, sp.a, sp.sa, sp.modal_a)
                vb = _velocity(q, v, sp.b, sp.sb, sp.modal_b)
                tension += sp.damping * ((vb[0] - va[0]) * ex + (vb[1] - va[1]) * ey)
            _add_point_force(Q, q, sp.a, sp.sa, tension * ex, tension * ey, sp.modal_a)
            _add_point_force(Q, q, sp.b, sp.sb, -tension * ex, -tension * ey, sp.modal_b)
        for load in self.loads:
            value = load.value(t) if callable(load.value) else load.value
            if load.is_torque:
                Q[load.body + 2] += value
            else:
                fx, fy = value
                _add_point_force(Q, q, load.body, load.s, fx, fy, load.modal)

    @property
    def rheonomic_rows(self) -> list[int]:
        """Rows of Φ that depend on time explicitly (drivers): they can do work."""
        return [i for i, name in enumerate(self.constraint_kinds) if name == "driver"]

    @property
    def work_channels(self) -> list[str]:
        """What can do work on the mechanism besides gravity and elastic springs, one name
        per channel of `work_rates`: each damped spring ("spring 's' (damping)"), each load
        ("load 'F'"), each beam with modal damping ("beam 'b' (modal damping)") and each
        driver ("driver 'motor'")."""
        names = [f"spring '{sp.name}' (damping)" for sp in self.springs if sp.damping]
        names += [f"load '{load.name}'" for load in self.loads]
        names += [f"beam '{fb.name}' (modal damping)" for fb in self.flexible
                  if np.any(fb.invariants.damping > 0.0)]
        names += [f"driver '{d}'" for d in self._driver_owners()]
        return names

    def _driver_owners(self) -> list[str]:
        """The drivers owning rows of Φ, in order of their first row."""
        return list(dict.fromkeys(self.constraint_owners[i] for i in self.rheonomic_rows))

    def work_rates(self, t, q, v) -> np.ndarray:
        """The power of each of `work_channels` at the consistent state (q, v), shape (k,):
        a damper's −c ṡ² (ṡ its rate of extension), a load's F·ṗ or τ ω, a beam's
        −Σ d_k η̇_k², a driver's λᵀ Φ_t over its rows (the constraint force −Φ_qᵀλ does
        the work −λᵀ Φ_q v = λᵀ Φ_t; λ from the equations of motion, least squares at a
        singular configuration)."""
        out = []
        for sp in self.springs:
            if not sp.damping:
                continue
            pa = _point(q, sp.a, sp.sa, sp.modal_a)
            pb = _point(q, sp.b, sp.sb, sp.modal_b)
            d = np.subtract(pb, pa)
            length = math.hypot(d[0], d[1])
            if length == 0.0:
                out.append(0.0)
                continue
            rate = (np.subtract(_velocity(q, v, sp.b, sp.sb, sp.modal_b),
                                _velocity(q, v, sp.a, sp.sa, sp.modal_a)) @ d) / length
            out.append(-sp.damping * rate * rate)
        for load in self.loads:
            value = load.value(t) if callable(load.value) else load.value
            if load.is_torque:
                out.append(float(value) * v[load.body + 2])
            else:
                out.append(float(np.dot(value, _velocity(q, v, load.body, load.s, load.modal))))
        for fb in self.flexible:
            d = fb.invariants.damping
            if np.any(d > 0.0):
                rates = v[fb.start + 3:fb.slice.stop]
                out.append(-float(np.sum(d * rates * rates)))
        owners = self._driver_owners()
        if owners:
            _, J, phi_t, gamma = self.terms(q, v, t)
            _, lam = self.accelerations(J, self.forces(t, q, v), gamma, q)
            for owner in owners:
                out.append(float(sum(lam[i] * phi_t[i] for i in self.rheonomic_rows
                                     if self.constraint_owners[i] == owner)))
        return np.array(out, float)

    # --- energies (vectorized over leading dimensions) ---------------------------------------
    def kinetic_energy(self, q, v) -> np.ndarray:
        T = 0.5 * np.einsum("...i,i,...i->...", v, self._rigid_mass, v)
        for fb in self.flexible:
            T = T + fb.invariants.kinetic(q[..., fb.slice], v[..., fb.slice])
        return T

    def gravity_potential(self, q) -> np.ndarray:
        V = -np.einsum("...i,i->...", q, self._gravity_force)
        for fb in self.flexible:
            V = V + fb.invariants.gravity_potential(q[..., fb.slice], self.gravity)
        return V

    def spring_potential(self, q) -> np.ndarray:
        total = np.zeros(np.shape(q)[:-1])
        for sp in self.springs:
            d = frame_point(q, sp.b, sp.sb, sp.modal_b) - frame_point(q, sp.a, sp.sa, sp.modal_a)
            total = total + 0.5 * sp.stiffness * (np.linalg.norm(d, axis=-1) - sp.rest_length) ** 2
        return total

    def potential_energy(self, q) -> np.ndarray:
        return self.gravity_potential(q) + self.spring_potential(q)

    def strain_energy(self, q) -> np.ndarray:
        """Elastic energy of the flexible bodies' modes, ½ Σ ω_k² η_k²."""
        U = np.zeros(np.shape(q)[:-1])
        for fb in self.flexible:
            U = U + fb.invariants.strain(q[..., fb.slice])
        return U

    def degrees_of_freedom(self, q, t) -> int:
        """n − rank Φ_q at (q, t) (the rank from the SVD, as `Mechanism.dof`)."""
        if self.m == 0:
            return self.n
        J = self.phi_q(q, t)
        s = _dense().svdvals(J)
        tol = max(J.shape) * np.finfo(float).eps * 1e3 * (s[0] if s.size else 1.0)
        return self.n - int(np.sum(s > tol))

    # --- projections onto the constraint manifold (mass metric) -------------------------------
    def project_positions(self, q, t, tol=1e-12, max_iter=20):
        """Newton steps Δq = −W Φ_qᵀ (Φ_q W Φ_qᵀ)⁺ Φ with W = M⁻¹: the smallest correction in
        the kinetic metric. Returns (q, iterations, final ‖Φ‖∞). Stops early where the
        residual is within 1000 tol and no longer halves (`newton_stalled`)."""
        q = np.array(q, float)
        f = self.mass_factor(q)
        prev = np.inf
        for k in range(max_iter + 1):
            phi, J = self.position_terms(q, t)
            err = float(np.max(np.abs(phi))) if phi.size else 0.0
            if err <= tol or k == max_iter or not np.isfinite(err) or \
                    newton_stalled(err, prev, tol):
                return q, k, err
            prev = err
            q -= f.right(f.cols(J).T @ self._schur_solve(J, phi, f))
            self.counters.projections += 1
        return q, max_iter, err

    def complement_solver(self, J, f):
        """r ↦ (Φ_q M⁻¹ Φ_qᵀ)⁻¹ r from one Cholesky factor at Φ_q = J (`f`: the mass factor
        there), banded where the problem has the banded form; None if the complement is
        not numerically positive definite (a singular configuration, redundancy)."""
        band = self._band()
        if band is not None:
            c = band.factor(J)
            return None if c is None else (lambda r: band.solve(c, r))
        dense = _dense()
        c = dense.cho_factor_or_none(self._complement(J, f))
        return None if c is None else (lambda r: dense.cho_solve(c, r))

    def project_state(self, q, v, t, tol, extra=0, max_iter=8, solve=None):
        """(q, v) with ‖Φ‖∞ ≤ tol (then `extra` further iterations) and Φ_q v + Φ_t = 0, by
        a chord Newton in the mass metric whose single factor of Φ_q M⁻¹ Φ_qᵀ at the given
        q also serves the velocity projection: where the corrections are small (a state
        off the manifold by an integrator's error) each iteration gains the digits by
        which Φ_q moves, and the one factor does the work of the three or four that
        `project_positions` and `project_velocities` form. `solve`: the factor's solve
        (`complement_solver`) if the caller has it. None where the complement cannot be
        factored or the chord does not converge; the full projections serve there."""
        f = self.mass_factor(q)
        phi, J = self.position_terms(q, t)
        if solve is None:
            solve = self.complement_solver(J, f)
            if solve is None:
                return None
        Jt = f.cols(J)
        q = np.array(q, float)
        prev = np.inf
        for k in range(max_iter + 1):
            err = max(abs(phi).tolist(), default=0.0)
            if err <= tol or newton_stalled(err, prev, tol):
                break
            if k == max_iter:
                return None
            prev = err
            q -= f.right(Jt.T @ solve(phi))
            self.counters.projections += 1
            phi = self.phi(q, t)
        for _ in range(extra):
            q -= f.right(Jt.T @ solve(phi))
            self.counters.projections += 1
            phi = self.phi(q, t)
        J = self.phi_q(q, t)
        f = self.mass_factor(q)
        r = J @ v + self.phi_t(q, t)
        return q, v - f.right(f.cols(J).T @ solve(r))

    def project_velocities(self, q, v, t):
        """v − W Φ_qᵀ (Φ_q W Φ_qᵀ)⁺ (Φ_q v + Φ_t): the nearest consistent velocity."""
        J = self.phi_q(q, t)
        r = J @ v + self.phi_t(q, t)
        f = self.mass_factor(q)
        return v - f.right(f.cols(J).T @ self._schur_solve(J, r, f))

    def accelerations(self, J, Q, c, q=None, factor=None):
        """Solve [M Φ_qᵀ; Φ_q 0][q̈; λ] = [Q; c] by the Schur complement of M = L Lᵀ (a
        diagonal for rigid mechanisms; `q` is needed only when M depends on it). Redundant
        constraints (a singular Φ_q M⁻¹ Φ_qᵀ) fall back to the least-squares λ. `factor`:
        the complement's banded factor at J, if the caller has it (`mechsim.banded`)."""
        self.counters.factorizations += 1
        if self._factor is not None:
            w = self.inverse_mass_diagonal
            wq = w * Q
            lam = self._schur_solve(J, J @ wq - c, factor=factor)
            return wq - w * (J.T @ lam), lam
        f = self.mass_factor(q)
        Jt, x = f.cols(J), f.left(Q)
        lam = _solve_psd(Jt @ Jt.T, Jt @ x - c)
        return f.right(x - Jt.T @ lam), lam


def newton_stalled(err, prev, tol):
    """Has a Newton iteration on Φ reached round-off? The residual no longer halves and is
    within 1000 tol: a tolerance below the round-off of large coordinates (the 40-window
    chain's reach 20 m, ‖Φ‖ settles at 7e-15 against a projection tolerance of 1e-15) is
    met as closely as arithmetic allows instead of iterating to the limit."""
    return err > 0.5 * prev and err <= 1e3 * tol


def _solve_psd(S, r):
    return _dense().solve_psd(S, r)


@functools.cache
def _dense():
    """`mechsim.dense`, imported on first use (scipy: not needed to build a scene). An
    import statement in the function that solves would cost 2.7 µs a call, as much as the
    Cholesky solve it imports."""
    from . import dense
    return dense


def _moved(q, start, s, modal):
    if modal is None:
        return s
    d = modal @ q[start + 3:start + 3 + modal.shape[1]]
    return (s[0] + d[0], s[1] + d[1])


def _point(q, start, s, modal=None):
    if start is None:
        return s
    s = _moved(q, start, s, modal)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    return (q[start] + c * s[0] - sn * s[1], q[start + 1] + sn * s[0] + c * s[1])


def _velocity(q, v, start, s, modal=None):
    if start is None:
        return (0.0, 0.0)
    s = _moved(q, start, s, modal)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    w = v[start + 2]
    vx, vy = v[start] - w * (sn * s[0] + c * s[1]), v[start + 1] + w * (c * s[0] - sn * s[1])
    if modal is not None:
        du = modal @ v[start + 3:start + 3 + modal.shape[1]]
        vx, vy = vx + c * du[0] - sn * du[1], vy + sn * du[0] + c * du[1]
    return (vx, vy)


def _add_point_force(Q, q, start, s, fx, fy, modal=None):
    """Generalized force of a point force (fx, fy) at body point `s`: on R the force, on θ
    its moment about the frame origin, on η its work through the point's mode shapes."""
    if start is None:
        return
    s = _moved(q, start, s, modal)
    c, sn = math.cos(q[start + 2]), math.sin(q[start + 2])
    rx, ry = c * s[0] - sn * s[1], sn * s[0] + c * s[1]
    Q[start] += fx
    Q[start + 1] += fy
    Q[start + 2] += rx * fy - ry * fx
    if modal is not None:
        k = modal.shape[1]
        Q[start + 3:start + 3 + k] += modal.T @ (c * fx + sn * fy, -sn * fx + c * fy)
