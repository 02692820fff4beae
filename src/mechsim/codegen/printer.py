"""Write a Python module (math + numpy only) that evaluates a SymbolicSystem.

One function per group of outputs, with common subexpressions shared inside the group
(sympy.cse), vector arguments unpacked to Python floats (scalar `math` calls are several times
faster than numpy ufuncs on 0-d values), and sparse matrices filled by one fancy-index
assignment from constant index arrays.
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from .compiled import C_MIN_COORDINATES, CSR_MIN_COORDINATES


class _Printer(PythonCodePrinter):
    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "standard": "python3"})

    def _print_PeriodicSpline(self, expr):
        return spline_call(self, expr, "_pspline", "_p[{0}:{1}]")

    def _print_TableSpline(self, expr):
        return spline_call(self, expr, "_tspline", "_p, {0}")       # no copy of the table


def spline_call(printer, expr, name, source) -> str:
    """A `PeriodicSpline` as a call `name(order, φ, k, source)`, `source` formatted with
    its first parameter's index and the end of the slice."""
    order, phi, k, first = (expr.args[0], expr.args[1], int(expr.args[2]), int(expr.args[3]))
    values = source.format(first, first + 5 * k + 1)
    return f"{name}({int(order)}, {printer.doprint(phi)}, {k}, {values})"


# What a module whose equations hold a periodic spline (a driver's table) imports to
# evaluate it.
SPLINE_IMPORT = "from mechsim.model.splines import evaluate as _pspline"
TABLE_IMPORT = "from mechsim.model.splines import evaluate_table as _tspline"


def spline_c() -> str:
    """`mechsim_pspline`, the C twin of `mechsim.model.splines.evaluate` (spline.c)."""
    from importlib import resources
    return resources.files(__package__).joinpath("spline.c").read_text(encoding="utf-8")


def c_printer():
    """sympy's C99 printer with every integer beyond 2⁵³ written as a double: C reads a
    longer integer literal as an integer that overflows (and so a different number than
    Python's exact integer), a double literal as the nearest double, as Python does."""
    from sympy.printing.c import C99CodePrinter

    class Printer(C99CodePrinter):
        def _print_Integer(self, expr, **kwargs):
            p = int(expr.p)
            return str(p) if abs(p) <= 2 ** 53 else repr(float(p))

        def _print_PeriodicSpline(self, expr):
            return spline_call(self, expr, "mechsim_pspline", "&p[{0}]")

        def _print_TableSpline(self, expr):
            return spline_call(self, expr, "mechsim_tspline", "&p[{0}]")

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
    def __init__(self, system, c_kernels=(), c_replace=False):
        self.sys = system
        self.printer = _Printer()
        self.constants: dict[tuple, str] = {}
        self.functions: list[str] = []
        self.extra: list[str] = []
        # C twins of the functions named in `c_kernels` (None: all), and whether they
        # replace the Python functions on loading (`mechsim.codegen.compiled`; else only the
        # compiled partitioned engine, `mechsim.codegen.engine`, calls them).
        # c_signatures: [(name, has_v, shapes)]
        self.c_kernels, self.c_replace = c_kernels, c_replace
        self.c_functions: list[str] = []
        self.c_signatures: list[tuple] = []
        # Each expression printed once in each language (a model's functions share terms).
        self._python: dict = {}
        self._c: dict = {}

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
        if self.c_kernels is None or name in self.c_kernels:
            self._c_function(name, "_v" in args, layout, repl, reduced)
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

    def _c_function(self, name, has_v, layout, repl, reduced):
        """The C twin of one function, `mechsim_<name>` (`gamma` is taken by math.h): the same
        common subexpressions, outputs written into zeroed row-major arrays."""
        s = self.sys
        names = {x: sp.Symbol(f"q[{i}]") for i, x in enumerate(s.q)}
        names.update({x: sp.Symbol(f"v[{i}]") for i, x in enumerate(s.v)})
        names.update({x: sp.Symbol(f"p[{i}]") for i, x in enumerate(s.p)})
        pr = c_printer()
        outs = ", ".join(f"double *o{k}" for k in range(len(layout)))
        head = "const double *q, const double *v" if has_v else "const double *q"
        lines = [f"void mechsim_{name}({head}, double t, const double *p, {outs}) {{"]
        printed = self._c

        def c(expr):
            text = printed.get(expr)
            if text is None:
                text = printed[expr] = pr.doprint(expr.xreplace(names))
            return text

        for sym, expr in repl:
            lines.append(f"  const double {sym} = {c(expr)};")
        k = 0
        for idx, (rows, cols, nz) in enumerate(layout):
            for (i, j), e in zip(nz, reduced[k:k + len(nz)]):
                lines.append(f"  o{idx}[{i * cols + j}] = {c(e)};")
            k += len(nz)
        lines.append("}")
        self.c_functions.append("\n".join(lines))
        self.c_signatures.append((name, has_v, [(rows, cols) for rows, cols, _ in layout]))

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
        if any("_pspline(" in f for f in self.functions):
            header.insert(3, SPLINE_IMPORT)
        if any("_tspline(" in f for f in self.functions):
            header.insert(3, TABLE_IMPORT)
        if self.c_functions:
            spline = spline_c() + "\n" if any("mechsim_pspline(" in f or
                                              "mechsim_tspline(" in f
                                              for f in self.c_functions) else ""
            c_source = "#include <math.h>\n\n" + spline + "\n\n".join(self.c_functions) + "\n"
            constants += ["", f"C_SOURCE = {c_source!r}",
                          f"C_SIGNATURES = {self.c_signatures!r}",
                          f"C_REPLACE = {self.c_replace!r}"]
        return "\n".join(header + self.extra + constants + [""] +
                         ["\n\n".join(self.functions), ""])


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


