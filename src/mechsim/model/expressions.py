"""Arithmetic expressions that users write (driver laws, scene numbers), parsed without `eval`.

A text is parsed by Python's `ast` into a syntax tree and only the nodes listed here are
accepted: numbers, the names the caller allows (dotted ones such as `crank.angle` too),
`+ − * / **`, unary signs, parentheses and calls of the functions in `FUNCTIONS`. Anything
else (other attributes, subscripts, keywords, lambdas, comparisons, strings, …) is an
`ExpressionError` naming the owner and the offending token. The accepted tree is kept as
plain tuples and evaluated by this module (floats) or
turned into sympy by `to_sympy`: nothing a user writes is executed.

Limits keep a hostile or careless text from hanging the parser or sympy: at most
`MAX_LENGTH` characters and `MAX_NODES` nodes nested at most `MAX_DEPTH` deep, integer
exponents of at most `MAX_EXPONENT` in magnitude, and every sub-expression made of numbers
alone must have a finite value of magnitude at most `MAX_CONSTANT` (so `9**9**9*t` is an
error, not an exact integer with 370 million digits). Such a sub-expression is replaced by
its double at parsing, so that every evaluation uses the same number.
"""

from __future__ import annotations

import ast
import math
import numbers

import numpy as np

from . import parameters as dual
from .checks import ModelError

MAX_LENGTH = 2000
MAX_NODES = 2000
MAX_DEPTH = 200
MAX_EXPONENT = 64
MAX_CONSTANT = 1e300
KNOWN_SHOWN = 24          # names an unknown-name message lists

def _step(x, x0, h0, x1, h1):
    """The smooth step of MSC Adams' STEP: h0 up to x0, h1 from x1, between them the cubic
    h0 + (h1 − h0) u² (3 − 2 u), u = (x − x0)/(x1 − x0), continuous in slope (a ramp-up
    of a motor's speed, a load switched on); at x0 and x1 its derivatives are those after
    them. Needs x0 < x1."""
    if not x0 < x1:
        raise ValueError(f"step needs x0 < x1, got {x0:g} and {x1:g}")
    at = x.f if isinstance(x, Jet) else x
    if at < x0:                  # at x0 and at x1 the derivatives after them (a run's way)
        return h0 + 0.0 * x
    if at >= x1:
        return h1 + 0.0 * x
    u = (x - x0) / (x1 - x0)
    return h0 + (h1 - h0) * u * u * (3.0 - 2.0 * u)


def _steps(x, x0, h0, x1, h1):
    """`_step` at an array x (x0 < x1 numbers)."""
    if not x0 < x1:
        raise ValueError(f"step needs x0 < x1, got {x0:g} and {x1:g}")
    u = (x - x0) / (x1 - x0)
    return np.where(x < x0, h0, np.where(x >= x1, h1, h0 + (h1 - h0) * u * u * (3.0 - 2.0 * u)))


# The functions over numpy arrays (`Expression.values`).
_ARRAYS = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin,
           "acos": np.arccos, "atan": np.arctan, "atan2": np.arctan2, "sinh": np.sinh,
           "cosh": np.cosh, "tanh": np.tanh, "exp": np.exp, "log": np.log, "sqrt": np.sqrt,
           "abs": np.abs, "hypot": np.hypot, "radians": np.radians, "degrees": np.degrees,
           "step": _steps}

# name: (number of arguments, float function, sympy function name)
FUNCTIONS = {
    "sin": (1, math.sin, "sin"), "cos": (1, math.cos, "cos"), "tan": (1, math.tan, "tan"),
    "asin": (1, math.asin, "asin"), "acos": (1, math.acos, "acos"),
    "atan": (1, math.atan, "atan"), "atan2": (2, math.atan2, "atan2"),
    "sinh": (1, math.sinh, "sinh"), "cosh": (1, math.cosh, "cosh"),
    "tanh": (1, math.tanh, "tanh"), "exp": (1, math.exp, "exp"), "log": (1, math.log, "log"),
    "sqrt": (1, math.sqrt, "sqrt"), "abs": (1, abs, "Abs"),
    "hypot": (2, math.hypot, None), "radians": (1, math.radians, None),
    "degrees": (1, math.degrees, None), "step": (5, _step, None),
}
CONSTANTS = {"pi": math.pi, "e": math.e}
# The functions that carry a Parameter's derivatives (`mechsim.model.parameters`).
_DUALS = {"sin": dual.sin, "cos": dual.cos, "tan": lambda x: x.tan(), "sqrt": dual.sqrt,
          "exp": lambda x: x.exp(), "log": lambda x: x.log(), "atan2": dual.atan2,
          "hypot": dual.hypot, "abs": abs, "radians": lambda x: x * (math.pi / 180.0),
          "degrees": lambda x: x * (180.0 / math.pi)}

