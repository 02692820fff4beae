"""Drivers: a prescribed joint coordinate as a function of time."""

from __future__ import annotations


import numpy as np

from . import parameters as dual
from .checks import ModelError, name_or_default, number_array, scalar
from .expressions import Expression, parse
from .joints import Joint, coordinate_joint
from .splines import evaluate_table


class Driver:
    """Prescribe the coordinate of `joint` (relative angle of a revolute, translation of a
    prismatic) as `expression` in t (or a `table` of measured values, `TableLaw`, or a
    Python `function` of t, `FunctionLaw`), measured from its value in the initial
    configuration:

        coordinate(q) − coordinate(q₀) = f(t)

    so `Driver(crank_pivot, "150*t")` turns the crank at 150 rad/s from where it was drawn. If
    f(0) ≠ 0, `Mechanism.assemble` moves the joint there. `expression` is a number or an
    arithmetic expression in `t` (`mechsim.model.expressions`: numbers, t, pi, e,
    ``+ − * / **``, parentheses and sin, cos, tan, asin, acos, atan, atan2, sinh, cosh, tanh,
    exp, log, sqrt, abs, hypot, radians, degrees, and step(t, t0, s0, t1, s1), MSC Adams'
    smooth cubic step from s0 to s1). It is parsed here, not evaluated by
    Python: anything else, an unknown name among them, is a ModelError naming the driver.

    `values` binds other names of the expression to numbers or Parameters
    (`mechsim.model.parameters`): `Driver(pivot, "w*t", values={"w": ms.Parameter("w",
    150.0)})` turns the crank at a speed a design can change (`Mechanism.set_parameters`,
    no new build: the law's numbers are parameters of the compiled model) and whose exact
    sensitivities the analyses give.
    """

    kind = "driver"
    parameter_names = ("offset",)
    equation_labels = ("coordinate",)

    def __init__(self, joint: Joint, expression=None, name: str | None = None, *,
                 table=None, function=None, values=None):
        self.joint = coordinate_joint(joint, "driver", "prescribe")
        self.name = name_or_default(name, f"driver({joint.name})", "driver")
        if sum(x is not None for x in (expression, table, function)) != 1:
            raise ModelError(f"driver '{self.name}': give an `expression` or a `table`, "
                             "or a `function`, one of them")
        if table is not None:
            self.law = TableLaw(table, f"driver '{self.name}' `table`")
        elif function is not None:
            self.law = FunctionLaw(function, f"driver '{self.name}'")
        self.values = self._checked_values(values, expression)
        self._unbound = None
        if expression is not None:
            self._unbound = parse(expression, {"t", *self.values},
                                  f"driver '{self.name}' `expression`")
            unused = sorted(set(self.values) - self._unbound.names)
            if unused:
                raise ModelError(f"driver '{self.name}': `values` names {unused[0]!r}, which "
                                 f"its expression {self._unbound.text!r:.80} does not use")
            self.refresh_numbers()

    @property
    def expression(self) -> str:
        """Its law's text (with the `values` bound to it now, as numbers)."""
        return self.law.text

    def _checked_values(self, values, expression) -> dict:
        """`values` as a dict of names to numbers or Parameters; ModelError naming the
        driver and the key where it is not one."""
        if values is None:
            return {}
        owner = f"driver '{self.name}'"
        if expression is None:
            raise ModelError(f"{owner}: `values` binds names of an expression; a table or a "
                             "function has none")
        if not isinstance(values, dict):
            raise ModelError(f"{owner}: `values` must be a dict of names to numbers or "
                             f"Parameters, got {type(values).__name__}")
        out = {}
        for key, x in values.items():
            if not isinstance(key, str) or not key.isidentifier() or key == "t":
                raise ModelError(f"{owner}: `values` key {key!r:.40} is not a name the law "
                                 "can use (an identifier other than t)")
            if not dual.is_exact(x):
                x = scalar(x, f"values[{key!r}]", owner)
            out[key] = x
        return out

    def exact_numbers(self) -> list:
        """The numbers bound into its law (`values`, Parameters kept)."""
        return list(self.values.values())

    def refresh_numbers(self) -> None:
        """Its law with the bound numbers' present values (after the Parameters took new
        ones): the same template, new constants."""
        if self._unbound is None:
            return
        bound = {k: dual.value_of(x) for k, x in self.values.items()}
        self.law = self._unbound.bind(**bound) if bound else self._unbound
        try:
            self._unbound.exact_constants(self.values)    # a Parameter as an exponent: refused
        except ModelError as exc:
            raise ModelError(f"driver '{self.name}': {exc}") from None

    @property
    def tabulated(self) -> bool:
        """Is its law a table (`TableLaw`)?"""
        return isinstance(self.law, TableLaw)

    @property
    def evaluated(self) -> bool:
        """Is its law evaluated in numbers only (a Python function, a table of more than
        `GENERATED_POINTS`)? Such a driver runs on the assembled build, which evaluates
        laws itself. A smaller table is not: its spline's knots and coefficients are
        numbers of the generated model (`TableLaw.constants`)."""
        return isinstance(self.law, FunctionLaw) or \
            (isinstance(self.law, TableLaw) and not self.law.generated)

    def value(self, t: float) -> float:
        """f(t), the prescribed change of the joint's coordinate (float arithmetic)."""
        return self.law.value(t=t)

    def values_at(self, ts) -> np.ndarray:
        """f at the times `ts` (an array): an expression's law in numpy at once (its values
        may differ from `value`'s in the last bit), any other law, and an expression not
        finite everywhere there, one `value` at a time (whose errors say why)."""
        ts = np.asarray(ts, float)
        if isinstance(self.law, Expression):
            out = self.law.values(t=ts)
            if np.all(np.isfinite(out)):
                return out
        return np.array([self.value(t) for t in ts.ravel()], float).reshape(ts.shape)

    @property
    def n_equations(self) -> int:
        return 1

    # Its offset carries the derivatives of Parameters in its joint's bodies' angles.
    carries_parameters = True

    def parameter_values(self):
        return (self.joint.exact_initial_coordinate(),)

    @property
    def exact_law_constants(self) -> list:
        """`law_constants`, those bound to Parameters as Duals (their exact derivatives)."""
        if self._unbound is None or not self.values:
            return self.law_constants
        return self._unbound.exact_constants(self.values)

    @property
    def law_constants(self) -> list[float]:
        """The numbers of its law (`Expression.constants`): parameters of the compiled model,
        so that drivers whose laws differ only in them (a sweep over crank speeds) share one
        compiled structure."""
        return self.law.constants()

    def equations(self, ctx, p):
        if self.tabulated and self.law.generated:
            law = ctx.table(self.law.pieces, ctx.t, ctx.law_constants(self))
        else:
            law = self.law.to_sympy({"t": ctx.t}, constants=ctx.law_constants(self))
        return [self.displacement(ctx, p) - law]

    def displacement(self, ctx, p):
        """The joint's coordinate less its initial value: the equation's part that does not
        depend on time (Φ = displacement − f(t)). The type kernels of `mechsim.assembly`
        differentiate it once for every driver of its kind and take f from the law."""
        return self.joint.coordinate(ctx, ctx.parameters(self.joint)) - p["offset"]

    def structure(self, index) -> tuple:
        """Its kind, the driven joint's position `index(joint)` and its law's template (its
        numbers are parameters: `law_constants`)."""
        return (self.kind, index(self.joint), self.law.template)

    def __repr__(self):
        return f"Driver({self.joint.name!r}, {self.expression!r})"


