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

from ..codegen.printer import SharedTerms, neutral_printer
from ..model import Driver
from ..symbolic import SymbolicContext, jacobian_of, second_derivative_along
from .unrolled import MATH, fill, placeholders


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
    pattern = [(i, j) for i in range(J.rows) for j in range(J.cols) if J[i, j] != 0]
    # sin and cos of a coordinate are inputs of the terms: a mechanism's unrolled model
    # (`mechsim.assembly.unrolled`) takes each body's once for all its joints.
    trig = {}
    for k, x in enumerate(ctx.q):
        trig[sp.sin(x)] = sp.Symbol(f"_s{k}", real=True)
        trig[sp.cos(x)] = sp.Symbol(f"_o{k}", real=True)
    shared = SharedTerms([m.xreplace(trig) for m in (phi, J, gamma)])
    names = {x: f"$q{k}" for k, x in enumerate(ctx.q)}
    names.update({x: f"$v{k}" for k, x in enumerate(ctx.v)})
    names.update({x: f"$p{k}" for k, x in enumerate(ctx.p)})
    names.update({sym: f"${sym.name[1]}{sym.name[2:]}" for sym in trig.values()})
    number = {sym: k for k, (sym, _) in enumerate(shared.repl)}     # a term's place
    names.update({sym: f"$c{k}" for sym, k in number.items()})
    printer = neutral_printer(names)
    terms = [printer.doprint(expr) for _, expr in shared.repl]
    entries, needs = [], []
    for k, (_, _, nz) in enumerate(shared.layout):
        _, repl, reduced, _ = shared.select([k])
        entries.append([(i, j, printer.doprint(e)) for (i, j), e in zip(nz, reduced)])
        needs.append([number[sym] for sym, _ in repl])
    writer = _Writer(terms, entries, needs, [(phi.rows,), (J.rows, J.cols), (gamma.rows,)])
    writer.function("phi", ("Q", "P"), [0])
    writer.function("jacobian", ("Q", "P"), [1])
    writer.function("position", ("Q", "P"), [0, 1])
    writer.function("gamma", ("Q", "V", "P"), [2])
    writer.function("terms", ("Q", "V", "P"), [0, 1, 2])
    writer.function("dynamics", ("Q", "V", "P"), [1, 2])
    header = ['"""A mechsim type kernel. Generated: rebuilt when missing."""',
              "import math", "import numpy",
              "from mechsim.assembly.unrolled import NUMPY_MATH",
              "from mechsim.model.splines import evaluate as pspline", "",
              f"KEY = {key!r}", f"ROWS = {phi.rows}", f"COLUMNS = {len(ctx.q)}",
              f"PARAMETERS = {len(ctx.p)}", f"PATTERN = {pattern!r}",
              "# The terms and entries as text with placeholders ($q, $v, $p: the kernel's",
              "# columns; $s, $o: sin, cos of a coordinate; $c: a term), for",
              "# `mechsim.assembly.unrolled`; NEEDS: the terms each of Φ, Φ_q, γ reads.",
              f"TERMS = {terms!r}", f"ENTRIES = {entries!r}", f"NEEDS = {needs!r}",
              f"{', '.join(MATH)} = ({', '.join(f'NUMPY_MATH[{n!r}]' for n in MATH)})",
              "M_PI, M_E = math.pi, math.e", ""]
    return "\n".join(header + ["\n\n".join(writer.functions), ""])


def _numpy_name(kind, index, length):
    if kind == "P":                           # a spline's parameters, one row per joint
        return f"P[:, {index}:{index + length}].T"
    return f"{kind}{index}"


class _Writer:
    """Prints the kernel's numpy functions from its templates: each placeholder a local
    name (a column of Q, V or P, a coordinate's sine or cosine, a term)."""

    def __init__(self, terms, entries, needs, shapes):
        self.terms, self.entries, self.needs, self.shapes = terms, entries, needs, shapes
        self.functions: list[str] = []

    def function(self, name: str, args: tuple[str, ...], outputs):
        needed = sorted(set().union(*(self.needs[k] for k in outputs)))
        texts = [self.terms[c] for c in needed] + \
            [e for k in outputs for _, _, e in self.entries[k]]
        used = set().union(*(placeholders(t) for t in texts))
        lines = [f"def {name}({', '.join(args)}):", "    n = len(Q)"]
        columns = {"q": "Q", "v": "V", "p": "P"}
        trig = sorted((int(u[1:]), u[0]) for u in used if u[0] in "so")
        inputs = sorted({(u[0], int(u[1:])) for u in used if u[0] in "qvp"} |
                        {("q", k) for k, _ in trig}, key=lambda x: ("qvp".index(x[0]), x[1]))
        lines += [f"    {kind}{k} = {columns[kind]}[:, {k}]" for kind, k in inputs]
        lines += [f"    {kind}{k} = {'sin' if kind == 's' else 'cos'}(q{k})"
                  for k, kind in trig]
        lines += [f"    c{c} = {fill(self.terms[c], _numpy_name)}" for c in needed]
        names = []
        for idx, k in enumerate(outputs):
            out = f"_o{idx}"
            vector = k != 1
            lines.append(f"    {out} = numpy.zeros((n, {', '.join(map(str, self.shapes[k]))}))")
            for i, j, e in self.entries[k]:
                lines.append(f"    {out}[:, {i}{'' if vector else f', {j}'}] = "
                             f"{fill(e, _numpy_name)}")
            names.append(out)
        lines.append(f"    return {names[0] if len(names) == 1 else ', '.join(names)}")
        self.functions.append("\n".join(lines))
