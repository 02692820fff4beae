"""Synthesis on exact gradients: `optimize` a mechanism's Parameters for an objective.

A design is the values of some of a mechanism's Parameters (`mechsim.model.parameters`).
`optimize` gives the mechanism each trial design (`set_parameters`: no new build, no new
code), asks the objective for its value and, with ``gradient="exact"``, its exact gradient
(the kinematic sensitivities of `mech.kinematics(..., sensitivities=...)`), and hands both
to `scipy.optimize.minimize`. ``gradient="2-point"`` or ``"3-point"`` leaves the gradient
to scipy's finite differences, for comparison.

An objective is a callable ``objective(mech, names) -> (value, gradient)``: the value at
the mechanism's present design and ∂value/∂(each of `names`) (an empty array where
`names` is empty). A design where the objective cannot be evaluated (the mechanism does
not assemble, its analysis fails) raises `DesignError` (or a ModelError) there; the
optimizer is then given a value above every one it has seen, and the result counts such
designs. Ready objectives: `PathPoints` (path generation with prescribed or free timing,
and motion generation: the body's angle too), `FunctionPoints` (function generation: an
output angle against the driver's), `EffortNorm` (a driver's RMS effort, or a smooth
stand-in for its peak), `JointForceNorm` (the same of a joint's transmitted force: the
peak pin load).

An objective may carry variables of its own besides the mechanism's Parameters (a path's
free timing): it then has `variables` (their names), `variable_values()`,
`variable_bounds()` and `set_variables(values)`, and its gradient has one more entry per
variable after the Parameters'. `optimize` searches them with the Parameters and reports
them in `Design.variables`.

A constraint is a callable ``constraint(mech, names) -> (values, jacobian)``, feasible
where every value is ≥ 0, its jacobian ∂values/∂(names), (m, len(names)) (scipy's
constraint dicts over the parameters' values are taken as well). Ready:
`TransmissionAngle` (a four-bar's transmission angle kept within bounds) and
`GrashofCrank` (its crank kept turning fully). An objective or constraint with a
`check(mech)` method has it called before the search, to refuse what it cannot evaluate.

`multistart` runs `optimize` from several starts spread over the bounds (a Latin
hypercube) as a parameter study (`mechsim.study.sweep`: local processes or a dask
cluster), for the global search a linkage's many local optima call for.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .model.parameters import Parameter


class DesignError(ValueError):
    """An objective could not be evaluated at a design."""


class PathPoints:
    """Path generation: the point `local` of `body` (a body of the mechanism, or its name)
    should pass through `targets[i]` when `driver` (a driver, or its name) has moved its
    joint by `values[i]` from where it starts. Its value is the mean squared distance to
    the targets [m²]; its gradient is exact (the point's kinematic sensitivities).

    Motion generation: with `angles` (one per target [rad]) the body's angle should take
    them too, each radian weighing as `length` metres (the value adds the mean squared
    angle error times length²).

    With `free_timing`, the timing is not prescribed: the driver's advances between
    successive points, values[i] − values[i − 1] (the first value stays), are the
    objective's own variables ("advance 1", …), each of the sign the given values advance
    by and of size between `min_advance` and 2π, with exact derivatives too (the point's
    velocity over the driver's rate)."""

    def __init__(self, body, local, targets, driver, values, free_timing=False,
                 min_advance=1e-3, angles=None, length=1.0):
        self.body, self.driver = body, driver
        self.angles = None if angles is None else np.asarray(angles, float).ravel()
        self.length = float(length)
        if self.angles is not None and self.angles.shape != np.shape(values):
            raise ValueError(f"PathPoints: `angles` must be one per value "
                             f"({np.size(values)}), got {self.angles.size}")
        self.local = tuple(float(x) for x in np.asarray(local, float).ravel())
        self.targets = np.asarray(targets, float)
        self.values = np.asarray(values, float).ravel()
        self.free_timing = bool(free_timing)
        self.min_advance = float(min_advance)
        steps = np.diff(self.values)
        self.sign = 1.0 if steps.size and steps[0] > 0 else -1.0
        if self.free_timing and not (steps.size and
                                     np.all(self.sign * steps >= self.min_advance)):
            raise ValueError("PathPoints: free timing needs `values` increasing or "
                             "decreasing, each at least `min_advance` "
                             f"({self.min_advance:g}) past the one before")
        if len(self.local) != 2:
            raise ValueError(f"PathPoints: `local` must be a 2-vector, got {local!r:.60}")
        if self.targets.ndim != 2 or self.targets.shape[1] != 2 or \
                len(self.targets) != len(self.values):
            raise ValueError(f"PathPoints: `targets` must be {len(self.values)} points (one "
                             f"per value), shape ({len(self.values)}, 2); got "
                             f"{self.targets.shape}")

    @property
    def variables(self) -> list[str]:
        """The objective's own variables: the driver's advances with free timing."""
        return [f"advance {i}" for i in range(1, len(self.values))] if self.free_timing \
            else []

    def variable_values(self) -> np.ndarray:
        return np.diff(self.values) if self.free_timing else np.zeros(0)

    def variable_bounds(self) -> list:
        low, high = sorted((self.sign * self.min_advance, self.sign * 2.0 * np.pi))
        return [(low, high)] * len(self.variables)

    def set_variables(self, advances) -> None:
        """The driver's advances between successive points (free timing)."""
        advances = np.asarray(advances, float).ravel()
        if len(advances) != len(self.variables):
            raise ValueError(f"PathPoints: {len(self.variables)} advances expected, got "
                             f"{len(advances)}")
        if len(advances):
            self.values = self.values[0] + np.concatenate([[0.0], np.cumsum(advances)])

    def __call__(self, mech, names):
        body = mech.body(self.body) if isinstance(self.body, str) else self.body
        kin = mech.kinematics(over=(self.driver, self.values),
                              sensitivities=list(names) or None)
        if not kin.success or len(kin.t) != len(self.values):
            raise DesignError(f"the path's points could not be reached: {kin.message}")
        d = kin.point(body, self.local) - self.targets
        value = float(np.mean(np.sum(d * d, axis=1)))
        grad = [2.0 * float(np.mean(np.sum(
            d * kin.sensitivity(k, of="point", body=body, local=self.local), axis=1)))
            for k in names]
        e = None
        if self.angles is not None:
            column = kin.coordinate_names.index(f"{body.name}.angle")
            e = kin.q[:, column] - self.angles
            value += self.length ** 2 * float(np.mean(e * e))
            grad = [g + 2.0 * self.length ** 2 * float(np.mean(e * kin.sensitivity(k)[:, column]))
                    for g, k in zip(grad, names)]
        if self.free_timing and names:
            grad += list(self._timing_gradient(mech, kin, body, d, e))
        return value, np.array(grad)

    def _timing_gradient(self, mech, kin, body, d, e) -> np.ndarray:
        """∂value/∂(advance j) = Σ_{i ≥ j} ∂value/∂values[i], ∂r_i/∂values[i] being the
        point's velocity over the driver's rate at sample i (and the body's angular
        velocity over it for the angle errors `e`, None without)."""
        driver = mech.driver(self.driver)
        rates = np.array([driver.law.jet("t", float(t))[1] for t in kin.t])
        along = kin.point_velocity(body, self.local) / rates[:, None]
        per_value = 2.0 * np.sum(d * along, axis=1) / len(self.values)
        if e is not None:
            per_value += 2.0 * self.length ** 2 * e * kin.angular_velocity(body) / rates \
                / len(self.values)
        return np.cumsum(per_value[::-1])[::-1][1:]


class FunctionPoints:
    """Function generation: the angle of `body_b` relative to `body_a` (bodies or names;
    the ground's angle is 0) should have turned by `targets[i]` [rad] from its value at the
    first point when `driver` has moved its joint by `values[i]` (targets[0] is 0). Its
    value is the mean squared error of those turns [rad²], its gradient exact (the
    angles' kinematic sensitivities)."""

    def __init__(self, body_a, body_b, targets, driver, values):
        self.body_a, self.body_b, self.driver = body_a, body_b, driver
        self.targets = np.asarray(targets, float).ravel()
        self.values = np.asarray(values, float).ravel()
        if self.targets.shape != self.values.shape or self.values.size < 2:
            raise ValueError(f"FunctionPoints: `targets` must be one turn per value (at "
                             f"least two), got {self.targets.size} for {self.values.size}")

    def _angle(self, kin, body, of):
        """Body's angle (or its sensitivity `of`) over the samples; 0 for the ground."""
        name = getattr(body, "name", body)
        key = f"{name}.angle"
        if key not in kin.coordinate_names:
            return np.zeros(len(kin.t))
        column = kin.coordinate_names.index(key)
        return (kin.q if of is None else kin.sensitivity(of))[:, column]

    def __call__(self, mech, names):
        kin = mech.kinematics(over=(self.driver, self.values),
                              sensitivities=list(names) or None)
        if not kin.success or len(kin.t) != len(self.values):
            raise DesignError(f"the function's points could not be reached: {kin.message}")

        def turn(of=None):
            psi = self._angle(kin, self.body_b, of) - self._angle(kin, self.body_a, of)
            return psi - psi[0]
        error = turn() - self.targets
        value = float(np.mean(error * error))
        grad = [2.0 * float(np.mean(error * turn(k))) for k in names]
        return value, np.array(grad)


class _OnAnalysis:
    """An objective or constraint taken over a kinematic analysis: `over` (a driver's
    range), or `t_end` and `output_step`."""

    def _analysis(self, mech, names):
        """The analysis at the mechanism's present design, with the sensitivities to
        `names`; DesignError where it fails."""
        kin = mech.kinematics(self.t_end, self.output_step, over=self.over,
                              sensitivities=list(names) or None)
        if not kin.success:
            raise DesignError(f"the analysis failed: {kin.message}")
        return kin


class EffortNorm(_OnAnalysis):
    """The p-norm mean of a driver's effort τ over a kinematic analysis,
    (mean abs(τ)^p)^(1/p) [N·m or N]: p = 2 its RMS; a large p (16) a smooth stand-in for its peak, below it by
    at most the factor N^(−1/p) over N samples. The analysis is `kinematics(t_end,
    output_step)` or over a driver's range (`over`). The gradient is exact (the effort's
    sensitivities): ∂/∂k = mean(abs(τ/value)^(p−1) sign(τ) ∂τ/∂k)."""

    def __init__(self, driver, p: float = 2.0, t_end=None, output_step=None, over=None):
        if not p >= 1.0:
            raise ValueError(f"EffortNorm: `p` must be at least 1, got {p!r:.40}")
        self.driver, self.p = driver, float(p)
        self.t_end, self.output_step, self.over = t_end, output_step, over

    def __call__(self, mech, names):
        kin = self._analysis(mech, names)
        tau = kin.driver_effort(self.driver)
        value = float(np.mean(np.abs(tau) ** self.p) ** (1.0 / self.p))
        if value == 0.0:
            return 0.0, np.zeros(len(names))
        weight = np.abs(tau / value) ** (self.p - 1.0) * np.sign(tau)
        grad = [float(np.mean(weight * kin.sensitivity(k, of="driver_effort",
                                                       driver=self.driver)))
                for k in names]
        return value, np.array(grad)


class JointForceNorm(_OnAnalysis):
    """The p-norm mean of the magnitude of the force a joint transmits, |F| [N] of
    `joint_force(joint)`, over a kinematic analysis: (mean |F|^p)^(1/p); p = 2 its RMS, a
    large p (16) a smooth stand-in for the peak pin load (below it by at most N^(−1/p)
    over N samples). The analysis as for `EffortNorm`. The gradient is exact (the joint
    force's sensitivities): ∂/∂k = mean((|F|/value)^(p−1) F·∂F/∂k / |F|)."""

    def __init__(self, joint, p: float = 2.0, t_end=None, output_step=None, over=None):
        if not p >= 1.0:
            raise ValueError(f"JointForceNorm: `p` must be at least 1, got {p!r:.40}")
        self.joint, self.p = joint, float(p)
        self.t_end, self.output_step, self.over = t_end, output_step, over

    def __call__(self, mech, names):
        kin = self._analysis(mech, names)
        force = kin.joint_force(self.joint)
        size = np.hypot(force[:, 0], force[:, 1])
        value = float(np.mean(size ** self.p) ** (1.0 / self.p))
        if value == 0.0:
            return 0.0, np.zeros(len(names))
        along = np.divide(force, size[:, None], out=np.zeros_like(force),
                          where=size[:, None] > 0.0)
        weight = (size / value) ** (self.p - 1.0)
        grad = [float(np.mean(weight * np.sum(along * kin.sensitivity(
            k, of="joint_force", joint=self.joint), axis=1))) for k in names]
        return value, np.array(grad)


class GrashofCrank:
    """A four-bar's crank kept turning fully: with crank a, coupler b, rocker c and ground
    d, the crank the shortest link and s + l ≤ p + q (Grashof), i.e. the three linear
    conditions b + c − a − d, b + d − a − c, c + d − a − b ≥ `margin` (each link's length
    either the name of a Parameter or a number [m]; `margin` > 0 keeps the design away
    from the change point, where the linkage can fold). Values ≥ 0 where feasible, with
    their exact jacobian (±1 on the links' Parameters)."""

    def __init__(self, crank, coupler, rocker, ground, margin: float = 0.0):
        self.links = (crank, coupler, rocker, ground)
        for role, link in zip(("crank", "coupler", "rocker", "ground"), self.links):
            if isinstance(link, bool) or not isinstance(link, (str, int, float)):
                raise ValueError(f"GrashofCrank: the {role} must be a Parameter's name or a "
                                 f"length, got {link!r:.60}")
        if isinstance(margin, bool) or not isinstance(margin, (int, float)) or margin < 0:
            raise ValueError(f"GrashofCrank: `margin` must be a length ≥ 0, got {margin!r:.40}")
        self.margin = float(margin)

    # Rows: b + c − a − d, b + d − a − c, c + d − a − b over (a, b, c, d).
    SIGNS = np.array([[-1.0, 1.0, 1.0, -1.0], [-1.0, 1.0, -1.0, 1.0],
                      [-1.0, -1.0, 1.0, 1.0]])

    def check(self, mech):
        """ValueError naming a link that names no Parameter of `mech`."""
        known = mech.parameters
        for link in self.links:
            if isinstance(link, str) and link not in known:
                raise ValueError(f"GrashofCrank: {link!r:.60} is no Parameter of mechanism "
                                 f"'{mech.name}'; its parameters: {', '.join(known) or '(none)'}")

    def __call__(self, mech, names):
        self.check(mech)
        values = mech.parameter_values()
        lengths = np.array([values[x] if isinstance(x, str) else float(x)
                            for x in self.links])
        jac = np.zeros((3, len(names)))
        for j, link in enumerate(self.links):
            if isinstance(link, str) and link in names:
                jac[:, names.index(link)] += self.SIGNS[:, j]
        return self.SIGNS @ lengths - self.margin, jac


class TransmissionAngle(_OnAnalysis):
    """The angle μ between the x axes of two bodies (a four-bar's coupler and rocker,
    their frames along the links as `RigidBody.rod` puts them) kept at least `minimum`
    degrees from alignment at every sample of a kinematic analysis (`over`, or `t_end` and
    `output_step`): one value per sample, abs(sin μ) − sin(minimum), feasible where ≥ 0,
    with their exact jacobian (the angles' sensitivities)."""

    def __init__(self, body_a, body_b, minimum: float, t_end=None, output_step=None,
                 over=None):
        if not 0.0 < minimum < 90.0:
            raise ValueError(f"TransmissionAngle: `minimum` must be between 0 and 90 degrees, "
                             f"got {minimum!r:.40}")
        self.body_a, self.body_b = body_a, body_b
        self.floor = float(np.sin(np.radians(minimum)))
        self.t_end, self.output_step, self.over = t_end, output_step, over

    def __call__(self, mech, names):
        kin = self._analysis(mech, names)
        a, b = (kin.coordinate_names.index(f"{getattr(x, 'name', x)}.angle")
                for x in (self.body_a, self.body_b))
        mu = kin.q[:, b] - kin.q[:, a]
        values = np.abs(np.sin(mu)) - self.floor
        slope = np.sign(np.sin(mu)) * np.cos(mu)
        jac = np.column_stack([slope * (kin.sensitivity(k)[:, b] - kin.sensitivity(k)[:, a])
                               for k in names]) if names else np.zeros((len(mu), 0))
        return values, jac


@dataclass
class Design:
    """What `optimize` found: `parameters` (name -> value, the mechanism set to them),
    `value` of the objective there, `success` and `message` (scipy's), `evaluations` of
    the objective (with the finite differences' own, where scipy takes them),
    `gradients` (exact ones asked for), `iterations`, `failures` (designs where the
    objective could not be evaluated, with the first messages), `wall_time` [s],
    `scipy`, the `scipy.optimize.OptimizeResult`, and `variables`, the objective's own
    variables at the design (a path's free timing; module docstring)."""
    parameters: dict
    value: float
    success: bool
    message: str
    evaluations: int
    gradients: int
    iterations: int
    failures: int
    wall_time: float
    failure_messages: list = field(default_factory=list)
    scipy: object = None
    variables: dict = field(default_factory=dict)     # the objective's own, at the design

    @property
    def status(self) -> str:
        """"success" where scipy's search converged, else "not converged"."""
        return "success" if self.success else "not converged"


def optimize(mech, objective, parameters, bounds=None, constraints=(), *,
             gradient: str = "exact", method: str | None = None, tol: float | None = None,
             options: dict | None = None) -> Design:
    """Minimise `objective(mech, names)` over the Parameters named in `parameters`, from
    their present values, with `scipy.optimize.minimize`.

    Parameters
    ----------
    mech : Mechanism
        Built with those Parameters; it is left set to the best design found.
    objective : callable
        ``objective(mech, names) -> (value, gradient)`` (see the module docstring), e.g.
        `PathPoints`.
    parameters : list of str
        The Parameters to vary (of `mech.parameters`).
    bounds : dict or sequence, optional
        ``{name: (low, high)}`` or one (low, high) per parameter; None for no bound.
    constraints : sequence, optional
        mechsim constraints (``c(mech, names) -> (values, jacobian)``, values ≥ 0 where
        feasible, e.g. `TransmissionAngle`) or scipy's constraint dicts over the
        parameters' values in the order of `parameters`.
    gradient : {"exact", "2-point", "3-point"}
        Exact gradients from the objective, or scipy's finite differences.
    method : str, optional
        scipy's method; default "L-BFGS-B", or "SLSQP" with constraints.
    tol, options
        As for `scipy.optimize.minimize`.

    Raises ValueError, before any evaluation, naming what is wrong with the arguments.
    """
    from scipy.optimize import minimize
    names = _names(mech, parameters)
    lows_highs = _bounds(names, bounds)
    if gradient not in ("exact", "2-point", "3-point"):
        raise ValueError(f"optimize: `gradient` must be 'exact', '2-point' or '3-point', got "
                         f"{gradient!r:.40}")
    exact = gradient == "exact"
    values = mech.parameter_values()
    own = list(getattr(objective, "variables", []))
    x0 = np.concatenate([[values[k] for k in names],
                         objective.variable_values() if own else []])
    if own:
        lows_highs = (lows_highs or [(None, None)] * len(names)) + \
            list(objective.variable_bounds())
    for item in (objective, *constraints):
        if hasattr(item, "check"):
            item.check(mech)
    trials = _Trials(mech, names, exact, objective if own else None)
    scipy_constraints = [c if isinstance(c, dict) else trials.constraint(c, x0)
                         for c in constraints]
    started = time.perf_counter()
    chosen = method or ("SLSQP" if constraints else "L-BFGS-B")
    res = minimize(lambda x: trials.objective(objective, x), x0,
                   jac=True if exact else gradient, method=chosen, bounds=lows_highs,
                   constraints=scipy_constraints, tol=tol, options=options)
    x = np.asarray(res.x, float)
    best = dict(zip(names, x[:len(names)].tolist()))
    trials.set(x)
    return Design(best, float(res.fun), bool(res.success), str(res.message),
                  trials.values, trials.gradients, int(getattr(res, "nit", 0)),
                  trials.failures, time.perf_counter() - started, trials.messages, res,
                  dict(zip(own, x[len(names):].tolist())))


class _Trials:
    """The trial designs of one search: each set on the mechanism, the objective and the
    constraints evaluated there, what could not be evaluated counted (with the first
    messages)."""

    def __init__(self, mech, names, exact, carrier=None):
        self.mech, self.names, self.exact = mech, names, exact
        # The objective whose own variables follow the Parameters in x (None: none).
        self.carrier = carrier
        self.size = len(names) + (len(carrier.variables) if carrier is not None else 0)
        self.values = self.gradients = self.failures = 0
        self.messages: list[str] = []
        self.worst = None            # the largest objective value seen

    def _failed(self, exc) -> None:
        self.failures += 1
        if len(self.messages) < 5:
            self.messages.append(str(exc))

    def set(self, x) -> None:
        """The design x: the Parameters on the mechanism, the rest on the objective."""
        self.mech.set_parameters(**dict(zip(self.names, x[:len(self.names)].tolist())))
        if self.carrier is not None:
            self.carrier.set_variables(x[len(self.names):])

    def objective(self, objective, x):
        """(value, gradient) with exact gradients, else the value; a design that cannot be
        evaluated gets a value above every one seen and a zero gradient."""
        self.values += 1
        self.gradients += self.exact
        try:
            self.set(x)
            value, grad = objective(self.mech, self.names if self.exact else [])
        except (DesignError, ValueError) as exc:
            self._failed(exc)
            worst = 1.0 if self.worst is None else self.worst
            value, grad = 10.0 * abs(worst) + 1.0, np.zeros(self.size)
        else:
            self.worst = value if self.worst is None else max(self.worst, value)
        return (value, np.asarray(grad, float)) if self.exact else value

    def constraint(self, c, x0) -> dict:
        """scipy's dict of the mechsim constraint `c` (its size from the start design x0,
        where it must evaluate): a design where it cannot be evaluated is infeasible."""
        self.set(x0)
        size = len(np.atleast_1d(c(self.mech, [])[0]))
        extra = self.size - len(self.names)

        def part(x, which):
            try:
                self.set(x)
                out = np.asarray(c(self.mech, self.names if which else [])[which], float)
            except (DesignError, ValueError) as exc:
                self._failed(exc)
                return np.zeros((size, self.size)) if which else -np.ones(size)
            # (A mechsim constraint does not depend on the objective's own variables.)
            return np.hstack([out.reshape(size, -1), np.zeros((size, extra))]) \
                if which and extra else out

        entry = {"type": "ineq", "fun": lambda x: part(x, 0)}
        if self.exact:
            entry["jac"] = lambda x: part(x, 1)
        return entry


@dataclass
class Multistart:
    """What `multistart` found: `best` (the `Design` of lowest value among the searches
    that ended, None if none did) and `study` (the `mechsim.study.Study`: one row per
    start: the start's values under the parameters' names, the design's as "design
    <name>", "value", "evaluations", "gradients", "iterations", "failures", status and
    message)."""
    best: Design | None
    study: object


def multistart(build, objective, bounds: dict, starts: int = 8, seed=None, *,
               client=None, workers=None, progress=False, **options) -> Multistart:
    """`optimize` from `starts` designs spread over `bounds` by a Latin hypercube
    (`scipy.stats.qmc`, `seed`), each start's mechanism `build(**parameters)` with every
    bounded parameter a `Parameter` of that name; run as a parameter study
    (`mechsim.study.sweep`: `workers` local processes, or the dask `client`). `options`:
    `optimize`'s keywords (constraints, gradient, method, tol, options). `build`,
    `objective` and the constraints must pickle (module-level functions, the ready
    objectives). ValueError before any search for bad arguments."""
    from scipy.stats import qmc
    from .study import sweep
    if not isinstance(bounds, dict) or not bounds:
        raise ValueError("multistart: `bounds` must map each parameter to (low, high)")
    names = list(bounds)
    _bounds(names, bounds)
    if any(None in pair for pair in bounds.values()):
        raise ValueError("multistart: every parameter needs finite bounds to spread starts")
    if not isinstance(starts, int) or starts < 1:
        raise ValueError(f"multistart: `starts` must be a count ≥ 1, got {starts!r:.40}")
    low = np.array([bounds[k][0] for k in names], float)
    high = np.array([bounds[k][1] for k in names], float)
    points = qmc.scale(qmc.LatinHypercube(d=len(names), seed=seed).random(starts), low, high)
    grid = [dict(zip(names, p.tolist())) for p in points]
    study = sweep(_Parametrized(build), grid, client=client, workers=workers,
                  progress=progress, analyse=_Search(objective, names, bounds, options),
                  measure=_row)
    table = study.table
    ended = np.flatnonzero(table["status"] == "success")
    best = None
    if ended.size:
        k = ended[np.argmin(table["value"][ended])]
        best = Design({n: float(table[f"design {n}"][k]) for n in names},
                      float(table["value"][k]), True, str(table["message"][k]),
                      *(int(table[c][k]) for c in ("evaluations", "gradients", "iterations",
                                                   "failures")),
                      float(table["time"][k]))
    return Multistart(best, study)


class _Parametrized:
    """`build` with each given value made a Parameter of its name (picklable)."""

    def __init__(self, build):
        self.build = build

    def __call__(self, **values):
        return self.build(**{k: Parameter(k, v) for k, v in values.items()})


class _Search:
    """One start's `optimize` (the study's `analyse`)."""

    def __init__(self, objective, names, bounds, options):
        self.objective, self.names, self.bounds, self.options = (objective, names, bounds,
                                                                 options)

    def __call__(self, mech):
        design = optimize(mech, self.objective, self.names, bounds=self.bounds,
                          **self.options)
        design.scipy = None                    # (it goes back to the study's process)
        return design


def _row(design) -> dict:
    """A start's measures: the design's values, its objective's value and evaluations."""
    return {**{f"design {k}": v for k, v in design.parameters.items()},
            "value": design.value, "evaluations": design.evaluations,
            "gradients": design.gradients, "iterations": design.iterations,
            "failures": design.failures}


def _names(mech, parameters) -> list[str]:
    if isinstance(parameters, str):
        parameters = [parameters]
    names = list(parameters)
    known = mech.parameters
    for name in names:
        if name not in known:
            raise ValueError(f"optimize: `parameters` names {name!r:.60}, which is no Parameter "
                             f"of mechanism '{mech.name}'; its parameters: "
                             f"{', '.join(known) or '(none)'}")
    if not names or len(set(names)) != len(names):
        raise ValueError(f"optimize: `parameters` must name distinct Parameters, got {names}")
    return names


def _bounds(names, bounds):
    """scipy's bounds, one (low, high) per name (None: unbounded), checked."""
    if bounds is None:
        return None
    pairs = [bounds.get(k, (None, None)) for k in names] if isinstance(bounds, dict) \
        else list(bounds)
    if len(pairs) != len(names):
        raise ValueError(f"optimize: `bounds` needs one (low, high) per parameter "
                         f"({len(names)}), got {len(pairs)}")
    for name, pair in zip(names, pairs):
        low, high = pair
        if low is not None and high is not None and not low < high:
            raise ValueError(f"optimize: the bounds of '{name}' must have low < high, got "
                             f"{pair!r}")
    return pairs
