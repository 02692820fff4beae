"""A driver's law f(t) with f' and f'' as straight-line code, one text for Python and C.

The law's parsed tree (`mechsim.model.expressions`) is differentiated forward (value, first
and second derivative in t, each operation by its own chain rule, as `Expression.jet`
does) into assignments whose right-hand sides are text in C's syntax that Python reads
the same way: the same operations in the same order in both languages, so the assembled
model (which runs the Python) and a fused model's Python and C functions
(`mechsim.assembly.unrolled`) give every driver's Φ, Φ_t and γ to the last bit. The law's
numbers are read from the parameter vector (`$L<j>`: its j-th constant,
`Expression.constants`), so laws that differ only in them share one generated model.

Integer powers of magnitude 2 to 4 are written as products and x**(1/2) as sqrt (a C
compiler turns pow(x, 2.0) into x*x, which Python's pow does not round alike); hypot as
the square root of the sum of squares (Python's math.hypot is not libm's). This module
must not import sympy.
"""

from __future__ import annotations

import math
import re

from ..model.expressions import CONSTANTS, Expression, structural
from .unrolled import MATH

# A generated assignment's name (`_Emitter.let`: l<driver>_<k>).
_NAME_TEXT = r"l\d+_\d+"
_NAME = re.compile(rf"\b{_NAME_TEXT}\b")
# A text that is a value already: an assignment's name, t, a law's number, a literal.
_BARE = re.compile(rf"{_NAME_TEXT}|\$t|\$L\d+|\d+\.\d+")


def power(x: str, e: float) -> str:
    """x**e as text: products for whole exponents of magnitude up to 4, sqrt for 1/2."""
    if float(e).is_integer() and abs(e) <= 4:
        n = int(abs(e))
        if n == 0:
            return "1.0"
        product = "*".join([x] * n)
        return f"({product})" if e > 0 else f"(1.0/({product}))"
    if e == 0.5:
        return f"sqrt({x})"
    return f"pow({x}, {e!r})"


