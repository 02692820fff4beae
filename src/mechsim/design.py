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
from .threads import in_run_threads
# The ready objectives and constraints live in `mechsim.objectives`; found here too.
from .objectives import (DesignError, EffortNorm, FunctionPoints,  # noqa: F401
                         GrashofCrank, JointForceNorm, PathPoints, TransmissionAngle)


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


@in_run_threads
def optimize(mech, objective, parameters, bounds=None, constraints=(), *,
             gradient: str = "exact", method: str | None = None, tol: float | None = None,
             options: dict | None = None) -> Design:
    """Minimise `objective(mech, names)` over the Parameters named in `parameters`, from
    their present values, with `scipy.optimize.minimize`. The search holds BLAS to one
    thread, as a run does (`mechsim.threads`).

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
        "least_squares": `scipy.optimize.least_squares` (trust-region reflective, within
        the bounds) on the objective's residuals and their exact Jacobian (an objective
        with `residuals(mech, names) -> (r, J)`, value r·r: `PathPoints`,
        `FunctionPoints`), no constraints: precision-point synthesis, where the best
        design traces the points exactly, converges there quadratically. The start
        must be evaluable (its DesignError is raised otherwise).
    tol, options
        As for `scipy.optimize.minimize` (with "least_squares": tol its ftol, xtol and
        gtol, options its keywords).

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
    if method == "least_squares":
        return _least_squares(objective, constraints, trials, x0, lows_highs, gradient,
                              tol, options or {}, own)
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


def _least_squares(objective, constraints, trials, x0, lows_highs, gradient, tol, options,
                   own) -> Design:
    """`optimize` with method "least_squares" (its docstring)."""
    from scipy.optimize import least_squares
    if not hasattr(objective, "residuals"):
        raise ValueError("optimize: method 'least_squares' needs an objective with "
                         "residuals(mech, names) (PathPoints, FunctionPoints)")
    if constraints:
        raise ValueError("optimize: method 'least_squares' takes no constraints (bounds "
                         "only)")
    pairs = lows_highs or [(None, None)] * len(x0)
    low = np.array([-np.inf if a is None else a for a, _ in pairs], float)
    high = np.array([np.inf if b is None else b for _, b in pairs], float)
    x0 = np.clip(x0, low, high)
    # The start must evaluate (else its DesignError is raised); the last design's (r, J)
    # serve scipy's calls of the residuals and of the Jacobian at the same design.
    r0, jac0 = trials.residuals(objective, x0)
    last = dict(x=x0.copy(), r=r0, jac=jac0)

    def fun(x):
        if not np.array_equal(x, last["x"]):
            r, jac = trials.residuals(objective, x, len(r0))
            last.update(x=x.copy(), r=r, jac=jac)
        return last["r"]

    def jac(x):
        fun(x)
        return last["jac"]

    kw = dict(ftol=tol, xtol=tol, gtol=tol) if tol is not None else {}
    names = trials.names
    started = time.perf_counter()
    res = least_squares(fun, x0, jac=jac if trials.exact else gradient, bounds=(low, high),
                        method="trf", **kw, **options)
    x = np.asarray(res.x, float)
    trials.set(x)
    return Design(dict(zip(names, x[:len(names)].tolist())), float(2.0 * res.cost),
                  bool(res.success), str(res.message), trials.values, trials.gradients,
                  int(res.njev or 0), trials.failures, time.perf_counter() - started,
                  trials.messages, res, dict(zip(own, x[len(names):].tolist())))


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

    def residuals(self, objective, x, size=None):
        """(r, J) at x (J with exact gradients, else None); a design that cannot be
        evaluated gets residuals above every value seen (`size` of them) and a zero J."""
        self.values += 1
        self.gradients += self.exact
        try:
            self.set(x)
            r, jac = objective.residuals(self.mech, self.names if self.exact else [])
        except (DesignError, ValueError) as exc:
            if size is None:
                raise
            self._failed(exc)
            worst = 1.0 if self.worst is None else self.worst
            return np.full(size, np.sqrt((10.0 * worst + 1.0) / size)), \
                np.zeros((size, self.size))
        r = np.asarray(r, float)
        value = float(r @ r)
        self.worst = value if self.worst is None else max(self.worst, value)
        return r, (np.asarray(jac, float) if self.exact else None)

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