_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_HINTS = {ast.BitXor: "`^` is not a power here: write `**`",
          ast.Mod: "`%` is not supported", ast.FloorDiv: "`//` is not supported"}


class ExpressionError(ModelError):
    """A user's expression is not one mechsim accepts; the message names its owner."""


class Expression:
    """A parsed expression: `text` (as given), `tree` (nested tuples), `names` (the free
    names it uses). Evaluate with `value(**names)`; `to_sympy(symbols)` gives the sympy
    expression, `symbols` mapping each free name to a sympy object."""

    __slots__ = ("text", "tree", "names")

    def __init__(self, text: str, tree: tuple, names: frozenset):
        self.text, self.tree, self.names = text, tree, names

    @property
    def canonical(self) -> str:
        """The tree written out with full parentheses: equal for texts that differ only in
        spacing or redundant parentheses (a cache key's part)."""
        return _canonical(self.tree)

    def value(self, **values) -> float:
        """The float value with the free names bound to `values`; ArithmeticError or
        ValueError where it is undefined (log of a negative number, overflow)."""
        return float(_evaluate(self.tree, values))

    def values(self, **arrays) -> np.ndarray:
        """`value` at arrays of the free names (broadcast together), in numpy: NaN or ±inf
        where it is undefined (no error). Its values may differ from `value`'s in the last
        bit (numpy's and the math module's functions)."""
        with np.errstate(all="ignore"):
            out = _evaluate(self.tree, {k: np.asarray(a, float) for k, a in arrays.items()},
                            arrays=True)
        shape = np.broadcast_shapes(*(np.shape(a) for a in arrays.values()))
        return np.array(np.broadcast_to(out, shape), float)

    def exact_value(self, **values):
        """`value`, with Parameters among `values` carried (`mechsim.model.parameters`):
        a Dual where the result depends on one, else a float."""
        out = _evaluate(self.tree, values)
        return out if isinstance(out, dual.Dual) else float(out)

    def jet(self, name: str, value: float, **values) -> tuple[float, float, float]:
        """(f, df/dx, d²f/dx²) at `name` = `value` (the other free names bound to `values`),
        by second-order forward differentiation of the tree in floats (`Jet`): what a
        driver's Φ, Φ_t and γ need of its law, exact to round-off and with no sympy."""
        out = _evaluate(self.tree, {**values, name: Jet(float(value), 1.0, 0.0)})
        if isinstance(out, Jet):
            return float(out.f), float(out.d1), float(out.d2)
        return float(out), 0.0, 0.0

    def to_sympy(self, symbols: dict, constants=None):
        """The sympy expression; `constants`: sympy objects standing in for its `constants`
        (in their order), else the numbers themselves."""
        import sympy as sp
        stand_ins = None if constants is None else iter(constants)
        return _sympy(self.tree, symbols, sp, stand_ins)

    def constants(self) -> list[float]:
        """Its numbers, in the order of the tree, but for whole-number exponents (which
        shape the expression): what a compiled model takes as parameters, so that laws
        that differ only in them share one compiled structure (`template`)."""
        out = []
        _constants(self.tree, out)
        return out

    @property
    def template(self) -> str:
        """`canonical` with each of its `constants` written as #."""
        return _canonical(self.tree, template=True)

    def exact_constants(self, values: dict) -> list:
        """`constants` of `bind(**values)` in the same order, each value bound to a name
        as given (a Parameter or a Dual kept: `mechsim.model.parameters`). ModelError
        where a Parameter would be a whole-number exponent (part of the shape, not
        differentiated)."""
        out = []
        _exact_constants(self.tree, values, out)
        return out

    def bind(self, **values) -> "Expression":
        """The same expression with the names in `values` replaced by those numbers (a
        scene's parameters in a driver's law), written out as its canonical text."""
        tree = _bind(self.tree, values)
        return Expression(_canonical(tree), tree, self.names - frozenset(values))

    def __repr__(self):
        return f"Expression({self.text!r})"