class _Emitter:
    """Assignments (name, Python text, C text) computing a tree's value and, where it
    depends on t, its first and second derivatives."""

    def __init__(self, prefix: str):
        self.prefix, self.lines, self.count, self.constant = prefix, [], 0, 0

    def let(self, text: str, c_text: str | None = None) -> str:
        name = f"{self.prefix}{self.count}"
        self.count += 1
        self.lines.append((name, text, text if c_text is None else c_text))
        return name

    def jet(self, f, d1, d2):
        """A jet of the texts: each a name of its own unless it is one already."""
        return tuple(x if _BARE.fullmatch(x) else self.let(x) for x in (f, d1, d2))

    def chain(self, u, g, dg, ddg):
        """g(u) for a jet u, given g, g', g'' at u's value (texts)."""
        f, d1, d2 = u
        g1, g2 = self.let(dg), self.let(ddg)
        return (self.let(g), self.let(f"{g1}*{d1}"), self.let(f"{g2}*{d1}*{d1} + {g1}*{d2}"))

    def emit(self, tree, parent=None):
        """A number's text, or a jet: (value, d1, d2) names."""
        kind = tree[0]
        if kind == "num":
            if structural(tree, parent):
                return repr(float(tree[1]))
            text = f"$L{self.constant}"
            self.constant += 1
            return text
        if kind == "const":
            return repr(CONSTANTS[tree[1]])
        if kind == "name":                  # t: the only free name of a law
            return ("$t", "1.0", "0.0")
        if kind == "neg":
            a = self.emit(tree[1], tree)
            return f"(-{a})" if isinstance(a, str) else self.jet(*(f"-{x}" for x in a))
        if kind == "op":
            return self.op(tree, self.emit(tree[2], tree), self.emit(tree[3], tree))
        args = [self.emit(a, tree) for a in tree[2:]]
        return self.call(tree[1], args)

    def op(self, tree, a, b):
        op = tree[1]
        ja, jb = not isinstance(a, str), not isinstance(b, str)
        if not ja and not jb:
            if op == "**":
                e = tree[3]
                if e[0] == "num" and structural(e, tree):
                    return self.let(power(a, float(e[1])))
                return self.let(f"pow({a}, {b})")
            return self.let(f"({a} {op} {b})")
        if op in "+-":
            if ja and jb:
                return self.jet(*(f"{x} {op} {y}" for x, y in zip(a, b)))
            if ja:
                return self.jet(f"{a[0]} {op} {b}", a[1], a[2])
            return self.jet(f"{a} {op} {b[0]}", *(f"{op}{y}" if op == "-" else y
                                                  for y in b[1:]))
        if op == "*":
            if ja and jb:
                (f, f1, f2), (g, g1, g2) = a, b
                return self.jet(f"{f}*{g}", f"{f1}*{g} + {f}*{g1}",
                                f"{f2}*{g} + 2.0*{f1}*{g1} + {f}*{g2}")
            c, (f, f1, f2) = (b, a) if ja else (a, b)
            return self.jet(f"{c}*{f}", f"{c}*{f1}", f"{c}*{f2}")
        if op == "/":
            if not jb:
                return self.jet(*(f"{x}/{b}" for x in a))
            (g, g1, g2) = b
            f, f1, f2 = a if ja else (a, "0.0", "0.0")
            q = self.let(f"{f}/{g}")
            q1 = self.let(f"({f1} - {q}*{g1})/{g}")
            q2 = self.let(f"({f2} - 2.0*{q1}*{g1} - {q}*{g2})/{g}")
            return (q, q1, q2)
        # a power
        if not jb:
            e = tree[3]
            if e[0] == "num" and structural(e, tree):
                c = float(e[1])
                return self.chain(a, power(a[0], c), f"{c!r}*{power(a[0], c - 1.0)}",
                                  f"{c * (c - 1.0)!r}*{power(a[0], c - 2.0)}")
            return self.chain(a, f"pow({a[0]}, {b})", f"{b}*pow({a[0]}, {b} - 1.0)",
                              f"{b}*({b} - 1.0)*pow({a[0]}, {b} - 2.0)")
        if not ja:                                  # c**u = exp(u log c)
            g = self.let(f"log({a})")
            return self.call("exp", [self.jet(f"{g}*{b[0]}", f"{g}*{b[1]}", f"{g}*{b[2]}")])
        return self.call("exp", [self.op(("op", "*"), b, self.call("log", [a]))])

    def call(self, name, args):
        if name == "step":
            return self.step(*args)
        if name == "hypot":
            x, y = args
            return self.call("sqrt", [self.op(("op", "+"), self.op(("op", "*"), x, x),
                                              self.op(("op", "*"), y, y))])
        if name in ("radians", "degrees"):
            factor = "(M_PI/180.0)" if name == "radians" else "(180.0/M_PI)"
            return self.op(("op", "*"), args[0], factor)
        if name == "atan2":
            y, x = args
            if isinstance(y, str) and isinstance(x, str):
                return self.let(f"atan2({y}, {x})")
            (yf, y1, y2) = y if not isinstance(y, str) else (y, "0.0", "0.0")
            (xf, x1, x2) = x if not isinstance(x, str) else (x, "0.0", "0.0")
            r2 = self.let(f"{xf}*{xf} + {yf}*{yf}")
            w = self.let(f"{xf}*{y1} - {yf}*{x1}")
            g1 = self.let(f"{w}/{r2}")
            g2 = self.let(f"({xf}*{y2} - {yf}*{x2})/{r2} - "
                          f"{g1}*2.0*({xf}*{x1} + {yf}*{y1})/{r2}")
            return (self.let(f"atan2({yf}, {xf})"), g1, g2)
        (u,) = args
        c_name = "fabs" if name == "abs" else name
        if isinstance(u, str):
            return self.let(f"{c_name}({u})")
        f = u[0]
        if name in ("sin", "cos"):
            s, c = self.let(f"sin({f})"), self.let(f"cos({f})")
            if name == "sin":
                return self.chain(u, s, c, f"-{s}")
            return self.chain(u, c, f"-{s}", f"-{c}")
        if name == "tan":
            t = self.let(f"tan({f})")
            d = self.let(f"1.0 + {t}*{t}")
            return self.chain(u, t, d, f"2.0*{t}*{d}")
        if name in ("asin", "acos"):
            r = self.let(f"1.0/sqrt(1.0 - {f}*{f})")
            sign = "" if name == "asin" else "-"
            return self.chain(u, f"{name}({f})", f"{sign}{r}", f"{sign}{f}*{r}*{r}*{r}")
        if name == "atan":
            r = self.let(f"1.0/(1.0 + {f}*{f})")
            return self.chain(u, f"atan({f})", r, f"-2.0*{f}*{r}*{r}")
        if name in ("sinh", "cosh"):
            s, c = self.let(f"sinh({f})"), self.let(f"cosh({f})")
            return self.chain(u, s, c, s) if name == "sinh" else self.chain(u, c, s, c)
        if name == "tanh":
            t = self.let(f"tanh({f})")
            d = self.let(f"1.0 - {t}*{t}")
            return self.chain(u, t, d, f"-2.0*{t}*{d}")
        if name == "exp":
            e = self.let(f"exp({f})")
            return self.chain(u, e, e, e)
        if name == "log":
            return self.chain(u, f"log({f})", f"1.0/{f}", f"-1.0/({f}*{f})")
        if name == "sqrt":
            r = self.let(f"sqrt({f})")
            return self.chain(u, r, f"0.5/{r}", f"-0.25/({r}*{f})")
        if name == "abs":
            return self.chain(u, f"fabs({f})", f"copysign(1.0, {f})", "0.0")
        raise ValueError(f"no generated code for {name}()")

    def step(self, x, x0, h0, x1, h1):
        """MSC Adams' STEP (`mechsim.model.expressions._step`): h0 below x0, h1 from x1,
        the cubic between (x0 … h1 numbers; x a number or a jet)."""
        xf = x if isinstance(x, str) else x[0]
        u = self.op(("op", "/"), self.op(("op", "-"), x, x0), self.let(f"({x1} - {x0})"))
        cubic = self.op(("op", "*"), self.op(("op", "*"), self.op(("op", "*"), self.let(
            f"({h1} - {h0})"), u), u), self.op(("op", "-"), "3.0", self.op(("op", "*"),
                                                                         "2.0", u)))
        inside = self.op(("op", "+"), h0, cubic)

        def select(low, high, mid):
            return self.let(f"({low} if {xf} < {x0} else ({high} if {xf} >= {x1} else {mid}))",
                            f"({xf} < {x0} ? {low} : ({xf} >= {x1} ? {high} : {mid}))")
        if isinstance(inside, str):
            return select(h0, h1, inside)
        return (select(h0, h1, inside[0]), select("0.0", "0.0", inside[1]),
                select("0.0", "0.0", inside[2]))


