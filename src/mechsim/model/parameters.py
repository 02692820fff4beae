"""Named design parameters and the numbers computed from them, with their exact derivatives.

A `Parameter` stands wherever a model argument accepts one (see below) and supports
arithmetic and numpy's functions: `(L, 0.0)`, `L / 2`, `np.array([L * np.cos(a), 0.0])`.
Every number computed from parameters is a `Dual`: its value and its exact first
derivatives with respect to each parameter it depends on (forward-mode differentiation
of the model's own arithmetic). The mechanism's build turns the joints' body-fixed
geometry, computed from such numbers, into the parameter vector of the generated
equations and its derivatives ∂p/∂(parameter), and sympy differentiates the equations in
p exactly (`mechsim.symbolic.sensitivity`): sensitivities are exact, never finite
differences.

A Dual is not a float: `float(x)`, `math.cos(x)` and friends raise TypeError, because they
would drop its derivatives silently; numpy's functions (`np.cos(x)`) carry them, and a
model argument that does not take parameters yet refuses one with a ModelError naming it.
Arguments that take parameters: a rigid body's `position`, `angle`, `mass` and `inertia`
(and `RigidBody.rod`'s `start`, `end` and `mass`), and its initial `velocity` and
`angular_velocity` (a simulation's sensitivities start from them; a driven mechanism's
analysis does not depend on them); a revolute joint's `at`, `local_a`,
`local_b`; a prismatic joint's `axis` and `at` (a driver's offset, its joint's initial
coordinate, follows its bodies' angles). A constraint that reads such numbers without
carrying their derivatives (a gear, a point on a curve) refuses sensitivities, naming
itself (`MechanismModel.parameter_blind`).

Every Dual remembers what it was computed from, so `refresh` computes it again after a
Parameter takes a new value (`MechanismModel.set_parameters`): a model built once takes
new values without being built again, and its generated equations, which take the
geometry as parameters, need no new code.
"""

from __future__ import annotations

import math
import numbers

import numpy as np


def _partials(x) -> dict | None:
    """x's partial derivatives (a dict, empty for a plain number), or None where x is not
    a number a Dual combines with."""
    if isinstance(x, Dual):
        return x.partials
    if isinstance(x, (numbers.Real, np.floating, np.integer)) and not isinstance(x, bool):
        return {}
    return None


def _combine(a: dict, ca: float, b: dict, cb: float) -> dict:
    """ca·a + cb·b for partial-derivative dicts."""
    out = {k: ca * d for k, d in a.items()}
    for k, d in b.items():
        out[k] = out.get(k, 0.0) + cb * d
    return out


