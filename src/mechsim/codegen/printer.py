"""Printing sympy expressions as code: the text the type kernels and a mechanism's fused
model share (`neutral_printer`, `SharedTerms`), and Python modules (math + numpy only) of
free-standing kernels (a flexible beam's, a model's sensitivities: `kernel_source`,
`sensitivity_source`).

A module has one function per group of outputs, with common subexpressions shared inside
the group (sympy.cse), vector arguments unpacked to Python floats (scalar `math` calls are
several times faster than numpy ufuncs on 0-d values), and sparse matrices filled by one
fancy-index assignment from constant index arrays.
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter


class _Printer(PythonCodePrinter):
    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "standard": "python3"})


def neutral_printer(names):
    """A printer of expressions as text that Python (math, or numpy over arrays) and C
    evaluate with the same arithmetic, operation by operation: C's syntax (numbers as C
    literals, which Python reads as the same doubles; rationals as quotients of doubles),
    integer powers of magnitude 2 to 4 written as products (Python's `x**2` calls pow,
    numpy's multiplies: they round differently), x**(1/2) as sqrt, other powers as pow;
    libm's functions (`mechsim.assembly.unrolled.MATH`); π and e as `M_PI`, `M_E`. `names`: symbol -> text
    (every symbol must have one); a periodic spline is printed as
    `pspline(order, φ, k, $P<first>_<length>)`, the placeholder to be replaced by each
    language's view of the parameters from `first` on. Integers beyond 2⁵³ are written
    as doubles: C reads a longer integer literal as an integer that overflows (and so a
    different number than Python's exact integer), a double literal as the nearest
    double, as Python does."""
    from sympy.printing.c import C99CodePrinter
    from sympy.printing.precedence import PRECEDENCE

    class Printer(C99CodePrinter):
        def _print_Symbol(self, expr):
            return names[expr]

        def _print_Integer(self, expr, **kwargs):
            p = int(expr.p)
            return str(p) if abs(p) <= 2 ** 53 else repr(float(p))

        def _print_Pow(self, expr, rational=False):
            base, e = expr.args
            if e.is_Integer and 2 <= abs(int(e)) <= 4:
                product = "*".join([self.parenthesize(base, PRECEDENCE["Mul"])] * abs(int(e)))
                return f"({product})" if e > 0 else f"(1.0/({product}))"
            if e == -1:
                return f"(1.0/{self.parenthesize(base, PRECEDENCE['Mul'])})"
            if e == sp.S.Half:
                return f"sqrt({self._print(base)})"
            return f"pow({self._print(base)}, {self._print(e)})"

        def _print_PeriodicSpline(self, expr):
            order, phi, k, first = (expr.args[0], expr.args[1], int(expr.args[2]),
                                    int(expr.args[3]))
            return f"pspline({int(order)}, {self._print(phi)}, {k}, $P{first}_{5 * k + 1})"

    return Printer()


def shared_terms(outputs):
    """The non-zero entries of the matrices `outputs` with their common subexpressions
    shared (sympy.cse): (layout, one (rows, cols, non-zero (i, j) list) per output;
    replacements [(symbol, expression)]; the entries in terms of them, in layout order;
    the free symbols they use)."""
    return SharedTerms(outputs).select(range(len(outputs)))


class SharedTerms:
    """The common subexpressions of several matrices found once (one sympy.cse over all
    their non-zero entries), from which a function of any of them takes only the terms
    its own entries need: a model's functions over overlapping outputs (Φ alone, Φ with
    Φ_q, all four) then cost one cse, not one each, and share every term's arithmetic,
    so Φ from one function equals Φ from another to the last bit."""

    def __init__(self, outputs):
        self.layout, entries = [], []
        for mat in outputs:
            nz = [(i, j) for i in range(mat.rows) for j in range(mat.cols) if mat[i, j] != 0]
            self.layout.append((mat.rows, mat.cols, nz))
            entries += [mat[i, j] for i, j in nz]
        self.repl, self.reduced = sp.cse(entries, symbols=sp.numbered_symbols("_c"))
        terms = {sym for sym, _ in self.repl}
        self._needs = {sym: expr.free_symbols & terms for sym, expr in self.repl}
        self._terms = terms
        self._starts = [0]
        for _, _, nz in self.layout:
            self._starts.append(self._starts[-1] + len(nz))

    def select(self, which, flat=()):
        """(layout, replacements, entries, free symbols) of the outputs numbered `which`,
        as `shared_terms` of those outputs gives them, the replacements in cse's order.
        The outputs numbered in `flat` are given as the vector of their non-zero entries
        in row-major order (the data of a CSR array of their pattern)."""
        which = list(which)
        layout = [self.layout[k] if k not in flat else
                  (len(self.layout[k][2]), 1, [(i, 0) for i in range(len(self.layout[k][2]))])
                  for k in which]
        reduced = [e for k in which for e in self.reduced[self._starts[k]:self._starts[k + 1]]]
        needed = set().union(*(e.free_symbols & self._terms for e in reduced))
        for sym, _ in reversed(self.repl):
            if sym in needed:
                needed |= self._needs[sym]
        repl = [(sym, expr) for sym, expr in self.repl if sym in needed]
        used = set().union(*(e.free_symbols for e in reduced),
                           *(r.free_symbols for _, r in repl))
        return layout, repl, reduced, used


class _ModuleWriter:
    def __init__(self, system):
        self.sys = system
        self.printer = _Printer()
        self.constants: dict[tuple, str] = {}
        self.functions: list[str] = []
        # Each expression printed once (a module's functions share terms).
        self._python: dict = {}

    def _constant(self, values) -> str:
        values = tuple(map(int, values))
        if values not in self.constants:
            self.constants[values] = f"_I{len(self.constants)}"
        return self.constants[values]

    def _print(self, expr) -> str:
        text = self._python.get(expr)
        if text is None:
            text = self._python[expr] = self.printer.doprint(expr)
        return text

    def function(self, name: str, args: tuple[str, ...], outputs, doc: str):
        """Write one function of the matrices `outputs` (or of `SharedTerms.select`'s
        terms); returns each output's non-zero (i, j) entries."""
        sysm, pr = self.sys, self.printer
        layout, repl, reduced, used = outputs if isinstance(outputs, tuple) else \
            shared_terms(outputs)
        lines = [f"def {name}({', '.join(args)}):", f'    """{doc}"""']
        unpack = {"_q": sysm.q, "_v": sysm.v, "_a": getattr(sysm, "a", ()),
                  "_l": getattr(sysm, "l", ()), "_p": sysm.p}
        for arg in args:
            syms = unpack.get(arg)
            if syms and any(s in used for s in syms):
                targets = ", ".join(pr.doprint(s) if s in used else "_" for s in syms)
                source = "_p" if arg == "_p" else f"{arg}.tolist()"
                lines.append(f"    [{targets}] = {source}")
        for sym, expr in repl:
            lines.append(f"    {pr.doprint(sym)} = {self._print(expr)}")
        results, k = [], 0
        for idx, (rows, cols, nz) in enumerate(layout):
            vals = [self._print(e) for e in reduced[k:k + len(nz)]]
            k += len(nz)
            out = f"_o{idx}"
            is_vector = cols == 1
            shape = f"{rows}" if is_vector else f"({rows}, {cols})"
            if is_vector and len(nz) == rows and rows > 0:
                lines.append(f"    {out} = _np.array([{', '.join(vals)}], dtype=float)")
            else:
                lines.append(f"    {out} = _np.zeros({shape})")
                if nz:
                    ri = self._constant([i for i, _ in nz])
                    if is_vector:
                        lines.append(f"    {out}[{ri}] = [{', '.join(vals)}]")
                    else:
                        ci = self._constant([j for _, j in nz])
                        lines.append(f"    {out}[{ri}, {ci}] = [{', '.join(vals)}]")
            results.append(out)
        lines.append(f"    return {results[0] if len(results) == 1 else '(' + ', '.join(results) + ')'}")
        self.functions.append("\n".join(lines))
        return [nz for _, _, nz in layout]

    def module(self, key: str) -> str:
        """The module text. Nothing a user wrote appears in it: the symbols' names are
        generated identifiers (`mechsim.symbolic.constraints.identifier`), numbers are
        printed by sympy, and names are written only inside `repr` string literals."""
        s = self.sys
        header = [
            '"""Generated by mechsim. Do not edit: it is rebuilt when missing."""',
            "import math",
            "import numpy as _np",
            "",
            f"KEY = {key!r}",
            f"N = {len(s.q)}",
            f"M = {s.phi.rows}",
            f"COORDINATES = {[str(x) for x in s.q]!r}",
            f"PARAMETERS = {[str(x) for x in s.p]!r}",
            "",
        ]
        constants = [f"{name} = _np.array({list(values)!r}, dtype=_np.intp)"
                     for values, name in self.constants.items()]
        return "\n".join(header + constants + [""] + ["\n\n".join(self.functions), ""])


def kernel_source(q, v, p, functions, key: str, a=()) -> str:
    """A module of free-standing kernels over block arguments `_q`, `_v`, `_p` and `_a`
    (symbol lists `q`, `v`, `p`, `a`): `functions` is a list of (name, args, outputs, doc)
    as for `_ModuleWriter.function`. Used for the flexible-beam mass matrix and forces and
    their derivatives."""
    from types import SimpleNamespace
    w = _ModuleWriter(SimpleNamespace(q=list(q), v=list(v), p=list(p), a=list(a),
                                      phi=sp.zeros(0, 1)))
    for name, args, outputs, doc in functions:
        w.function(name, args, outputs, doc)
    return w.module(key)


def sensitivity_source(system, key: str) -> str:
    """The module text of a `mechsim.symbolic.sensitivity.SensitivitySystem`: functions
    `sensitivity_terms(_q, _v, _a, t, _p)` returning its `outputs` and
    `multiplier_terms(_q, _l, t, _p)` returning its `multiplier_outputs` (Python only:
    they run once per sample of an analysis, not inside the integration)."""
    w = _ModuleWriter(system)
    w.function("sensitivity_terms", ("_q", "_v", "_a", "t", "_p"), system.outputs(),
               "(R0_p, R1_q, R1_p, R2_q, R2_v, R2_p) of the constraints at the position, "
               "velocity and acceleration levels (mechsim.symbolic.sensitivity).")
    w.function("multiplier_terms", ("_q", "_l", "t", "_p"), system.multiplier_outputs(),
               "(R3_q, R3_p) of R3 = Φ_qᵀ λ (mechsim.symbolic.sensitivity).")
    return w.module(key)