def parse(text, names, owner: str) -> Expression:
    """Parse `text` (a str, or an int/float taken as a constant) allowing the free names in
    `names` besides `CONSTANTS`; raise ExpressionError naming `owner` where it is not a
    plain arithmetic expression of those names."""
    if isinstance(text, bool) or not isinstance(text, (str, numbers.Real)):
        raise ExpressionError(f"{owner}: expected a number or an expression string, "
                              f"got {type(text).__name__} {text!r:.80}")
    if not isinstance(text, str):
        value = float(text)
        if not math.isfinite(value):
            raise ExpressionError(f"{owner}: expected a finite number, got {value}")
        return Expression(repr(value), ("num", value), frozenset())
    if not text.strip():
        raise ExpressionError(f"{owner}: the expression is empty")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"{owner}: the expression has {len(text)} characters; at most "
                              f"{MAX_LENGTH} are accepted")
    try:
        node = ast.parse(text.strip(), mode="eval").body
    except (SyntaxError, ValueError, RecursionError, MemoryError) as exc:
        detail = getattr(exc, "msg", None) or type(exc).__name__
        raise ExpressionError(f"{owner}: cannot parse {text!r:.200}: {detail}") from None
    builder = _Builder(text, frozenset(names), owner)
    tree = builder.build(node, 0)
    return Expression(text.strip(), tree, frozenset(builder.used))