ENGINE_KERNELS = ("phi", "phi_q", "phi_t", "gamma")


def model_source(system, key: str) -> str:
    """The full module text for `system` (see `mechsim.codegen` for the functions)."""
    large = len(system.q) >= C_MIN_COORDINATES
    w = _ModuleWriter(system, c_kernels=None if large else ENGINE_KERNELS, c_replace=large)
    s = system
    # One cse over Φ, Φ_q, Φ_t and γ; each function takes the terms of its outputs.
    shared = SharedTerms([s.phi, s.phi_q, s.phi_t, s.gamma])
    phi, phi_q, phi_t, gamma = range(4)
    w.function("phi", ("_q", "t", "_p"), shared.select([phi]),
               "Constraint residual Φ, shape (m,).")
    [nz] = w.function("phi_q", ("_q", "t", "_p"), shared.select([phi_q]),
                      "Jacobian Φ_q, shape (m, n).")
    # Where Φ_q can be non-zero at all: what a sparse factorisation of its products needs.
    w.extra += [f"JACOBIAN_ROWS = {[i for i, _ in nz]!r}",
                f"JACOBIAN_COLS = {[j for _, j in nz]!r}", ""]
    w.function("phi_t", ("_q", "t", "_p"), shared.select([phi_t]), "Φ_t, shape (m,).")
    w.function("gamma", ("_q", "_v", "t", "_p"), shared.select([gamma]),
               "γ = −(Φ_q v)_q v − 2 Φ_qt v − Φ_tt, shape (m,).")
    w.function("position_terms", ("_q", "t", "_p"), shared.select([phi, phi_q]),
               "(Φ, Φ_q) with shared terms.")
    w.function("terms", ("_q", "_v", "t", "_p"), shared.select([phi, phi_q, phi_t, gamma]),
               "(Φ, Φ_q, Φ_t, γ) with shared terms.")
    w.function("dynamics_terms", ("_q", "_v", "t", "_p"), shared.select([phi_q, gamma]),
               "(Φ_q, γ) with shared terms: what the constrained accelerations need.")
    if len(s.q) >= CSR_MIN_COORDINATES:
        # Φ_q as its non-zero entries (JACOBIAN_ROWS, JACOBIAN_COLS, row-major): a long
        # chain's solvers take it as a CSR array (`mechsim.codegen.cache.sparse_forms`),
        # where the dense (m, n) array would cost O(m n) to fill for O(m) entries.
        w.function("phi_q_nz", ("_q", "t", "_p"), shared.select([phi_q], flat=[phi_q]),
                   "Φ_q's non-zero entries in row-major order.")
        w.function("position_terms_nz", ("_q", "t", "_p"),
                   shared.select([phi, phi_q], flat=[phi_q]),
                   "(Φ, Φ_q's non-zero entries) with shared terms.")
        w.function("dynamics_terms_nz", ("_q", "_v", "t", "_p"),
                   shared.select([phi_q, gamma], flat=[phi_q]),
                   "(Φ_q's non-zero entries, γ) with shared terms.")
    return w.module(key)


def sensitivity_source(system, key: str) -> str:
    """The module text of a `mechsim.symbolic.sensitivity.SensitivitySystem`: functions
    `sensitivity_terms(_q, _v, _a, t, _p)` returning its `outputs` and
    `multiplier_terms(_q, _l, t, _p)` returning its `multiplier_outputs` (Python only:
    they run once per sample of an analysis, not inside the integration)."""
    w = _ModuleWriter(system, c_kernels=())
    w.function("sensitivity_terms", ("_q", "_v", "_a", "t", "_p"), system.outputs(),
               "(R0_p, R1_q, R1_p, R2_q, R2_v, R2_p) of the constraints at the position, "
               "velocity and acceleration levels (mechsim.symbolic.sensitivity).")
    w.function("multiplier_terms", ("_q", "_l", "t", "_p"), system.multiplier_outputs(),
               "(R3_q, R3_p) of R3 = Φ_qᵀ λ (mechsim.symbolic.sensitivity).")
    return w.module(key)
