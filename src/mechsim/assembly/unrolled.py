"""A mechanism's fused model written from its joint types' kernels: the assembled model's
arithmetic, unrolled.

A type kernel (`mechsim.assembly.generate`) carries, besides its numpy functions, its terms
and entries as text with placeholders for the joint's coordinates, velocities, parameters,
its coordinates' sines and cosines, and its own terms. This module writes one Python module
for a whole mechanism from those texts, each joint's with its own coordinates and
parameters, each body's sine and cosine taken once, with the C twins of its functions
(`mechsim.codegen.compiled`, `mechsim.codegen.engine`). So a mechanism's fused model

- costs no sympy (only its joint types' kernels, cached per machine), and
- computes every number of Φ, Φ_q, Φ_t and γ with the very operations the assembled model
  does, in the same order: the text is one for numpy, Python and C (`neutral_printer`:
  C's syntax, integer powers as products, the functions of libm, which numpy's sin, cos,
  sqrt and fabs match and for the others numpy's kernels map libm's over the values).
  A mechanism's runs then give the same numbers to the last bit whichever build serves
  them (tests).

A driver's law enters its row as the assembled model adds it, from the same generated
code (`mechsim.assembly.laws`). This module must not import sympy.
"""

from __future__ import annotations

import math
import re

import numpy as np


def _libm(function):
    """`function` (a math module function: libm's) mapped over numpy arrays."""
    def mapped(*args):
        arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in args))
        values = [function(*x) for x in zip(*(a.ravel().tolist() for a in arrays))]
        return np.array(values, dtype=float).reshape(arrays[0].shape)
    return mapped


# The functions generated text calls besides + − * / (`codegen.printer.neutral_printer`,
# `assembly.laws`): libm's, which Python's math module and C call alike.
MATH = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp",
        "log", "sqrt", "fabs", "pow", "copysign")
# The same over numpy arrays (a type kernel's): numpy's own where they round as libm's
# (sin, cos, sqrt, fabs), libm's mapped elsewhere (numpy's tan, atan2, pow, exp, log …
# differ from libm's in the last bit).
NUMPY_MATH = {name: getattr(np, name) if name in ("sin", "cos", "sqrt", "fabs")
              else _libm(getattr(math, name)) for name in MATH}


_PLACEHOLDER = re.compile(r"\$([qvpsocP])(\d+)(?:_(\d+))?")


def placeholders(text: str) -> set:
    """The placeholders ("q3", "c12", …) a template text holds."""
    return {m.group(1) + m.group(2) for m in _PLACEHOLDER.finditer(text)}


def fill(text: str, name) -> str:
    """`text` with each placeholder replaced by `name(kind, index, length)` (length: a
    parameter slice's, else None)."""
    return _PLACEHOLDER.sub(lambda m: name(m.group(1), int(m.group(2)),
                                           None if m.group(3) is None else int(m.group(3))),
                            text)


class _Joint:
    """One constraint item as its kernel sees it: the kernel, its first row, and the
    global indices of its coordinates and parameters."""

    def __init__(self, number, kernel, row, cols, params):
        self.number, self.kernel, self.row = number, kernel, row
        self.cols, self.params = cols, params

    def name(self, c_language: bool):
        """The placeholder namer of this joint in Python (scalars) or C."""
        cols, params, k = self.cols, self.params, self.number

        def python(kind, index, length):
            if kind == "q":
                return f"q{cols[index]}"
            if kind == "v":
                return f"v{cols[index]}"
            if kind == "p":
                return f"p{params[index]}"
            if kind in "so":
                return f"{kind}{cols[index]}"
            if kind == "c":
                return f"c{k}_{index}"
            return f"_p[{params[index]}:{params[index] + length}]"       # a spline's

        def c(kind, index, length):
            if kind in "qvp":
                return f"{kind}[{(params if kind == 'p' else cols)[index]}]"
            if kind == "P":
                return f"&p[{params[index]}]"
            return python(kind, index, length)
        return c if c_language else python


def joints(bodies, items):
    """(the items as `_Joint`s, N, M, each driver's row -> its `DriverLaw`), from the
    assembled model's tables (`mechsim.assembly.model.placed`)."""
    from .laws import DriverLaw
    from .model import placed
    tables, n, m, _ = placed(bodies, items)
    laws = {t.row: DriverLaw(t.item.law, number, t.law_first)
            for number, t in enumerate(tables) if t.law_first is not None}
    return [_Joint(number, t.kernel, t.row, t.cols, t.params)
            for number, t in enumerate(tables)], n, m, laws