# How far past its first and last time a table's spline is evaluated, in its span.
REACH = 1e-6
# Up to this many points a table's spline is part of the generated model; a longer one
# is evaluated by the assembled build (a generated model's every Python function unpacks
# all its numbers, and its source grows with them: past about this many the assembled
# build costs less, docs/benchmarks.md).
GENERATED_POINTS = 1000


class TableLaw:
    """A drive's law given as data: `table` = (times, values), or rows (t, value), with
    times strictly increasing, at least 4 points, finite. Between them the not-a-knot cubic
    spline through every point (scipy's CubicSpline): twice continuously differentiable,
    so the prescribed rate and acceleration are continuous and the reactions and efforts
    smooth. Defined on [times[0], times[-1]] only: a run must stay inside it
    (`Mechanism.simulate` refuses one that does not, naming the driver), and a value
    asked for outside is a ValueError. It offers what a driver asks of a law: `text`,
    `value(t=)`, `jet`, `constants()`: the spline's knots and pieces' coefficients
    (`mechsim.model.splines`' layout), numbers of the generated model, which evaluates the
    spline itself (in C where it is compiled), so that tables of as many points share one
    build; `template` names only their count. A table of more than `GENERATED_POINTS`
    (`generated` False) has no constants: the assembled build evaluates it."""

    MIN_POINTS = 4
    names = frozenset({"t"})

    def __init__(self, table, owner: str):
        data = number_array(table, owner, "(times, values) or rows (t, value) of numbers")
        if data.ndim == 2 and data.shape[1] == 2 and data.shape[0] != 2:
            data = data.T                                  # rows (t, value)
        if data.ndim != 2 or data.shape[0] != 2:
            raise ModelError(f"{owner}: expected (times, values) of equal length or rows "
                             f"(t, value), got an array of shape {data.shape}")
        times, values = data
        if times.size < self.MIN_POINTS:
            raise ModelError(f"{owner}: needs at least {self.MIN_POINTS} points for its "
                             f"spline, got {times.size}")
        if not np.all(np.isfinite(data)):
            k = int(np.flatnonzero(~np.all(np.isfinite(data), axis=0))[0])
            raise ModelError(f"{owner}: point {k} (t = {times[k]!r}, value = {values[k]!r}) "
                             "is not finite")
        steps = np.diff(times)
        if not np.all(steps > 0.0):
            k = int(np.flatnonzero(~(steps > 0.0))[0])
            raise ModelError(f"{owner}: the times must increase strictly; t = "
                             f"{times[k + 1]:g} (point {k + 1}) follows t = {times[k]:g}")
        self.times, self.values = times, values
        self.text = (f"a table of {times.size} points over [{times[0]:g}, {times[-1]:g}] s")
        self.canonical = self.text
        self.pieces = times.size - 1
        self.generated = times.size <= GENERATED_POINTS
        self.template = f"table of {self.pieces} cubic pieces" if self.generated else "table"
        self._spline = None          # `spline`

    @property
    def domain(self) -> tuple[float, float]:
        """(first time, last time) of the table [s]."""
        return float(self.times[0]), float(self.times[-1])

    def _at(self, t: float):
        t0, t1 = self.domain
        # The solvers look a hair past a run's end (a difference quotient's 1e-7 s): the
        # end pieces of the spline go on that far, smoothly.
        slack = REACH * (t1 - t0)
        if not t0 - slack <= t <= t1 + slack:
            raise ValueError(f"t = {t:.9g} is outside the table's times [{t0:g}, {t1:g}]")
        return t

    @property
    def spline(self) -> tuple:
        """The spline's knots, then each piece's (a, b, c, d) of f = ((a u + b) u + c) u +
        d (`mechsim.model.splines`' layout), computed once."""
        if self._spline is None:
            from scipy.interpolate import CubicSpline
            c = CubicSpline(self.times, self.values, bc_type="not-a-knot").c
            self._spline = tuple(self.times.tolist()) + tuple(c.T.ravel().tolist())
        return self._spline

    def value(self, t: float) -> float:
        """The spline's value at t (ValueError outside the table's times)."""
        return evaluate_table(0, self._at(float(t)), self.pieces, self.spline)

    def jet(self, name: str, value: float, **_) -> tuple[float, float, float]:
        """(f, f', f'') at t = `value`, the spline's and its derivatives', summed as the
        generated model sums them (`mechsim.model.splines.evaluate_table`)."""
        t = self._at(float(value))
        return tuple(evaluate_table(k, t, self.pieces, self.spline) for k in range(3))

    def constants(self) -> list[float]:
        """The knots, then each piece's (a, b, c, d) of f = ((a u + b) u + c) u + d (none
        where the table is not `generated`)."""
        return list(self.spline) if self.generated else []

    def __repr__(self):
        return f"TableLaw({self.text})"


