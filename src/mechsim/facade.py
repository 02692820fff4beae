"""The user's `Mechanism`: the declarative model (`mechsim.model.MechanismModel`) with what
can be done with it: its numeric problem built (`mechsim.build`), assembled, simulated
(`mechsim.run.solver`, or the runs between events of `mechsim.engineering.impacts`), analysed
(equilibrium, linearization, kinematics) and driven to a periodic steady state
(`mechsim.shooting`).

This module stands at the top of the package: it may call every layer, and no layer below
imports it. The model knows nothing of the numerics, so a new analysis is added here (or in
its own module) without the model learning of it. Each method loads what it needs when it
is called: importing mechsim stays light.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .model.checks import ModelError
from .model.mechanism import AssemblyError, AssemblyReport, DofReport, MechanismModel

__all__ = ["Mechanism"]


class Mechanism(MechanismModel):
    """A planar mechanism: bodies, joints, drivers and loads, and what it does.

    >>> import mechsim as ms
    >>> mech = ms.Mechanism("pendulum", gravity=(0.0, -9.81))
    >>> rod = mech.add(ms.RigidBody.rod("rod", (0, 0), (1, 0), mass=1.0))
    >>> _ = mech.add(ms.Revolute(mech.ground, rod, at=(0, 0)))
    >>> mech.dof().dof
    1
    """

    # --- the numeric problem -----------------------------------------------------------------
    def problem(self, build: str | None = None):
        """The NumericProblem of this mechanism, built once (`mechsim.build`). `build`:
        "fused" (one generated model for the whole mechanism, compiled where small),
        "assembled" (from joint-type kernels: no sympy run for a new structure), or
        "auto" (the fused model where the cache has it or the mechanism is small, else the
        assembled one; `mechsim.build.constraint_model`); None: `$MECHSIM_BUILD`, else
        "auto". Asking for another build than the one made
        rebuilds."""
        from .build import build_mode, build_problem
        mode = None if build is None else build_mode(build)
        if self._problem is None or (mode is not None and mode != self._build):
            if not self.bodies:
                raise ModelError(f"mechanism '{self.name}' has no moving bodies")
            self._build = mode or build_mode()
            self._problem, self.from_cache = build_problem(self, self._build)
            import warnings
            for text in self.placement_warnings():
                warnings.warn(f"mechsim: mechanism '{self.name}': {text}", stacklevel=2)
        return self._problem

    # --- analysis ----------------------------------------------------------------------------
    def dof(self, t: float = 0.0) -> DofReport:
        """Degrees of freedom from the rank of Φ_q at the (assembled, if available) initial
        configuration; names the joints whose equations are redundant."""
        prob = self.problem()
        q = self._assembled.q if self._assembled is not None else self.initial_coordinates()
        J = prob.phi_q(q, t)
        m, n = J.shape
        if m == 0:
            return DofReport(n, 0, 0, n, 0, [], np.zeros(0))
        U, s, _ = np.linalg.svd(J)
        from .problem.algebra import RANK_FACTOR
        tol = max(m, n) * np.finfo(float).eps * RANK_FACTOR * (s[0] if s.size else 1.0)
        rank = int(np.sum(s > tol))
        involved = []
        if rank < m:
            left_null = U[:, rank:]          # combinations of rows that vanish: redundancy
            weight = np.linalg.norm(left_null, axis=1)
            for i in np.flatnonzero(weight > 1e-8):
                if prob.constraint_owners[i] not in involved:
                    involved.append(prob.constraint_owners[i])
        return DofReport(n, m, rank, n - rank, m - rank, involved, s)

    def compilation(self):
        """Whether compiled C serves this mechanism's runs: a `Compilation` with `kernels`
        (its generated functions run as C), `engine` (compiled evaluations of the rigid
        formulations) and the `reason` where neither does (no compiler and the compiler's
        error, `MECHSIM_NO_COMPILE`, flexible bodies, …). Builds what is missing."""
        from .codegen.compiled import compilation
        return compilation(self.problem())

    def assemble(self, t: float = 0.0, tol: float = 1e-10, max_iter: int = 50) -> AssemblyReport:
        """Make the initial state consistent: positions by Newton with the smallest change
        (kinetic metric), then velocities by projection in the mass metric. Consistent input is
        kept exactly. Raises AssemblyError naming the joint with the largest residual, or a
        driver whose law (or its rate or acceleration) is undefined at t."""
        for name, value, rule in (("tol", tol, "a positive number"),
                                  ("max_iter", max_iter, "a whole number ≥ 1")):
            ok = (isinstance(value, numbers.Real) and not isinstance(value, bool) and
                  value > 0 and math.isfinite(value) and
                  (name == "tol" or float(value).is_integer()))
            if not ok:
                raise ValueError(f"assemble: `{name}` must be {rule}, got {value!r:.40}")
        for driver in self.drivers:
            try:
                jet = driver.law.jet("t", float(t))
            except (ArithmeticError, ValueError) as exc:
                jet = (exc,)
            if not all(isinstance(x, float) and math.isfinite(x) for x in jet):
                why = f" ({jet[0]})" if isinstance(jet[0], Exception) else ""
                raise AssemblyError(
                    f"mechanism '{self.name}': driver '{driver.name}' prescribes "
                    f"{driver.expression}, whose value, rate or acceleration is not defined "
                    f"at t = {float(t):g}, where the run starts{why}; start the run where it "
                    "is (t_start) or change the law")
        prob = self.problem()
        q0, v0 = self._state if self._state is not None else \
            (self.initial_coordinates(), self.initial_velocities())
        q, iterations, err = prob.project_positions(q0, t, tol=tol, max_iter=max_iter)
        if not err <= tol:
            raise AssemblyError(
                f"mechanism '{self.name}' cannot be assembled: after {iterations} Newton "
                f"iterations the largest residual is {prob.worst_constraint(prob.phi(q, t))}. "
                "Check that joint's points and the link lengths it implies.")
        v = self._velocities(prob, q, v0, t, tol)
        self._assembled = AssemblyReport(
            q, v, iterations, float(np.max(np.abs(q - q0), initial=0.0)),
            float(np.max(np.abs(v - v0), initial=0.0)),
            float(np.max(np.abs(prob.phi(q, t)), initial=0.0)))
        return self._assembled

    def _velocities(self, prob, q, v0, t, tol):
        """Consistent velocities nearest the given ones (mass metric) with the joint rates
        of `set_speed`; a warning where a velocity the user gave (non-zero) had to change."""
        extra = None
        if self.speeds:
            from .problem.geometry import joint_gradient
            G = np.array([joint_gradient(prob.joints[name], q) for name in self.speeds])
            extra = (G, np.array(list(self.speeds.values())))
        J = prob.phi_q(q, t)
        rows = [J @ v0 + prob.phi_t(q, t)] + ([extra[0] @ v0 - extra[1]] if extra else [])
        vscale = max(1.0, float(np.max(np.abs(v0))) if v0.size else 1.0,
                     *(abs(r) for r in self.speeds.values()))
        v = v0 if np.max(np.abs(np.concatenate(rows)), initial=0.0) <= tol * vscale \
            else prob.project_velocities(q, v0, t, extra)
        r_after = np.max(np.abs(prob.phi_q(q, t) @ v + prob.phi_t(q, t)), initial=0.0)
        missed = np.abs(extra[0] @ v - extra[1]) if extra is not None else np.zeros(1)
        if extra is not None and max(r_after, np.max(missed)) > 1e-8 * vscale:
            name = list(self.speeds)[int(np.argmax(missed))]
            raise AssemblyError(f"mechanism '{self.name}': the joint rates of set_speed "
                                f"cannot all hold with the constraints and drivers (joint "
                                f"'{name}' off by {np.max(missed):.3g}, the constraints by "
                                f"{r_after:.3g}); the mechanism has fewer degrees of "
                                "freedom than rates set")
        if r_after > 1e-8 * vscale:
            raise AssemblyError(f"mechanism '{self.name}': no velocity satisfies the "
                                f"constraints (residual {r_after:.3g}); check the drivers")
        given = np.flatnonzero(v0 != 0.0)
        change = np.abs(v - v0)[given]
        if change.size and np.max(change) > 1e-6 * vscale:
            import warnings
            k = given[int(np.argmax(change))]
            warnings.warn(
                f"mechsim: assembling mechanism '{self.name}' changed the initial velocity "
                f"'{prob.coordinate_names[k]}' from {v0[k]:.6g} to {v[k]:.6g}: the velocities "
                "given do not satisfy the joints, and the nearest ones that do were taken. "
                "Give the speeds of joints instead (Mechanism.set_speed(joint, rate)).",
                stacklevel=3)
        return v


    def set_state(self, q, v=None, t: float = 0.0) -> AssemblyReport:
        """Start later simulations from the consistent state (q, v) (v default zeros),
        such as an equilibrium's `eq.q`, instead of the assembled initial configuration;
        a `set_speed` after it starts the joint turning from that state. Raises ModelError
        if (q, v) does not satisfy the constraints; adding to the mechanism forgets the
        state."""
        from .run.solver import check_initial_state
        prob = self.problem()
        v = np.zeros(prob.n) if v is None else v
        try:
            q, v = check_initial_state(prob, q, v, t)
        except ValueError as exc:
            raise ModelError(f"mechanism '{self.name}': set_state: {exc}") from None
        self._state = (q, v)
        self._assembled = AssemblyReport(q, v, 0, 0.0, 0.0,
                                         float(np.max(np.abs(prob.phi(q, t)), initial=0.0)))
        return self._assembled

    # --- engineering analysis ----------------------------------------------------------------
    def equilibrium(self, t: float = 0.0):
        """The static equilibrium nearest the assembled state under gravity, springs and
        constant loads, with the drivers held where their laws put them at t: an
        `Equilibrium` (`mechsim.engineering.equilibrium`) with `q`, `converged`, `stable`
        (the reduced stiffness positive definite), the stiffness itself and the reactions
        there (`eq.joint_force(joint)`). `mech.set_state(eq.q)` starts simulations there."""
        from .engineering.equilibrium import equilibrium
        return equilibrium(self, t)

    def linearize(self, q=None, v=None, t: float = 0.0):
        """The linearized equations of motion about the consistent state (q, v) at t, in the
        independent coordinates: a `Linearization` with M, C, K, A, natural frequencies,
        damping ratios and mode shapes in all coordinates. q=None: the static equilibrium
        found from the assembled state (`equilibrium`); v=None: at rest, but for what the
        drivers move (the consistent velocity of least kinetic energy)."""
        from .engineering.linearize import linearize
        prob = self.problem()
        if q is None:
            eq = self.equilibrium(t)
            q = eq.q if eq.converged else self.assemble(t=t).q
        if v is None:
            v = prob.project_velocities(np.asarray(q, float), np.zeros(prob.n), t) \
                if prob.m else np.zeros(prob.n)
        from .run.solver import check_initial_state
        try:
            q, v = check_initial_state(prob, q, v, t)
        except ValueError as exc:
            raise ModelError(f"mechanism '{self.name}': linearize: {exc}") from None
        return linearize(prob, q, v, t)

    def kinematics(self, t_end: float | None = None, output_step: float | None = None,
                   t_start: float = 0.0, over=None, sensitivities=None):
        """Kinematic analysis of a fully driven mechanism (0 degrees of freedom): its
        positions, velocities and accelerations solved from the constraints at t_start,
        t_start + output_step, …, t_end (no integration), or over a driver's range with
        `over=(driver, values)` (the times where its law reaches each change of its
        joint's coordinate, e.g. `(motor, np.radians(np.arange(0, 361)))`), as a
        `SimulationResult` whose `driver_effort`, `joint_force` and `cycle_figures()` give
        the inverse dynamics: the efforts the drivers need and the loads on the joints.
        `sensitivities`: names of Parameters (`parameters`) whose exact sensitivities the
        result keeps (`SimulationResult.sensitivity`). See `mechsim.engineering.driven`."""
        from .engineering.driven import kinematic_analysis
        if over is None and isinstance(t_end, numbers.Real):
            self.check_tables(t_start, t_end)
        return kinematic_analysis(self, t_end, output_step, t_start, over=over,
                                  sensitivities=sensitivities)


    # --- simulation --------------------------------------------------------------------------
    def simulate(self, t_end: float, method: str | None = None, sensitivities=None,
                 **options):
        """Simulate from the assembled initial state to `t_end`; see `mechsim.run.solver.simulate`
        for the options. Returns a SimulationResult (partial, with a status, on failure).

        `sensitivities`: names of Parameters (`parameters`) whose exact sensitivities the
        motion carries, integrated with it under the same error control
        (`mechsim.formulations.tangent`; rigid bodies and flexible beams under gravity,
        springs, dampers, forces and torques of time on rigid bodies, impacts on stops of
        rigid mechanisms (`mechsim.engineering.impact_sensitivity`: each impact's time
        sensitivity on `Impact.time_sensitivity`; they end where a joint comes to rest on a
        stop, and the message says so); loads on a beam and friction are refused);
        `result.sensitivity(name, of=...)` gives them at the samples. They start from the
        assembly linearised at the given configuration: exact where that configuration
        satisfies the joints (the message says so where the assembly moved it)."""
        from .run.solver import check_simulate_arguments, run
        config = check_simulate_arguments(len(self.coordinate_names), t_end, method, options)
        self.check_tables(config.t_start, config.t_end)
        tangent = self._tangent(sensitivities) if sensitivities is not None else None
        report = self._assembled or self.assemble(t=config.t_start)
        if tangent is not None and self._state is None:
            tangent = self._assembled_partials(tangent, report, config.t_start)
        if self.stops or self.frictions:
            from .engineering.impacts import simulate_with_stops
            res = simulate_with_stops(self, report, t_end, method, sensitivities=tangent,
                                      **options)
        else:
            res = run(self.problem(), report.q, report.v, config,
                      stream=options.get("stream"), mechanism=self, sensitivities=tangent)
        if tangent is not None and self._state is None and report.position_change > 1e-9:
            res.message += (f"; the initial sensitivities linearise the assembly, which moved "
                            f"the given configuration by up to {report.position_change:.3g}: "
                            "they are first-order accurate in that change (start from a "
                            "configuration that satisfies the joints for exact ones)")
        return res

    def _tangent(self, sensitivities):
        """(the sensitivity equations, ∂q0/∂k, ∂v0/∂k as given) for `simulate`, the names
        checked and what cannot be differentiated refused before any work."""
        from .build import sensitivity_model
        from .engineering.driven import sensitivity_names
        from .problem.sensitivity import MotionEquations, load_blindness
        names = sensitivity_names(self, sensitivities, "simulate", ValueError)
        if not names:
            return None
        blind = self.parameter_blind_loads()
        if blind:
            raise ValueError(f"simulate: {load_blindness(blind[0])}")
        if self.frictions:
            from .problem.friction_sensitivity import refusal
            why = refusal(self, self.problem(), names)
            if why:
                raise ValueError(f"simulate: {why}")
        self._check_stops_differentiable(names)
        equations = MotionEquations(self.problem(), sensitivity_model(self), names)
        if self._state is not None:            # a state set by the user: held as given
            held = np.zeros((len(self.coordinate_names), len(names)))
            return equations, held, held
        return (equations, *self.initial_partials(names))

    def _assembled_partials(self, tangent, report, t):
        """(equations, q_k, v_k) at the assembled start: q_k on the constraints' tangent,
        v_k the assembly's velocity projection linearised (the rates of `set_speed` held,
        the given velocities' own change and the masses' metric included:
        `mechsim.engineering.impact_sensitivity.VelocityProjection`). A flexible
        mechanism's (M(q)) are left to the tangent's projection."""
        equations, Sq, Sv = tangent
        problem = equations.problem
        if problem.flexible:
            return tangent
        from .engineering.impact_sensitivity import VelocityProjection
        Sq = equations.project(t, report.q, report.v, Sq, Sv)[0]
        rows = [(problem.joints[name], 0.0) for name in self.speeds]
        law = VelocityProjection(problem, equations, rows, t, report.q,
                                 self.initial_velocities(), report.v)
        return equations, Sq, law.partials(Sq, Sv)

    def _check_stops_differentiable(self, names) -> None:
        """ValueError naming the stop where its impacts' sensitivities cannot be carried:
        on a flexible mechanism, or where its joint's coordinate moves with a Parameter
        differentiated."""
        if not self.stops:
            return
        problem = self.problem()
        if problem.flexible:
            raise ValueError(f"simulate: sensitivities across the impacts on stop "
                             f"'{self.stops[0].name}' are carried for rigid bodies only")
        for stop in self.stops:
            moved = stop.joint.moved_by(names)
            if moved is not None:
                raise ValueError(f"simulate: the coordinate of joint '{stop.joint.name}', "
                                 f"which stop '{stop.name}' limits, moves with Parameter "
                                 f"'{moved}': its impacts' sensitivities are not "
                                 "carried (keep the joint's geometry out of the Parameters "
                                 "asked for)")

    def steady_state(self, period: float, guess=None, method: str = "newton",
                     tol: float = 1e-8, max_iter: int = 30, t_start: float = 0.0,
                     t0: float | None = None, **simulate_options):
        """The periodic steady state of period `period` (e.g. 2π/ω of a driver or a
        forcing) starting at `t_start` (as in `simulate`; `t0` is its older name), found by
        shooting on the independent coordinates and velocities without simulating the
        transient. Returns a `ShootingResult`; `result.trajectory.result` is the
        SimulationResult over one period. `guess` defaults to the assembled state."""
        from .shooting import solve
        from .shooting.mechanism import MechanismPeriodicProblem
        if t0 is not None:
            if t_start != 0.0:
                raise ValueError("steady_state: give `t_start` or `t0` (its older name), "
                                 "not both")
            t_start = t0
        problem = MechanismPeriodicProblem(self, period, t_start, **simulate_options)
        start = problem.guess0 if guess is None else guess
        return solve(problem, start, method=method, tol=tol, max_iter=max_iter)