# The outputs of each function: 0 Φ, 1 Φ_q (dense), 2 γ, 3 Φ_t, 4 Φ_q's non-zero entries.
_FUNCTIONS = [
    ("phi", False, [0], "Constraint residual Φ, shape (m,)."),
    ("phi_q", False, [1], "Jacobian Φ_q, shape (m, n)."),
    ("phi_t", False, [3], "Φ_t, shape (m,)."),
    ("gamma", True, [2], "γ = −(Φ_q v)_q v − 2 Φ_qt v − Φ_tt, shape (m,)."),
    ("position_terms", False, [0, 1], "(Φ, Φ_q)."),
    ("terms", True, [0, 1, 3, 2], "(Φ, Φ_q, Φ_t, γ)."),
    ("dynamics_terms", True, [1, 2], "(Φ_q, γ): what the constrained accelerations need."),
]
_SPARSE = [
    ("phi_q_nz", False, [4], "Φ_q's non-zero entries in row-major order."),
    ("position_terms_nz", False, [0, 4], "(Φ, Φ_q's non-zero entries)."),
    ("dynamics_terms_nz", True, [4, 2], "(Φ_q's non-zero entries, γ)."),
]
# Which of a kernel's outputs (0 Φ, 1 Φ_q, 2 γ) each function output reads.
_KERNEL_OUTPUT = {0: 0, 1: 1, 2: 2, 3: None, 4: 1}
# The C twins the compiled engine calls (`mechsim.codegen.engine`) for a small model: the
# pairs evaluated at one state share their sines and cosines and common terms, and give
# each output to the bit as its own function does.
ENGINE_FUNCTIONS = ("phi", "phi_q", "phi_t", "gamma", "position_terms", "dynamics_terms")


class _Writer:
    def __init__(self, items, n, m, laws):
        self.items, self.n, self.m, self.laws = items, n, m, laws
        entries = [(j.row + i, j.cols[c], j, e) for j in items
                   for i, c, e in j.kernel.ENTRIES[1]]
        entries.sort(key=lambda x: (x[0], x[1]))
        self.jacobian = entries                   # row-major: the CSR order
        self.constants: dict[tuple, str] = {}

    def _constant(self, values) -> str:
        values = tuple(map(int, values))
        if values not in self.constants:
            self.constants[values] = f"_I{len(self.constants)}"
        return self.constants[values]

    def _entries(self, output, c_language):
        """[(global row, global column or None, text)] of an output. A driver's row adds
        its law as the assembled model does: Φ −= f, Φ_t = 0 − f', γ += f''."""
        if output in (1, 4):
            return [(r, col, fill(e, j.name(c_language))) for r, col, j, e in self.jacobian]
        rows = {} if output == 3 else {j.row + i: fill(e, j.name(c_language))
                                       for j in self.items
                                       for i, _, e in j.kernel.ENTRIES[output]}
        for row, law in self.laws.items():
            f, f1, f2 = law.jet(c_language)
            if output == 0:
                rows[row] = f"({rows.get(row, '0.0')}) + (-({f}))"
            elif output == 3:
                rows[row] = f"0.0 + (-({f1}))"
            else:
                rows[row] = f"({rows.get(row, '0.0')}) + ({f2})"
        return [(r, None, rows[r]) for r in sorted(rows)]

    def _body(self, outputs, c_language):
        """(input names used: {"q": cols, "v": cols, "p": params, "s"/"o": cols},
        the statements computing the terms in order)."""
        lines, used = [], {"q": set(), "v": set(), "p": set(), "s": set(), "o": set()}
        for j in self.items:
            kernel_outputs = {_KERNEL_OUTPUT[k] for k in outputs} - {None}
            needed = sorted(set().union(*(j.kernel.NEEDS[k] for k in kernel_outputs)))
            texts = [j.kernel.TERMS[c] for c in needed] + \
                [e for k in kernel_outputs for _, _, e in j.kernel.ENTRIES[k]]
            for u in set().union(*(placeholders(t) for t in texts)):
                kind, index = u[0], int(u[1:])
                if kind in "qvso":
                    used[kind].add(j.cols[index])
                elif kind == "p":
                    used["p"].add(j.params[index])
            name = j.name(c_language)
            for c in needed:
                text = fill(j.kernel.TERMS[c], name)
                lines.append(f"const double c{j.number}_{c} = {text};" if c_language else
                             f"c{j.number}_{c} = {text}")
        wanted = [k for k, output in enumerate((0, 3, 2)) if output in outputs]  # f, f', f''
        for law in self.laws.values():
            lines += [f"const double {x} = {text};" if c_language else f"{x} = {text}"
                      for x, text in law.needed(c_language, wanted)]
        used["q"] |= used["s"] | used["o"]
        return used, lines

    def python(self, name, has_v, outputs, doc) -> str:
        used, body = self._body(outputs, False)
        args = ["_q"] + (["_v"] if has_v else []) + ["t", "_p"]
        lines = [f"def {name}({', '.join(args)}):", f'    """{doc}"""']
        for kind, size, source in (("q", self.n, "_q.tolist()"), ("v", self.n, "_v.tolist()")):
            if used[kind] and (kind == "q" or has_v):
                targets = ", ".join(f"{kind}{i}" if i in used[kind] else "_"
                                    for i in range(size))
                lines.append(f"    [{targets}] = {source}")
        if used["p"]:
            size = max(used["p"]) + 1
            targets = ", ".join(f"p{i}" if i in used["p"] else "_" for i in range(size))
            lines.append(f"    [{targets}] = _p[:{size}]")
        lines += [f"    s{i} = sin(q{i})" for i in sorted(used["s"])]
        lines += [f"    o{i} = cos(q{i})" for i in sorted(used["o"])]
        lines += [f"    {line}" for line in body]
        results = []
        for idx, k in enumerate(outputs):
            out = f"_o{idx}"
            entries = self._entries(k, False)
            values = [e for _, _, e in entries]
            if k == 1:
                lines.append(f"    {out} = _np.zeros(({self.m}, {self.n}))")
                if entries:
                    rows = self._constant([r for r, _, _ in entries])
                    cols = self._constant([c for _, c, _ in entries])
                    lines.append(f"    {out}[{rows}, {cols}] = [{', '.join(values)}]")
            elif k == 4 or (entries and len(entries) == self.m):
                lines.append(f"    {out} = _np.array([{', '.join(values)}], dtype=float)")
            else:
                lines.append(f"    {out} = _np.zeros({self.m})")
                if entries:
                    rows = self._constant([r for r, _, _ in entries])
                    lines.append(f"    {out}[{rows}] = [{', '.join(values)}]")
            results.append(out)
        lines.append(f"    return {results[0] if len(results) == 1 else ', '.join(results)}")
        return "\n".join(lines)

    def c(self, name, has_v, outputs) -> tuple[str, list]:
        """The C twin `mechsim_<name>` (outputs written into zeroed row-major arrays) and
        its output shapes."""
        used, body = self._body(outputs, True)
        head = "const double *q, const double *v" if has_v else "const double *q"
        outs = ", ".join(f"double *out{k}" for k in range(len(outputs)))
        lines = [f"void mechsim_{name}({head}, double t, const double *p, {outs}) {{"]
        lines += [f"  const double s{i} = sin(q[{i}]);" for i in sorted(used["s"])]
        lines += [f"  const double o{i} = cos(q[{i}]);" for i in sorted(used["o"])]
        lines += [f"  {line}" for line in body]
        shapes = []
        for idx, k in enumerate(outputs):
            entries = self._entries(k, True)
            for at, (r, c, e) in enumerate(entries):
                slot = at if k == 4 else r * self.n + c if k == 1 else r
                lines.append(f"  out{idx}[{slot}] = {e};")
            shapes.append((len(entries), 1) if k == 4 else (self.m, self.n) if k == 1
                          else (self.m, 1))
        lines.append("}")
        text = "\n".join(lines)
        return re.sub(r"\bpspline\(", "mechsim_pspline(", text), shapes