def _dotted(node) -> str | None:
    """The name a Name or a chain of attributes of one spells ("crank.angle.rate"), None
    for any other attribute (of a call, a number, …)."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return ".".join([node.id, *reversed(parts)])


class _Builder:
    """Turns an `ast` tree into the tuple tree, checking each node against the whitelist."""

    def __init__(self, text, names, owner):
        self.text, self.names, self.owner = text, names, owner
        self.count = 0
        self.used: set[str] = set()

    def fail(self, what: str):
        raise ExpressionError(f"{self.owner}: {what} in {self.text!r:.200}")

    def build(self, node, depth):
        self.count += 1
        if self.count > MAX_NODES:
            self.fail(f"more than {MAX_NODES} terms")
        if depth > MAX_DEPTH:
            self.fail(f"nesting deeper than {MAX_DEPTH}")
        tree = self._node(node, depth + 1)
        if _is_constant(tree) and tree[0] not in ("num", "const"):
            # Folded to its double here, once: every evaluation (this module's floats,
            # sympy and the C it prints, the assembled kernels) then uses the same number.
            # Left to sympy, 5**30 stayed an exact integer that C read as an overflowing
            # integer literal (cos(5**30): -0.49820 compiled against 0.27471).
            return ("num", self._check_constant(tree))
        return tree

    def _node(self, node, depth):
        if isinstance(node, ast.Constant):
            v = node.value
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                self.fail(f"unsupported literal {v!r:.40}")
            if abs(v) > MAX_CONSTANT or not (isinstance(v, int) or math.isfinite(v)):
                self.fail(f"number {str(v)[:40]} out of range (magnitude up to "
                          f"{MAX_CONSTANT:g})")
            return ("num", float(v) if isinstance(v, int) and abs(v) > 2 ** 53 else v)
        if isinstance(node, (ast.Name, ast.Attribute)):
            name = _dotted(node)
            if name is None or ("." in name and name not in self.names and
                                name.split(".")[0] in self.names | set(CONSTANTS)):
                segment = ast.get_source_segment(self.text.strip(), node) or "attribute"
                self.fail(f"unsupported syntax {segment!r:.60}")
            if name in self.names:
                self.used.add(name)
                return ("name", name)
            if name in CONSTANTS:
                return ("const", name)
            known = sorted(self.names | set(CONSTANTS))
            shown = ", ".join(known[:KNOWN_SHOWN]) + (", …" if len(known) > KNOWN_SHOWN else "")
            self.fail(f"unknown name {name!r} (known: {shown})")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            operand = self.build(node.operand, depth)
            return ("neg", operand) if isinstance(node.op, ast.USub) else operand
        if isinstance(node, ast.BinOp):
            op = _BINARY.get(type(node.op))
            if op is None:
                self.fail(_HINTS.get(type(node.op), f"unsupported operator "
                                                     f"{type(node.op).__name__}"))
            left, right = self.build(node.left, depth), self.build(node.right, depth)
            if op == "**" and _is_constant(right):
                exponent = _evaluate(right, {})
                if exponent == int(exponent) and abs(exponent) > MAX_EXPONENT:
                    self.fail(f"exponent {exponent:g} too large (at most {MAX_EXPONENT})")
            return ("op", op, left, right)
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                what = node.func.id if isinstance(node.func, ast.Name) else \
                    ast.get_source_segment(self.text.strip(), node.func) or "call"
                self.fail(f"unknown function {what!r:.60} (known: {', '.join(FUNCTIONS)})")
            name = node.func.id
            arity = FUNCTIONS[name][0]
            if node.keywords or len(node.args) != arity or \
                    any(isinstance(a, ast.Starred) for a in node.args):
                self.fail(f"{name} takes {arity} argument(s)")
            return ("call", name, *(self.build(a, depth) for a in node.args))
        segment = ast.get_source_segment(self.text.strip(), node) or type(node).__name__
        self.fail(f"unsupported syntax {segment!r:.60}")

    def _check_constant(self, tree):
        try:
            value = _evaluate(tree, {})
        except OverflowError:
            self.fail(f"{_canonical(tree)} overflows")
        except (ArithmeticError, ValueError) as exc:
            self.fail(f"{_canonical(tree)} cannot be evaluated ({exc})")
        if isinstance(value, complex) or not math.isfinite(value) or abs(value) > MAX_CONSTANT:
            self.fail(f"{_canonical(tree)} is out of range (magnitude up to {MAX_CONSTANT:g})")
        return float(value)


class Jet:
    """A truncated Taylor series f + d1 h + d2 h²/2 in one variable: the value with its
    first and second derivatives, carried through the arithmetic and functions of
    `FUNCTIONS` (each by its own chain rule, f(u)'' = f''(u) u'² + f'(u) u'')."""

    __slots__ = ("f", "d1", "d2")

    def __init__(self, f, d1, d2):
        self.f, self.d1, self.d2 = f, d1, d2

    @staticmethod
    def of(x) -> "Jet":
        return x if isinstance(x, Jet) else Jet(float(x), 0.0, 0.0)

    def chain(self, f, df, ddf) -> "Jet":
        """g(self) given g = f, g' = df, g'' = ddf at self.f."""
        return Jet(f, df * self.d1, ddf * self.d1 * self.d1 + df * self.d2)

    def __add__(self, o):
        o = Jet.of(o)
        return Jet(self.f + o.f, self.d1 + o.d1, self.d2 + o.d2)

    __radd__ = __add__

    def __neg__(self):
        return Jet(-self.f, -self.d1, -self.d2)

    def __sub__(self, o):
        return self + (-Jet.of(o))

    def __rsub__(self, o):
        return Jet.of(o) + (-self)

    def __mul__(self, o):
        o = Jet.of(o)
        return Jet(self.f * o.f, self.d1 * o.f + self.f * o.d1,
                   self.d2 * o.f + 2.0 * self.d1 * o.d1 + self.f * o.d2)

    __rmul__ = __mul__

    def __truediv__(self, o):
        o = Jet.of(o)
        return self * o.chain(1.0 / o.f, -1.0 / o.f ** 2, 2.0 / o.f ** 3)

    def __rtruediv__(self, o):
        return Jet.of(o) / self

    def __pow__(self, o):
        o = Jet.of(o)
        if o.d1 == 0.0 and o.d2 == 0.0:            # a constant exponent: x**c
            c, x = o.f, self.f
            value = x ** c
            if isinstance(value, complex):
                raise ValueError(f"({x:g})**({c:g}) is not real")
            if c in (0.0, 1.0):
                return Jet(value, c * self.d1, c * self.d2)
            return self.chain(value, c * x ** (c - 1.0), c * (c - 1.0) * x ** (c - 2.0))
        return _exp(o * _log(self))                # a varying exponent: exp(b log a)

    def __rpow__(self, o):
        return Jet.of(o) ** self

    def derivative(self) -> "Jet":
        """d/dx of the series as a series one order shorter: its value and first
        derivative are exact, its second is not known (left 0, and never read)."""
        return Jet(self.d1, self.d2, 0.0)


def _exp(u):
    e = math.exp(u.f)
    return u.chain(e, e, e)


def _log(u):
    return u.chain(math.log(u.f), 1.0 / u.f, -1.0 / u.f ** 2)


def _sqrt(u):
    r = math.sqrt(u.f)
    return u.chain(r, 0.5 / r, -0.25 / (r * u.f))


