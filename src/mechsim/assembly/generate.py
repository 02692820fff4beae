"""The source of one type kernel: a joint kind's equations between two kinds of bodies,
differentiated by sympy once and printed as numpy code vectorized over every joint of the
type. Imported only when a type's kernel is not in the cache (it imports sympy).

A kernel's functions take the stacked coordinates `Q` (N, nq) of the N joints' bodies
(body_a's then body_b's; the ground has none), their velocities `V` and parameters `P`
(N, np), and return

    phi(Q, P)          -> Φ (N, r)
    jacobian(Q, P)     -> Φ_q (N, r, nq)
    position(Q, P)     -> (Φ, Φ_q)
    gamma(Q, V, P)     -> −(Φ_q v)_q v (N, r)
    terms(Q, V, P)     -> (Φ, Φ_q, −(Φ_q v)_q v)
    dynamics(Q, V, P)  -> (Φ_q, −(Φ_q v)_q v)

with `PATTERN`, the (row, column) entries of Φ_q that can be non-zero. Joints do not depend
on time; a driver's kernel is its `Driver.displacement`, and its law enters numerically
(`mechsim.assembly.model`).
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.numpy import NumPyPrinter

from ..codegen.printer import SPLINE_IMPORT, SharedTerms, spline_call
from ..model import Driver
from ..symbolic import SymbolicContext, jacobian_of, second_derivative_along


def kernel_source(item, key: str) -> str:
    """The module text of the kernel of `item`'s type (any joint, driver or gear of it
    serves)."""
    from .model import kernel_items
    bodies, holders = kernel_items(item)
    ctx = SymbolicContext(bodies, holders,
                          laws=False)      # a driver's law is evaluated by the model itself
    p = ctx.parameters(item)
    rows = [item.displacement(ctx, p)] if isinstance(item, Driver) else item.equations(ctx, p)
    q, v = sp.Matrix(ctx.q), sp.Matrix(ctx.v)
    phi = sp.Matrix(rows)
    J = jacobian_of(phi, q)
    gamma = -second_derivative_along(phi, q, v, jacobian=J)
    writer = _Writer(ctx)
    shared = SharedTerms([phi, J, gamma])       # one cse; each function takes its terms
    writer.function("phi", ("Q", "P"), shared.select([0]))
    writer.function("jacobian", ("Q", "P"), shared.select([1]))
    writer.function("position", ("Q", "P"), shared.select([0, 1]))
    writer.function("gamma", ("Q", "V", "P"), shared.select([2]))
    writer.function("terms", ("Q", "V", "P"), shared.select([0, 1, 2]))
    writer.function("dynamics", ("Q", "V", "P"), shared.select([1, 2]))
    pattern = [(i, j) for i in range(J.rows) for j in range(J.cols) if J[i, j] != 0]
    imports = ["import numpy"] + ([SPLINE_IMPORT] if any("_pspline(" in f for f in
                                                         writer.functions) else [])
    header = ['"""A mechsim type kernel. Generated: rebuilt when missing."""', *imports, "",
              f"KEY = {key!r}", f"ROWS = {phi.rows}", f"COLUMNS = {len(ctx.q)}",
              f"PARAMETERS = {len(ctx.p)}", f"PATTERN = {pattern!r}", ""]
    return "\n".join(header + ["\n\n".join(writer.functions), ""])


class _KernelPrinter(NumPyPrinter):
    def _print_PeriodicSpline(self, expr):
        return spline_call(self, expr, "_pspline", "P[:, {0}:{1}].T")


class _Writer:
    """Prints functions of the kernel's matrices with their common subexpressions shared;
    a symbol is a column of Q, V or P (symbol names are generated, never the user's)."""

    def __init__(self, ctx):
        self.columns = {"Q": list(ctx.q), "V": list(ctx.v), "P": list(ctx.p)}
        self.printer = _KernelPrinter({"fully_qualified_modules": True})
        self.functions: list[str] = []
        self._printed: dict = {}            # each expression printed once

    def _print(self, expr) -> str:
        text = self._printed.get(expr)
        if text is None:
            text = self._printed[expr] = self.printer.doprint(expr)
        return text

    def function(self, name: str, args: tuple[str, ...], terms: tuple):
        """One function of `SharedTerms.select`'s `terms`."""
        pr = self.printer
        layout, repl, reduced, used = terms
        lines = [f"def {name}({', '.join(args)}):", "    n = len(Q)"]
        for arg in args:
            for k, sym in enumerate(self.columns[arg]):
                if sym in used:
                    lines.append(f"    {pr.doprint(sym)} = {arg}[:, {k}]")
        lines += [f"    {pr.doprint(sym)} = {self._print(expr)}" for sym, expr in repl]
        names, k = [], 0
        for idx, (rows, cols, nz) in enumerate(layout):
            out = f"_o{idx}"
            vector = cols == 1
            shape = f"(n, {rows})" if vector else f"(n, {rows}, {cols})"
            lines.append(f"    {out} = numpy.zeros({shape})")
            for (i, j), e in zip(nz, reduced[k:k + len(nz)]):
                lines.append(f"    {out}[:, {i}{'' if vector else f', {j}'}] = {self._print(e)}")
            k += len(nz)
            names.append(out)
        lines.append(f"    return {names[0] if len(names) == 1 else ', '.join(names)}")
        self.functions.append("\n".join(lines))