def unrolled_source(bodies, items, key: str) -> str:
    """The fused module's text for the constraint `items` on `bodies`, from their types'
    kernels (generated by sympy where one is not cached) and their drivers' laws (none
    given as a function or a long table: those run assembled)."""
    from ..codegen.compiled import C_MIN_COORDINATES, CSR_MIN_COORDINATES, spline_c
    joint_list, n, m, laws = joints(bodies, items)
    w = _Writer(joint_list, n, m, laws)
    large = n >= C_MIN_COORDINATES
    functions = _FUNCTIONS + (_SPARSE if n >= CSR_MIN_COORDINATES else [])
    python = [w.python(*f) for f in functions]
    c_functions, signatures = [], []
    for name, has_v, outputs, _ in functions:
        if large or name in ENGINE_FUNCTIONS:
            text, shapes = w.c(name, has_v, outputs)
            c_functions.append(text)
            signatures.append((name, has_v, shapes))
    splines = any("mechsim_pspline(" in f or "mechsim_tspline(" in f for f in c_functions)
    c_source = "#include <math.h>\n\n" + (spline_c() + "\n" if splines else "") + \
        "\n\n".join(c_functions) + "\n"
    header = [
        '"""Generated by mechsim from its joint types\' kernels. Do not edit: it is rebuilt '
        'when missing."""',
        "import math",
        "import numpy as _np",
        "from mechsim.model.splines import evaluate as pspline, evaluate_table as tspline",
        "",
        f"from math import {', '.join(MATH)}",
        "M_PI, M_E = math.pi, math.e",
        "",
        f"KEY = {key!r}",
        f"N = {n}",
        f"M = {m}",
        f"JACOBIAN_ROWS = {[r for r, _, _, _ in w.jacobian]!r}",
        f"JACOBIAN_COLS = {[c for _, c, _, _ in w.jacobian]!r}",
    ]
    constants = [f"{name} = _np.array({list(values)!r}, dtype=_np.intp)"
                 for values, name in w.constants.items()]
    constants += [f"C_SOURCE = {c_source!r}", f"C_SIGNATURES = {signatures!r}",
                  f"C_REPLACE = {large!r}"]
    return "\n".join(header + constants + [""] + ["\n\n".join(python), ""])