def _atan2(y, x):
    y, x = Jet.of(y), Jet.of(x)
    r2 = x * x + y * y
    rate = (x * y.derivative() - y * x.derivative()) / r2     # d atan2 / dx and its slope
    return Jet(math.atan2(y.f, x.f), rate.f, rate.d1)

# name: u -> the function of a jet u, by f(u), f'(u), f''(u) at u's value
_JETS = {
    "sin": lambda u: u.chain(math.sin(u.f), math.cos(u.f), -math.sin(u.f)),
    "cos": lambda u: u.chain(math.cos(u.f), -math.sin(u.f), -math.cos(u.f)),
    "tan": lambda u: u.chain(math.tan(u.f), 1.0 + math.tan(u.f) ** 2,
                             2.0 * math.tan(u.f) * (1.0 + math.tan(u.f) ** 2)),
    "asin": lambda u: u.chain(math.asin(u.f), 1.0 / math.sqrt(1.0 - u.f ** 2),
                              u.f / (1.0 - u.f ** 2) ** 1.5),
    "acos": lambda u: u.chain(math.acos(u.f), -1.0 / math.sqrt(1.0 - u.f ** 2),
                              -u.f / (1.0 - u.f ** 2) ** 1.5),
    "atan": lambda u: u.chain(math.atan(u.f), 1.0 / (1.0 + u.f ** 2),
                              -2.0 * u.f / (1.0 + u.f ** 2) ** 2),
    "sinh": lambda u: u.chain(math.sinh(u.f), math.cosh(u.f), math.sinh(u.f)),
    "cosh": lambda u: u.chain(math.cosh(u.f), math.sinh(u.f), math.cosh(u.f)),
    "tanh": lambda u: u.chain(math.tanh(u.f), 1.0 - math.tanh(u.f) ** 2,
                              -2.0 * math.tanh(u.f) * (1.0 - math.tanh(u.f) ** 2)),
    "exp": _exp, "log": _log, "sqrt": _sqrt,
    "abs": lambda u: u.chain(abs(u.f), math.copysign(1.0, u.f), 0.0),
    "atan2": _atan2,
    "hypot": lambda x, y: _sqrt(Jet.of(x) * x + Jet.of(y) * y),
    "radians": lambda u: u * (math.pi / 180.0),
    "degrees": lambda u: u * (180.0 / math.pi),
    "step": lambda x, x0, h0, x1, h1: _step(x, x0.f, h0.f, x1.f, h1.f),
}


def _is_constant(tree) -> bool:
    kind = tree[0]
    if kind in ("num", "const"):
        return True
    if kind == "name":
        return False
    if kind == "neg":
        return _is_constant(tree[1])
    if kind == "op":
        return _is_constant(tree[2]) and _is_constant(tree[3])
    return all(_is_constant(a) for a in tree[2:])


def _evaluate(tree, values, arrays=False):
    """The value of `tree` with its free names bound to `values`: floats (or `Jet`s, Duals
    of Parameters); with `arrays`, numpy arrays, whose numbers are numpy floats (what is
    undefined comes out NaN or ±inf, not an error) and whose functions numpy's (`_ARRAYS`)."""
    kind = tree[0]
    if kind == "num":
        return np.float64(tree[1]) if arrays else float(tree[1])
    if kind == "const":
        return np.float64(CONSTANTS[tree[1]]) if arrays else CONSTANTS[tree[1]]
    if kind == "name":
        return values[tree[1]]
    if kind == "neg":
        return -_evaluate(tree[1], values, arrays)
    if kind == "op":
        a, b = _evaluate(tree[2], values, arrays), _evaluate(tree[3], values, arrays)
        op = tree[1]
        if op == "+":
            return a + b
        if op == "-":
            return a - b
        if op == "*":
            return a * b
        if op == "/":
            return a / b
        out = a ** b
        if isinstance(out, Jet):
            return out
        if isinstance(out, complex):
            raise ValueError(f"({a:g})**({b:g}) is not real")
        return out
    args = [_evaluate(a, values, arrays) for a in tree[2:]]
    if arrays:
        return _ARRAYS[tree[1]](*args)
    if any(isinstance(a, Jet) for a in args):
        return _JETS[tree[1]](*(Jet.of(a) for a in args))
    if any(isinstance(a, dual.Dual) for a in args):
        if tree[1] not in _DUALS:
            raise ValueError(f"{tree[1]}() does not carry a Parameter's derivatives")
        return _DUALS[tree[1]](*(dual.lift(a) if tree[1] in ("atan2", "hypot") else a
                                 for a in args))
    return FUNCTIONS[tree[1]][1](*args)