# The step of the central differences that give a function law's rate and acceleration
# where the function gives its value alone (relative to max(1, |t|)).
DIFFERENCE_STEP = 1e-4


class FunctionLaw:
    """A drive's law as a Python function of t (the user's own code, called as a load's
    function is; an exception in it ends the run with a LoadError naming the driver). It
    returns the change s(t) of the joint's coordinate, or (s, ṡ, s̈): then the rate and
    acceleration are exact; else they come from central differences of step
    `DIFFERENCE_STEP` (about 1e-8 relative in the rate, 1e-6 in the acceleration). Such a
    driver runs on the assembled build, and a scene cannot hold it."""

    names = frozenset({"t"})
    template = "function"

    def __init__(self, function, owner: str):
        if not callable(function):
            raise ModelError(f"{owner}: `function` must be a function of t, got "
                             f"{type(function).__name__}")
        self.function, self.owner = function, owner
        self.text = f"the function {getattr(function, '__name__', 'given')}(t)"
        self.canonical = self.text

    def _call(self, t):
        from .checks import call_user
        out = call_user(self.function, (float(t),), self.owner)
        try:
            values = tuple(float(x) for x in out) if isinstance(out, (tuple, list)) \
                else (float(out),)
        except (TypeError, ValueError):
            values = ()
        if len(values) not in (1, 3):
            from .checks import LoadError
            raise LoadError(f"{self.owner}: its function returned {out!r:.60} at t = "
                            f"{float(t):.9g}; expected s or (s, rate, acceleration)")
        return values

    def value(self, t: float) -> float:
        return self._call(t)[0]

    def jet(self, name: str, value: float, **_) -> tuple[float, float, float]:
        """(s, ṡ, s̈) at t = `value`: the function's own, or by central differences."""
        t = float(value)
        got = self._call(t)
        if len(got) == 3:
            return got
        h = DIFFERENCE_STEP * max(1.0, abs(t))
        ahead, behind = self._call(t + h)[0], self._call(t - h)[0]
        return got[0], (ahead - behind) / (2.0 * h), (ahead - 2.0 * got[0] + behind) / h**2

    def constants(self) -> list[float]:
        return []

    def __repr__(self):
        return f"FunctionLaw({self.text})"