class Dual:
    """A number with its exact first derivatives: `value` and `partials` (parameter name →
    ∂value/∂parameter), and how it was computed: `parents` (the Duals it came from) and
    `recompute` (computes it again from them; None for a Parameter or a constant).
    Arithmetic with plain numbers, other Duals and numpy arrays (as
    arrays of Duals) and numpy's ufuncs (sin, cos, tan, arctan2, hypot, sqrt, exp, log,
    square, absolute, power) carry the derivatives; comparisons compare values."""

    __slots__ = ("value", "partials", "parents", "recompute")

    def __init__(self, value: float, partials: dict | None = None):
        self.value = float(value)
        self.partials = dict(partials or {})
        self.parents: tuple = ()
        self.recompute = None

    # --- what a Dual is not ------------------------------------------------------------------
    def __float__(self):
        raise TypeError(f"{self!r} is not a plain number: float() and the math module would drop "
                        "its derivatives; use numpy's functions (np.cos, np.hypot, …) on "
                        "parameters, or `.value` for the number alone")

    def __int__(self):
        raise TypeError(f"{self!r} is not an integer")

    __index__ = __int__

    # --- arithmetic ----------------------------------------------------------------------------
    def _binary(self, other, rule, ufunc, reflected=False):
        """self ∘ other (other ∘ self where `reflected`) by `rule` on values and partials;
        with an array, elementwise over object arrays (`ufunc`)."""
        b = _partials(other)
        if b is not None:
            y = other.value if isinstance(other, Dual) else float(other)
            out = rule(y, b, self.value, self.partials) if reflected else \
                rule(self.value, self.partials, y, b)
            return _recorded(out, (self, other),
                             lambda: self._binary(other, rule, ufunc, reflected))
        if isinstance(other, np.ndarray):
            args = (other, self) if reflected else (self, other)
            return ufunc(*[_objects(x) for x in args])
        return NotImplemented

    def __add__(self, other):
        return self._binary(other, _add, np.add)

    def __radd__(self, other):
        return self._binary(other, _add, np.add, reflected=True)

    def __sub__(self, other):
        return self._binary(other, _sub, np.subtract)

    def __rsub__(self, other):
        return self._binary(other, _sub, np.subtract, reflected=True)

    def __mul__(self, other):
        return self._binary(other, _mul, np.multiply)

    def __rmul__(self, other):
        return self._binary(other, _mul, np.multiply, reflected=True)

    def __truediv__(self, other):
        return self._binary(other, _div, np.true_divide)

    def __rtruediv__(self, other):
        return self._binary(other, _div, np.true_divide, reflected=True)

    def __pow__(self, other):
        return self._binary(other, _pow, np.power)

    def __rpow__(self, other):
        return self._binary(other, _pow, np.power, reflected=True)

    def __neg__(self):
        return _recorded(Dual(-self.value, {k: -d for k, d in self.partials.items()}),
                         (self,), self.__neg__)

    def __pos__(self):
        return self

    def __abs__(self):
        # Recorded, so that a new value of the wrong sign takes the other branch (`refresh`).
        return _chain(self, abs(self.value), math.copysign(1.0, self.value), self.__abs__)

    # --- comparisons (values) ---------------------------------------------------------------------
    def _v(self, other):
        return other.value if isinstance(other, Dual) else other

    def __eq__(self, other):
        return self.value == self._v(other)

    def __ne__(self, other):
        return self.value != self._v(other)

    def __lt__(self, other):
        return self.value < self._v(other)

    def __le__(self, other):
        return self.value <= self._v(other)

    def __gt__(self, other):
        return self.value > self._v(other)

    def __ge__(self, other):
        return self.value >= self._v(other)

    def __bool__(self):
        return self.value != 0.0

    __hash__ = None

    def __reduce__(self):
        # A copy (pickle: the background build, process pools) is a snapshot: its value and
        # partials, not how it was computed (functions do not pickle).
        return (Dual, (self.value, self.partials))

    def __format__(self, spec):
        return format(self.value, spec)

    def __repr__(self):
        names = ", ".join(sorted(self.partials))
        return f"Dual({self.value!r}; d/d {names or '(nothing)'})"

    # --- numpy ---------------------------------------------------------------------------------------
    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        if method != "__call__" or kwargs:
            return NotImplemented
        if any(isinstance(x, np.ndarray) for x in inputs):
            # Elementwise over object arrays: each element's operators and methods.
            return ufunc(*[_objects(x) for x in inputs])
        rule = _UFUNCS.get(ufunc)
        if rule is None:
            raise TypeError(f"numpy's {ufunc.__name__} does not carry a parameter's "
                            f"derivatives ({self!r})")
        return rule(*inputs)

    # numpy's object loops call these methods by the ufunc's name.
    def sin(self):
        return _chain(self, math.sin(self.value), math.cos(self.value), self.sin)

    def cos(self):
        return _chain(self, math.cos(self.value), -math.sin(self.value), self.cos)

    def tan(self):
        t = math.tan(self.value)
        return _chain(self, t, 1.0 + t * t, self.tan)

    def arcsin(self):
        return _chain(self, math.asin(self.value), _inverse_root(self.value), self.arcsin)

    def arccos(self):
        return _chain(self, math.acos(self.value), -_inverse_root(self.value), self.arccos)

    def arctan(self):
        return _chain(self, math.atan(self.value), 1.0 / (1.0 + self.value**2), self.arctan)

    def sqrt(self):
        r = math.sqrt(self.value)
        return _chain(self, r, 0.5 / r if r > 0 else math.inf, self.sqrt)

    def exp(self):
        e = math.exp(self.value)
        return _chain(self, e, e, self.exp)

    def log(self):
        return _chain(self, math.log(self.value), 1.0 / self.value, self.log)

    def arctan2(self, x):
        return atan2(self, x)

    def hypot(self, other):
        return hypot(self, other)