def structural(tree, parent) -> bool:
    """Is the number `tree` a whole-number exponent (part of the expression's shape)?"""
    return parent is not None and parent[0] == "op" and parent[1] == "**" and \
        parent[3] is tree and float(tree[1]).is_integer()


def _constants(tree, out, parent=None) -> None:
    kind = tree[0]
    if kind == "num":
        if not structural(tree, parent):
            out.append(float(tree[1]))
    elif kind == "neg":
        _constants(tree[1], out, tree)
    elif kind == "op":
        _constants(tree[2], out, tree)
        _constants(tree[3], out, tree)
    elif kind == "call":
        for a in tree[2:]:
            _constants(a, out, tree)


def _exact_constants(tree, values, out, parent=None) -> None:
    kind = tree[0]
    if kind == "name" and tree[1] in values:
        x = values[tree[1]]
        bound = ("num", float(dual.value_of(x)))
        if not (parent is not None and parent[0] == "op" and parent[1] == "**" and
                parent[3] is tree and bound[1].is_integer()):
            out.append(x)
        elif dual.is_exact(x):
            raise ModelError(f"the Parameter bound to {tree[1]!r} is a whole-number exponent, "
                             "which shapes the law and is not differentiated")
    elif kind == "num":
        if not structural(tree, parent):
            out.append(float(tree[1]))
    elif kind == "neg":
        _exact_constants(tree[1], values, out, tree)
    elif kind == "op":
        _exact_constants(tree[2], values, out, tree)
        _exact_constants(tree[3], values, out, tree)
    elif kind == "call":
        for a in tree[2:]:
            _exact_constants(a, values, out, tree)


def _sympy(tree, symbols, sp, stand_ins=None, parent=None):
    kind = tree[0]
    if kind == "num":
        v = tree[1]
        if stand_ins is not None and not structural(tree, parent):
            return next(stand_ins)
        return sp.Integer(v) if isinstance(v, int) or float(v).is_integer() and \
            structural(tree, parent) else sp.Float(v)
    if kind == "const":
        return {"pi": sp.pi, "e": sp.E}[tree[1]]
    if kind == "name":
        return symbols[tree[1]]
    if kind == "neg":
        return -_sympy(tree[1], symbols, sp, stand_ins, tree)
    if kind == "op":
        a = _sympy(tree[2], symbols, sp, stand_ins, tree)
        b = _sympy(tree[3], symbols, sp, stand_ins, tree)
        return {"+": lambda: a + b, "-": lambda: a - b, "*": lambda: a * b,
                "/": lambda: a / b, "**": lambda: a ** b}[tree[1]]()
    args = [_sympy(a, symbols, sp, stand_ins, tree) for a in tree[2:]]
    name = tree[1]
    if name == "hypot":
        return sp.sqrt(args[0] ** 2 + args[1] ** 2)
    if name == "radians":
        return args[0] * sp.pi / 180
    if name == "degrees":
        return args[0] * 180 / sp.pi
    if name == "step":
        x, x0, h0, x1, h1 = args
        u = (x - x0) / (x1 - x0)
        return sp.Piecewise((h0, x < x0), (h0 + (h1 - h0) * u**2 * (3 - 2 * u), x < x1),
                            (h1, True))
    return getattr(sp, FUNCTIONS[name][2])(*args)


def _bind(tree, values):
    kind = tree[0]
    if kind == "name":
        return ("num", float(values[tree[1]])) if tree[1] in values else tree
    if kind in ("num", "const"):
        return tree
    if kind == "neg":
        return ("neg", _bind(tree[1], values))
    if kind == "op":
        return ("op", tree[1], _bind(tree[2], values), _bind(tree[3], values))
    return (kind, tree[1], *(_bind(a, values) for a in tree[2:]))


def _canonical(tree, template=False, parent=None) -> str:
    kind = tree[0]
    if kind == "num":
        return "#" if template and not structural(tree, parent) else repr(tree[1])
    if kind in ("const", "name"):
        return tree[1]
    if kind == "neg":
        return f"(-{_canonical(tree[1], template, tree)})"
    if kind == "op":
        return (f"({_canonical(tree[2], template, tree)} {tree[1]} "
                f"{_canonical(tree[3], template, tree)})")
    return f"{tree[1]}({', '.join(_canonical(a, template, tree) for a in tree[2:])})"
