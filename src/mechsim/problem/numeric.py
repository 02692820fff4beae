"""NumericProblem: the constrained equations of motion in numbers.

    M q̈ + Φ_qᵀ λ = Q(t, q, v),    Φ(q, t) = 0,    Φ_q q̈ = γ(q, v, t)

Formulations and integrators see only this object (as scipy's solvers see only `fun`): they
never touch a Body or a Joint. It joins three parts: the constraints (the generated model's
functions of (q, t) and its parameter values), the mass and the Schur-complement solves
(`mass`), and the loads (`loads`); and it projects states onto the constraints.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..linalg.newton import newton
from ..linalg.sparse import dense as as_dense, transpose_times
from .loads import Loads
from .mass import MassFactor, MassModel, SchurSolver, dense
from .multipliers import minimum_norm


# Velocities projected by a Cholesky factor of Φ_q M⁻¹ Φ_qᵀ are kept where ‖Φ_q v + Φ_t‖∞
# ends below this, relative to ‖Φ_q v‖∞ + ‖Φ_t‖∞ (at least 1); elsewhere the factor was
# of a rank-deficient complement (redundant rows: it solves to garbage without an error)
# or of another configuration, and the velocities' own projection serves.
VELOCITY_RESIDUAL = 1e-8


def velocities_hold(J, v, phi_t) -> bool:
    """Does v hold Φ_q v + Φ_t = 0 to `VELOCITY_RESIDUAL` (J = Φ_q, dense or sparse)?"""
    if not len(phi_t):
        return True
    Jv = J @ v
    scale = max(np.abs(Jv).max() + np.abs(phi_t).max(), 1.0)
    return bool(np.abs(Jv + phi_t).max() <= VELOCITY_RESIDUAL * scale)


@dataclass
class Counters:
    """Work counters, incremented by whoever does the work (scipy's nfev/njev/nlu)."""
    rhs: int = 0
    constraint_terms: int = 0
    factorizations: int = 0
    projections: int = 0
    partitions: int = 0
    switches: int = 0

    def compiled_rates(self, evaluations: int) -> None:
        """Rates a compiled step evaluated (`mechsim.integrators.compiled`): right-hand
        sides, each with its factorization."""
        self.rhs += evaluations
        self.factorizations += evaluations


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
    constraint_kinds : list of str, "joint", "driver" or "gear" for each row of Φ
    springs, loads, torsion : tuples of SpringData / PointLoad / RotationalSpringData
    flexible : tuple of FlexibleData; their blocks of M depend on q (`mass_diagonal` holds
        only nominal values there, and the rigid-body terms skip them)
    drawing : list of (body name, start, local points (p, 2), modal shapes (p, 2, k) or
        None): the polylines `SimulationResult.export` draws
    driver_laws : list of (driver name, `mechsim.model.expressions.Expression` in t): what
        each driver prescribes, for the failure messages of a run
    joints : dict joint name -> `mechsim.problem.geometry.JointGeometry`: what joint
        coordinates and reactions are evaluated from (results only; never the solvers)
    driver_joints : dict driver name -> the name of the joint it drives
    friction : `mechsim.problem.friction.FrictionModel` of the joints with friction or stops,
        or None: its forces join Q (solved with the reactions that load them)
    """

    def __init__(self, model, parameters, mass_diagonal, gravity, body_starts,
                 coordinate_names, constraint_names, constraint_owners,
                 springs=(), loads=(), title="mechanism", constraint_kinds=None,
                 flexible=(), drawing=(), driver_laws=(), joints=None, driver_joints=None,
                 torsion=(), gear_signs=None, friction=None, parameter_partials=None,
                 mass_partials=None):
        self.model = model
        self.p = tuple(float(x) for x in parameters)
        # name -> ∂p/∂(that design Parameter), (len(p),), for each Parameter the
        # mechanism's geometry depends on (`mechsim.model.parameters`).
        self.parameter_partials = dict(parameter_partials or {})
        # name -> ∂(mass diagonal)/∂(that Parameter), (n,), for the Parameters the rigid
        # bodies' masses and inertias depend on.
        self.mass_partials = dict(mass_partials or {})
        self.mass_model = MassModel(mass_diagonal, flexible)
        self.mass_diagonal = self.mass_model.diagonal
        self.inverse_mass_diagonal = self.mass_model.inverse_diagonal
        self.n = self.mass_diagonal.size
        self.m = int(model.M)
        self.body_starts = dict(body_starts)
        self.coordinate_names = list(coordinate_names)
        self.constraint_names = list(constraint_names)
        self.constraint_owners = list(constraint_owners)
        self.constraint_kinds = list(constraint_kinds or ["joint"] * len(self.constraint_names))
        self.title = title
        self.drawing = list(drawing)
        self.driver_laws = list(driver_laws)
        self.joints = dict(joints or {})
        self.driver_joints = dict(driver_joints or {})
        self.gear_signs = dict(gear_signs or {})    # gear name -> its force per unit of −λ
        self.counters = Counters()
        self.friction = friction
        self.flexible = tuple(flexible)
        self.constant_mass = self.mass_model.constant
        flex_starts = {fb.start for fb in self.flexible}
        rigid = [s for s in self.body_starts.values() if s is not None and s not in flex_starts]
        self.load_model = Loads(self.n, gravity, self.mass_diagonal, rigid, springs, loads,
                                flexible, torsion)
        self.gravity = self.load_model.gravity
        self.springs, self.loads = self.load_model.springs, self.load_model.loads
        self.solver = SchurSolver(self.mass_model, self._banded_form)
        self._sparse = None               # decided on first use (`sparse`)
        self._algebra = None              # decided on first use (`algebra`)

    def _banded_form(self):
        from ..linalg.banded import for_problem
        return for_problem(self)

    @property
    def schur(self):
        """The banded Schur complement of a large rigid mechanism (`mechsim.linalg.banded`), built
        on first use; None where the dense path serves. Assign None to force the dense
        path, or a `BandedSchur` to force the banded one."""
        return self.solver.band

    @schur.setter
    def schur(self, value):
        self.solver.band = value
        self._algebra = None

    @property
    def algebra(self):
        """The constraint algebra the solvers use (`mechsim.problem.algebra`): banded for
        a long chain with the banded Schur complement, else dense; chosen on first use and
        kept (assigning `schur` chooses again)."""
        if self._algebra is None or self._algebra.problem is not self:   # (a copy's own)
            from .algebra import choose
            self._algebra = choose(self)
        return self._algebra

    @algebra.setter
    def algebra(self, value):
        """Serve the solvers with another `ConstraintAlgebra` (made for this problem)."""
        if getattr(value, "problem", None) is not self:
            raise ValueError("`algebra` must be a ConstraintAlgebra made for this problem "
                             f"(its `problem`), got {value!r:.60}")
        self._algebra = value

    @property
    def sparse(self) -> bool:
        """Do the solvers take Φ_q as a CSR array of its fixed pattern (`mechsim.linalg.sparse`)?
        For a long chain (one with the banded Schur complement) whose model gives it (an
        assembled model): its Φ_q has a handful of entries a row, and a dense m × n array
        would make every evaluation O(mn). Assign False to force dense arrays."""
        if self._sparse is None:
            self._sparse = self.schur is not None and hasattr(self.model, "dynamics_terms_csr")
        return self._sparse

    @sparse.setter
    def sparse(self, value):
        self._sparse = bool(value)

    def start_run(self):
        """Forget what earlier runs left behind (the banded form's eigenvector warm starts,
        the compiled monitor's last SVD): the same run twice gives the same result."""
        band = self.solver.decided_band()
        if band is not None:
            band.forget()
        if self._algebra is not None and self._algebra.problem is self:
            self._algebra.forget()

    # --- constraints -----------------------------------------------------------------------
    def phi(self, q, t):
        return self.model.phi(q, t, self.p)

    def phi_q(self, q, t):
        return self.model.phi_q(q, t, self.p)

    def phi_t(self, q, t):
        return self.model.phi_t(q, t, self.p)

    def phi_many(self, Q, ts) -> np.ndarray:
        """Φ at the states (ts[i], Q[i]), shape (k, m): each state's `phi`, in one call
        where the model evaluates many states together (the assembled one)."""
        if hasattr(self.model, "phi_many"):
            return self.model.phi_many(Q, ts, self.p)
        return np.array([self.phi(q, t) for q, t in zip(Q, ts)]).reshape(len(Q), self.m)

    def phi_q_many(self, Q, ts) -> np.ndarray:
        """Φ_q at the states (ts[i], Q[i]), shape (k, m, n), as `phi_many`."""
        if hasattr(self.model, "phi_q_many"):
            return self.model.phi_q_many(Q, ts, self.p)
        return np.array([self.phi_q(q, t) for q, t in zip(Q, ts)]).reshape(
            len(Q), self.m, self.n)

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

    # Φ_q in the form the solvers take: CSR where `sparse`, else dense (`mechsim.linalg.sparse`).
    def solver_phi_q(self, q, t):
        return self.model.phi_q_csr(q, t, self.p) if self.sparse else self.phi_q(q, t)

    def solver_phi_q_many(self, Q, ts) -> list:
        """`solver_phi_q` at the states (ts[i], Q[i]): in one call where the model evaluates
        many states together (the assembled one)."""
        if self.sparse and hasattr(self.model, "phi_q_csr_many"):
            return self.model.phi_q_csr_many(Q, ts, self.p)
        return [self.solver_phi_q(q, t) for q, t in zip(Q, ts)]

    def solver_position_terms(self, q, t):
        if self.sparse:
            return self.model.position_terms_csr(q, t, self.p)
        return self.position_terms(q, t)

    def solver_dynamics_terms(self, q, v, t):
        if not self.sparse:
            return self.dynamics_terms(q, v, t)
        self.counters.constraint_terms += 1
        return self.model.dynamics_terms_csr(q, v, t, self.p)

    def worst_constraint(self, phi) -> str:
        """'<residual> in '<equation>' of '<joint or driver>'' for the largest |Φ_i|: how
        failures name the model object at fault."""
        phi = np.asarray(phi, float)
        i = int(np.nanargmax(np.abs(phi))) if phi.size and np.all(np.isfinite(phi)) else 0
        value = abs(phi[i]) if phi.size else 0.0
        return (f"{value:.3g} in '{self.constraint_names[i]}' of "
                f"'{self.constraint_owners[i]}'")

    @property
    def rheonomic_rows(self) -> list[int]:
        """Rows of Φ that depend on time explicitly (drivers): they can do work."""
        return [i for i, name in enumerate(self.constraint_kinds) if name == "driver"]

    def degrees_of_freedom(self, q, t) -> int:
        """n − rank Φ_q at (q, t) (`rank`)."""
        return self.n - self.rank(self.phi_q(q, t)) if self.m else self.n

    def rank(self, J) -> int:
        """The numerical rank of Φ_q = J: the number of its singular values above
        1e3 ε max(m, n) σ_max (as `Mechanism.dof`), by the problem's `algebra`."""
        return self.algebra.rank(J)

    # --- mass and forces -------------------------------------------------------------------
    def mass(self, q=None) -> np.ndarray:
        """M(q), shape (n, n); constant unless the mechanism has flexible bodies."""
        return self.mass_model.matrix(q)

    def mass_factor(self, q) -> MassFactor:
        """M(q) = L Lᵀ as a `MassFactor` (shared and constant for rigid mechanisms)."""
        return self.mass_model.factor(q)

    def forces(self, t, q, v) -> np.ndarray:
        """Generalized applied forces Q(t, q, v), shape (n,) (`Loads.forces`), with the
        joints' friction (`friction_state`) where the mechanism has any."""
        Q = self.load_model.forces(t, q, v)
        if self.friction is None or self.friction.idle:
            return Q
        return Q + self.friction.solve(self, t, q, v, Q).generalized()

    def constant_forces(self):
        """Q where it is the same at every state (gravity alone, no friction at work), else
        None."""
        if self.load_model.gravity_only and (self.friction is None or self.friction.idle):
            return self.load_model.gravity_force
        return None

    def forces_at(self, T, Q, V) -> np.ndarray:
        """`forces` at many states (rows), shape (N, n)."""
        F = self.load_model.forces_at(T, Q, V)
        if self.friction is None or self.friction.idle or not len(F):
            return F
        return F + [s.generalized() for s in self.friction.solve_many(self, T, Q, V, F)]

    def friction_state(self, t, q, v, modes=None):
        """The joints' friction forces at (t, q, v) with the reactions that load them: a
        `mechsim.problem.friction.FrictionState` (`modes` overrides the model's)."""
        return self.friction.solve(self, t, q, v, self.load_model.forces(t, q, v), modes)

    def with_friction(self, friction) -> "NumericProblem":
        """This problem with another `FrictionModel` (the same model and caches)."""
        other = copy.copy(self)
        other.friction = friction
        return other

    def nonconservative_forces(self, t, q, v) -> np.ndarray:
        """The part of Q with no potential (`Loads.nonconservative_forces`)."""
        return self.load_model.nonconservative_forces(t, q, v)

    def accelerations(self, J, Q, c, q=None, factor=None):
        """(q̈, λ) of [M Φ_qᵀ; Φ_q 0][q̈; λ] = [Q; c] by the Schur complement of M = L Lᵀ (a
        diagonal for rigid mechanisms; `q` is needed only when M depends on it). Redundant
        constraints (a singular Φ_q M⁻¹ Φ_qᵀ) fall back to the least-squares λ. `factor`:
        the complement's banded factor at J, if the caller has it (`mechsim.linalg.banded`)."""
        self.counters.factorizations += 1
        return self.solver.accelerations(J, Q, c, q, factor)

    def complement_solver(self, J, f):
        """r ↦ (Φ_q M⁻¹ Φ_qᵀ)⁻¹ r from one Cholesky factor at Φ_q = J (`f`: the mass factor
        there), banded where the problem has the banded form; None if the complement is
        not numerically positive definite (a singular configuration, redundancy)."""
        return self.solver.factored(J, f)

    # --- work and energies -----------------------------------------------------------------
    @property
    def work_channels(self) -> list[str]:
        """What can do work on the mechanism besides gravity and elastic springs, one name
        per channel of `work_rates`: the loads' channels (`Loads.work_channels`) and each
        each joint's friction ("friction 'f'") and each driver ("driver 'motor'")."""
        friction = self.friction.channels if self.friction is not None else []
        return self.load_model.work_channels + friction + \
            [f"driver '{d}'" for d in self._driver_owners()]

    def _driver_owners(self) -> list[str]:
        """The drivers owning rows of Φ, in order of their first row."""
        return list(dict.fromkeys(self.constraint_owners[i] for i in self.rheonomic_rows))

    def work_rates(self, t, q, v) -> np.ndarray:
        """The power of each of `work_channels` at the consistent state (q, v), shape (k,):
        the loads' (`Loads.powers`), friction's f ṡ, and a driver's λᵀ Φ_t over its rows
        (the constraint force −Φ_qᵀλ does the work −λᵀ Φ_q v = λᵀ Φ_t; λ from the equations
        of motion, least squares at a singular configuration)."""
        out = self.load_model.powers(t, q, v)
        owners = self._driver_owners()
        acting = self.friction is not None and not self.friction.idle
        Q = self.load_model.forces(t, q, v) if owners or acting else None
        if acting:
            state = self.friction.solve(self, t, q, v, Q)
            out += list((state.forces * state.rates)[self.friction.frictions])
            Q = Q + state.generalized()
        elif self.friction is not None:               # every friction free: no power
            out += [0.0] * len(self.friction.frictions)
        return np.array(out + self._driver_powers(t, q, v, Q, owners), float)

    def _driver_powers(self, t, q, v, Q, owners) -> list[float]:
        """λᵀ Φ_t over each driver's rows of `owners` at (t, q, v) under the forces Q."""
        if not owners:
            return []
        _, J, phi_t, gamma = self.terms(q, v, t)
        _, lam = self.accelerations(J, Q, gamma, q)
        return [float(sum(lam[i] * phi_t[i] for i in self.rheonomic_rows
                          if self.constraint_owners[i] == owner)) for owner in owners]

    def work_rates_many(self, T, Q, V) -> np.ndarray:
        """`work_rates` at the consistent states (T[i], Q[i], V[i]), shape (N, k). The
        drivers' λ and Φ_t come from the compiled engine for all states in one call where
        it takes them (the states whose Φ_q M⁻¹ Φ_qᵀ has a Cholesky factor, the same test
        as `accelerations`); the other states take `work_rates`. With friction acting, its
        forces at all states come from one `FrictionModel.solve_many`."""
        T = np.asarray(T, float)
        N, k = len(T), len(self.work_channels)
        owners = self._driver_owners()
        acting = self.friction is not None and not self.friction.idle
        lam = phi_t = ok = None
        if acting and N:                # friction's states solved together
            F = self.load_model.forces_at(T, Q, V)
            states = self.friction.solve_many(self, T, Q, V, F)
            rubbing = self.friction.frictions
            return np.hstack([
                self.load_model.powers_at(T, Q, V),
                np.array([(s.forces * s.rates)[rubbing] for s in states]).reshape(N, -1),
                np.array([self._driver_powers(t, q, v, f + s.generalized(), owners) for
                          t, q, v, f, s in zip(T, Q, V, F, states)]).reshape(N, -1)])
        if owners and not acting and N:
            lam, phi_t = np.zeros((N, self.m)), np.zeros((N, self.m))
            ok = self.algebra.multipliers(T, Q, V, self.load_model.forces_at(T, Q, V), -1.0,
                                          0.0, lam, phi_t)
        if ok is None:
            return np.array([self.work_rates(t, q, v) for t, q, v in zip(T, Q, V)]).reshape(
                N, k)
        rheonomic = self.rheonomic_rows
        P = lam * phi_t
        drivers = np.column_stack([
            P[:, [i for i in rheonomic if self.constraint_owners[i] == owner]].sum(axis=1)
            for owner in owners])
        idle = np.zeros((N, len(self.friction.frictions) if self.friction is not None else 0))
        out = np.hstack([self.load_model.powers_at(T, Q, V), idle, drivers])
        for i in np.flatnonzero(~ok):
            out[i] = self.work_rates(T[i], Q[i], V[i])
        return out

    def rows_of(self, owner: str) -> list[int]:
        """The rows of Φ that the joint or driver named `owner` wrote."""
        return [i for i, o in enumerate(self.constraint_owners) if o == owner]

    def multipliers(self, T, Q, V, passages=None):
        """λ at the consistent states (T[i], Q[i], V[i]), with the rows whose share is not
        unique there (`mechsim.problem.multipliers`; `passages`: the (t_start, t_end) of a
        run's singular passages, None where no monitor watched): a `Multipliers`."""
        from .multipliers import multipliers
        return multipliers(self, T, Q, V, passages)

    def kinetic_energy(self, q, v) -> np.ndarray:
        return self.mass_model.kinetic_energy(q, v)

    def gravity_potential(self, q) -> np.ndarray:
        return self.load_model.gravity_potential(q)

    def spring_potential(self, q) -> np.ndarray:
        return self.load_model.spring_potential(q)

    def potential_energy(self, q) -> np.ndarray:
        return self.gravity_potential(q) + self.spring_potential(q)

    def strain_energy(self, q) -> np.ndarray:
        """Elastic energy of the flexible bodies' modes, ½ Σ ω_k² η_k²."""
        return self.load_model.strain_energy(q)

    def stored_energy(self, q) -> np.ndarray:
        """The energy the configuration holds: gravity's and the springs' potential and
        the beams' strain (what `work_channels` leave out)."""
        return self.potential_energy(q) + self.strain_energy(q)

    # --- projections onto the constraint manifold (mass metric) -----------------------------
    def project_positions(self, q, t, tol=1e-12, max_iter=20):
        """Newton steps Δq = −W Φ_qᵀ (Φ_q W Φ_qᵀ)⁺ Φ with W = M⁻¹: the smallest correction in
        the kinetic metric, a fresh Jacobian each iteration. Returns (q, iterations, final
        ‖Φ‖∞); stops at round-off (`mechsim.linalg.newton`)."""
        f = self.mass_factor(q)

        def correct(q, phi, J, slow):
            self.counters.projections += 1
            return q - f.right(transpose_times(f.cols(J), self.solver.solve(J, phi, f)))

        done = newton(np.array(q, float), lambda q: self.solver_position_terms(q, t), correct,
                      tol, max_iter, stall=True)
        return done.x, done.iterations, done.residual

    def project_state(self, q, v, t, tol, extra=0, max_iter=8, solve=None):
        """(q, v) with ‖Φ‖∞ ≤ tol (then `extra` further iterations) and Φ_q v + Φ_t = 0, by
        a chord Newton in the mass metric whose single factor of Φ_q M⁻¹ Φ_qᵀ at the given
        q also serves the velocity projection: where the corrections are small (a state
        off the manifold by an integrator's error) each iteration gains the digits by
        which Φ_q moves, and the one factor does the work of the three or four that
        `project_positions` and `project_velocities` form. `solve`: the factor's solve
        (`complement_solver`) if the caller has it. None where the complement cannot be
        factored or the chord does not converge; the full projections serve there. The
        velocities are projected again at the new q (`project_velocities`) where the
        chord's factor leaves them off their constraints (`velocities_hold`)."""
        f = self.mass_factor(q)
        phi, J = self.solver_position_terms(q, t)
        if solve is None:
            solve = self.complement_solver(J, f)
            if solve is None:
                return None
        Jt = f.cols(J)
        first = [phi]

        def residual(q):
            return (first.pop() if first else self.phi(q, t)), None

        def correct(q, phi, _, slow):
            self.counters.projections += 1
            return q - f.right(transpose_times(Jt, solve(phi)))

        done = newton(np.array(q, float), residual, correct, tol, max_iter, stall=True,
                      extra=extra)
        if not done.converged:
            return None
        return done.x, self.velocities_by(done.x, v, t, solve)

    def velocities_by(self, q, v, t, solve, J=None):
        """v projected onto Φ_q v + Φ_t = 0 at q in the mass metric with `solve`, the
        complement's factor at a configuration near q (a chord's), where that leaves them
        on their constraints (`velocities_hold`); else by their own projection at q.
        `J`: `solver_phi_q` at (q, t), if the caller has it."""
        J = self.solver_phi_q(q, t) if J is None else J
        f = self.mass_factor(q)
        phi_t = self.phi_t(q, t)
        moved = v - f.right(transpose_times(f.cols(J), solve(J @ v + phi_t)))
        if velocities_hold(J, moved, phi_t):
            return moved
        # The factor at the given q leaves J v off by |ΔJ| |Δv| at the new q (a long step's
        # sample), or it was of a singular complement (redundant rows): the velocities'
        # own projection at the new q.
        return self.project_velocities(q, v, t)

    def project_velocities(self, q, v, t, extra=None):
        """v − W Φ_qᵀ (Φ_q W Φ_qᵀ)⁺ (Φ_q v + Φ_t): the nearest consistent velocity in the
        mass metric (the least-norm correction where Φ_q has redundant rows). `extra` =
        (G, r): also G v = r (prescribed joint rates), the same way with [Φ_q; G] (least
        squares where the rows cannot all hold)."""
        J = self.solver_phi_q(q, t) if extra is None else self.phi_q(q, t)
        phi_t = self.phi_t(q, t)
        r = J @ v + phi_t
        f = self.mass_factor(q)
        if extra is not None:
            G, rates = extra
            A, r = np.vstack([J, G]), np.concatenate([r, G @ v - rates])
            At = f.cols(A)
            return v - f.right(At.T @ dense().solve_psd(At @ At.T, r))
        out = v - f.right(transpose_times(f.cols(J), self.solver.solve(J, r, f)))
        if velocities_hold(J, out, phi_t):
            return out
        # Redundant rows: a Cholesky factor of the singular complement solved to garbage
        # without an error; the least-norm correction leaves their directions out.
        Jt = f.cols(as_dense(J))
        return v - f.right(Jt.T @ minimum_norm(Jt, r)[0])