class Parameter(Dual):
    """A named design parameter: a number of the model that sensitivities are taken to
    (`kinematics(..., sensitivities=[name])`, `simulate(..., sensitivities=[name])`).

    Parameters
    ----------
    name : str
        Its name in results (`res.sensitivity(name)`); a non-empty string.
    value : float
        Its value (finite).
    """

    __slots__ = ("name",)

    def __init__(self, name: str, value: float):
        from .checks import ModelError
        if not isinstance(name, str) or not name.strip():
            raise ModelError(f"a Parameter needs a non-empty name, got {name!r:.60}")
        super().__init__(finite_value(value, name), {name: 1.0})
        self.name = name

    def set(self, value) -> None:
        """Give it a new value (`MechanismModel.set_parameters` does, and computes the
        numbers that depend on it again)."""
        self.value = finite_value(value, self.name)

    def __reduce__(self):
        return (Parameter, (self.name, self.value))

    def __repr__(self):
        return f"Parameter({self.name!r}, {self.value!r})"


def finite_value(value, name: str) -> float:
    """`value` as a float, or a ModelError naming the Parameter: a plain finite number."""
    from .checks import ModelError
    if isinstance(value, (bool, str, bytes, Dual)) or \
            not isinstance(value, (numbers.Real, np.floating, np.integer)) or \
            not math.isfinite(value):
        raise ModelError(f"Parameter '{name}': `value` must be a finite number, got "
                         f"{value!r:.60}")
    return float(value)


def _add(x, a, y, b):
    return Dual(x + y, _combine(a, 1.0, b, 1.0))


def _sub(x, a, y, b):
    return Dual(x - y, _combine(a, 1.0, b, -1.0))


def _mul(x, a, y, b):
    return Dual(x * y, _combine(a, y, b, x))


def _div(x, a, y, b):
    return Dual(x / y, _combine(a, 1.0 / y, b, -x / (y * y)))


def _pow(x, a, y, b):
    value = x ** y
    da = y * x ** (y - 1.0) if a else 0.0
    db = value * math.log(x) if b else 0.0
    return Dual(value, _combine(a, da, b, db))


def _inverse_root(x: float) -> float:
    """1/√(1 − x²), the slope of arcsin (infinite at ±1)."""
    root = math.sqrt(1.0 - x * x)
    return 1.0 / root if root > 0.0 else math.inf


def _chain(x: Dual, value: float, slope: float, again) -> Dual:
    """f(x) of value `value` and slope f'(x); `again` computes it anew (`refresh`)."""
    return _recorded(Dual(value, {k: slope * d for k, d in x.partials.items()}), (x,), again)


def _recorded(out: Dual, parents, again) -> Dual:
    """`out`, with what it was computed from (`refresh`)."""
    out.parents = tuple(x for x in parents if isinstance(x, Dual))
    out.recompute = again
    return out


def refresh(numbers) -> None:
    """Compute every Dual among `numbers` (numbers, arrays or sequences of them) again, in
    place, from the Parameters' present values: each from the Duals it was computed from,
    in the order they were computed, so all that share a Parameter agree."""
    done, order = set(), []

    def visit(x):
        stack = [(x, False)]
        while stack:
            node, expanded = stack.pop()
            if id(node) in done:
                continue
            if expanded or not node.parents:
                done.add(id(node))
                order.append(node)
                continue
            stack.append((node, True))
            stack.extend((p, False) for p in node.parents if id(p) not in done)

    for x in _flat(numbers):
        visit(x)
    for node in order:
        if node.recompute is not None:
            new = node.recompute()
            node.value, node.partials = new.value, new.partials


def _flat(numbers):
    """The Duals among numbers, arrays and (nested) sequences of them."""
    if isinstance(numbers, Dual):
        yield numbers
    elif isinstance(numbers, np.ndarray):
        if numbers.dtype == object:
            for x in numbers.flat:
                yield from _flat(x)
    elif isinstance(numbers, (list, tuple)):
        for x in numbers:
            yield from _flat(x)