def law_code(law: Expression, prefix: str):
    """(assignments [(name, Python text, C text)], (f, f', f'') texts) of `law` at t:
    placeholders `$t` for the time, `$L<j>` for the law's j-th constant."""
    e = _Emitter(prefix)
    out = e.emit(law.tree)
    if isinstance(out, str):
        return e.lines, (out, "0.0", "0.0")
    return e.lines, out


# The names the Python text reads (a generated module defines the same).
PYTHON_NAMES = {**{name: getattr(math, name) for name in MATH},
                "M_PI": math.pi, "M_E": math.e}


class DriverLaw:
    """The code of driver number `number`'s law, its constants from `first` on in the
    parameter vector: `lines(c)` the assignments and `jet(c)` the texts of f, f', f'' in
    Python (`_p`, `t`) or C (`p`, `t`). An expression's law is `law_code`'s; a table's
    (`TableLaw.generated`) the spline's calls (`mechsim.model.splines.evaluate_table`, in
    C `mechsim_tspline`)."""

    def __init__(self, law, number: int, first: int):
        from ..model.drivers import TableLaw
        self.first = first
        if isinstance(law, Expression):
            self._lines, self._jet = law_code(law, f"l{number}_")
            self._table = None
        elif isinstance(law, TableLaw) and law.generated:
            self._lines, self._jet, self._table = [], None, law.pieces
        else:
            raise ValueError("a law given as a function or a long table has no code")

    def _fill(self, text: str, c: bool) -> str:
        vector = "p" if c else "_p"
        text = text.replace("$t", "t")
        return re.sub(r"\$L(\d+)", lambda m: f"{vector}[{self.first + int(m.group(1))}]", text)

    def lines(self, c: bool) -> list[tuple[str, str]]:
        return [(name, self._fill(c_text if c else text, c))
                for name, text, c_text in self._lines]

    def needed(self, c: bool, which) -> list[tuple[str, str]]:
        """The assignments that the jet's entries numbered `which` (0 f, 1 f', 2 f'')
        read, in order."""
        jet = self.jet(c)
        texts = [jet[k] for k in which]
        names = set().union(*(_NAME.findall(t) for t in texts)) if texts else set()
        kept = []
        for name, text in reversed(self.lines(c)):
            if name in names:
                kept.append((name, text))
                names |= set(_NAME.findall(text))
        return kept[::-1]

    def jet(self, c: bool) -> tuple[str, str, str]:
        if self._table is not None:
            k, first = self._table, self.first
            return tuple(f"mechsim_tspline({order}, t, {k}, &p[{first}])" if c else
                         f"tspline({order}, t, {k}, _p, {first})" for order in range(3))
        return tuple(self._fill(x, c) for x in self._jet)


def expression_laws(laws, first: list[int]):
    """(a Python function `(t, p) -> [f, f', f'', …]` of the expression laws among
    `laws`, their constants from `first[i]` on in p; the indices of those laws in
    `laws`), or None where there is none. The function is compiled from `DriverLaw`'s
    text (no sympy; nothing a user wrote runs: generated names, the parsed tree's
    numbers, operators and libm's functions)."""
    drivers = [(i, DriverLaw(law, i, at)) for i, (law, at) in enumerate(zip(laws, first))
               if isinstance(law, Expression)]
    if not drivers:
        return None
    body = [f"    {name} = {text}" for _, d in drivers for name, text in d.lines(False)]
    values = [x for _, d in drivers for x in d.jet(False)]
    source = "\n".join(["def laws(t, _p):", *body, f"    return [{', '.join(values)}]"])
    namespace = dict(PYTHON_NAMES)
    exec(compile(source, "<mechsim driver laws>", "exec"), namespace)
    return namespace["laws"], [i for i, _ in drivers]