def leaves(numbers) -> dict:
    """name -> Parameter of every Parameter the numbers were computed from."""
    out, seen = {}, set()
    stack = list(_flat(numbers))
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, Parameter):
            out.setdefault(node.name, node)
        stack.extend(node.parents)
    return out


def _objects(x):
    """x as an object array (a Dual as a 0-d one), for numpy's elementwise object loops."""
    if isinstance(x, np.ndarray):
        return x.astype(object)
    out = np.empty((), dtype=object)
    out[()] = x
    return out


def lift(x) -> Dual:
    """x as a Dual (a plain number with no derivatives)."""
    return x if isinstance(x, Dual) else Dual(x)


def value_of(x) -> float:
    """The number alone of x (a Dual's value, a plain number as a float)."""
    return x.value if isinstance(x, Dual) else float(x)


def is_exact(x) -> bool:
    """Does x (a number, or a sequence or array of them) hold a Dual?"""
    if isinstance(x, Dual):
        return True
    if isinstance(x, np.ndarray):
        return x.dtype == object and any(isinstance(e, Dual) for e in x.flat)
    if isinstance(x, (list, tuple)):
        return any(is_exact(e) for e in x)
    return False


def values(x) -> np.ndarray:
    """A number, sequence or array of them (Duals among them) as a float array of values."""
    return np.vectorize(value_of, otypes=[float])(np.asarray(x, dtype=object)) \
        if is_exact(x) else np.asarray(x, dtype=float)


def cos(x):
    return x.cos() if isinstance(x, Dual) else math.cos(x)


def sin(x):
    return x.sin() if isinstance(x, Dual) else math.sin(x)


def sqrt(x):
    return x.sqrt() if isinstance(x, Dual) else math.sqrt(x)


def atan2(y, x):
    """atan2 carrying derivatives: d = (x dy − y dx)/(x² + y²)."""
    if not isinstance(x, Dual) and not isinstance(y, Dual):
        return math.atan2(y, x)
    y, x = lift(y), lift(x)
    r2 = x.value * x.value + y.value * y.value
    return _recorded(Dual(math.atan2(y.value, x.value),
                          _combine(y.partials, x.value / r2, x.partials, -y.value / r2)),
                     (y, x), lambda: atan2(y, x))


def hypot(x, y):
    if not isinstance(x, Dual) and not isinstance(y, Dual):
        return math.hypot(x, y)
    x, y = lift(x), lift(y)
    r = math.hypot(x.value, y.value)
    return _recorded(Dual(r, _combine(x.partials, x.value / r, y.partials, y.value / r)),
                     (x, y), lambda: hypot(x, y))


_UFUNCS = {
    np.sin: sin, np.cos: cos, np.sqrt: sqrt,
    np.tan: lambda x: x.tan(), np.exp: lambda x: x.exp(), np.log: lambda x: x.log(),
    np.arcsin: lambda x: x.arcsin(), np.arccos: lambda x: x.arccos(),
    np.arctan: lambda x: x.arctan(),
    np.arctan2: atan2, np.hypot: hypot,
    np.square: lambda x: x * x, np.absolute: abs, np.negative: lambda x: -x,
    np.positive: lambda x: x,
    np.add: lambda a, b: lift(a) + b, np.subtract: lambda a, b: lift(a) - b,
    np.multiply: lambda a, b: lift(a) * b, np.true_divide: lambda a, b: lift(a) / b,
    np.power: lambda a, b: lift(a) ** b,
}


def rotation(angle) -> np.ndarray:
    """A(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]: a float array, or an object array of
    Duals where θ is one."""
    c, s = cos(angle), sin(angle)
    return np.array([[c, -s], [s, c]], dtype=object if isinstance(angle, Dual) else float)


def gradient(items, names) -> np.ndarray:
    """(len(items), len(names)): ∂items[i]/∂names[j] of numbers some of which are Duals."""
    out = np.zeros((len(items), len(names)))
    for i, x in enumerate(items):
        if isinstance(x, Dual):
            for j, name in enumerate(names):
                out[i, j] = x.partials.get(name, 0.0)
    return out


def parameter_names(items) -> list[str]:
    """The names of the parameters the numbers `items` depend on, sorted."""
    return sorted({k for x in items if isinstance(x, Dual) for k in x.partials})
