"""A mechanism's constraint system assembled in numbers from the kernels of its joint types.

Joints of one type (kind, the kinds of the two bodies, the parameter names) share one
kernel (`mechsim.assembly.generate`), generated once per machine and cached on disk; a
model is then only tables: for each type, the rows its joints write, the columns of their
bodies' coordinates, and where their parameters sit in p. Evaluating Φ is one vectorized
kernel call per type and one scatter, so a new model of known types costs no sympy and no
compiler, however large it is, and a changed topology or geometry costs nothing.

A driver's type is its joint's: its kernel is the displacement of the joint's coordinate,
and its law f(t) with f' and f'' comes from `Expression.jet` (Φ −= f, Φ_t = −f',
γ += f''), so drivers with different laws share a kernel too.
"""

from __future__ import annotations

import json
from typing import NamedTuple

import numpy as np

from ..codegen import load_model, structure_key
from ..linalg import sparse
from ..model import Driver
from .laws import expression_laws

# Bump when the kernels' generated code changes meaning.
KERNEL_VERSION = 4          # 4: terms as text for the unrolled model; sin, cos inputs


def _side(body):
    return "ground" if not body.coordinate_names else [type(body).__name__,
                                                       list(body.coordinate_names)]


def type_key(item) -> list:
    """What a joint's, driver's or gear's kernel depends on: its kind, the kinds of its
    bodies (the ground, or a body class with its coordinates) and its parameter names; a
    gear's, its joints' keys and which of their bodies are one and the same."""
    if isinstance(item, Driver):
        return ["driver", type_key(item.joint)]
    if item.kind == "gear":
        slots = [b for j in item.joints for b in (j.body_a, j.body_b)] + item.extra_bodies
        same = [next(k for k, o in enumerate(slots) if o is b) for b in slots]
        return ["gear", item.form, type_key(item.joint_a), type_key(item.joint_b),
                [_side(b) for b in item.extra_bodies], same]
    return [item.kind, _side(item.body_a), _side(item.body_b), list(item.parameter_names),
            *([item.kernel_tag] if hasattr(item, "kernel_tag") else [])]


def kernel_items(item) -> tuple[list, list]:
    """(the moving bodies whose coordinates `item`'s kernel takes, in order; the items
    whose parameters it takes, in order: the joints a driver or gear reads, then itself)."""
    if isinstance(item, Driver):
        joints = [item.joint]
    elif item.kind == "gear":
        joints = list(item.joints)
    else:
        joints = []
    holders = joints + [item]
    bodies = []
    for b in [b for j in joints or [item] for b in (j.body_a, j.body_b)] + \
            list(getattr(item, "extra_bodies", ())):
        if b.coordinate_names and all(b is not o for o in bodies):
            bodies.append(b)
    return bodies, holders


def load_kernel(item):
    """(the kernel module of `item`'s type, whether it came from the cache)."""
    structure = {"type kernel": type_key(item), "version": KERNEL_VERSION}

    def generate() -> str:
        from .generate import kernel_source
        return kernel_source(item, structure_key(structure))
    return load_model(structure, generate)


class Placed(NamedTuple):
    """A constraint item where the system puts it: its type's key and kernel, its first
    row, the indices in q of its kernel's coordinates and in p of its kernel's
    parameters, and (a driver's) the index in p of its law's first number (else None)."""
    item: object
    key: str
    kernel: object
    row: int
    cols: list
    params: list
    law_first: int | None


def placed(bodies, items) -> tuple[list[Placed], int, int, bool]:
    """(each of `items` as `Placed`, the coordinates N, the equations M, whether every
    kernel came from the cache): the tables the assembled and the unrolled model share.
    The laws' numbers follow all the items' own parameters, in the items' order."""
    start, starts = 0, {}
    for b in bodies:
        starts[id(b)] = range(start, start + len(b.coordinate_names))
        start += len(b.coordinate_names)
    first, k = {}, 0
    for item in items:
        first[id(item)] = k
        k += len(item.parameter_names)
    kernels, cached, out, row = {}, True, [], 0
    for item in items:
        key = json.dumps(type_key(item))
        if key not in kernels:
            kernels[key], hit = load_kernel(item)
            cached &= hit
        kernel_bodies, holders = kernel_items(item)
        law_first = None
        if isinstance(item, Driver):
            law_first = k
            k += len(item.law_constants)
        out.append(Placed(item, key, kernels[key], row,
                          [c for b in kernel_bodies for c in starts[id(b)]],
                          [first[id(h)] + j for h in holders
                           for j in range(len(h.parameter_names))], law_first))
        row += kernels[key].ROWS
    return out, start, row, cached


class _Group:
    """The joints (or drivers) of one type: their kernel and index tables."""

    def __init__(self, kernel):
        self.kernel = kernel
        self.rows, self.cols, self.params = [], [], []

    def freeze(self, n: int):
        self.rows = np.array(self.rows, dtype=np.intp).reshape(-1, self.kernel.ROWS)
        self.cols = np.array(self.cols, dtype=np.intp).reshape(-1, self.kernel.COLUMNS)
        self.params = np.array(self.params, dtype=np.intp).reshape(-1, self.kernel.PARAMETERS)
        # Φ_q's entries of each joint, as flat indices into the (m, n) matrix
        self.flat = self.rows[:, :, None] * n + self.cols[:, None, :]
        # the (row, column) entries of a joint's block that can be non-zero
        self.pattern = tuple(np.array(x, dtype=np.intp).reshape(-1)
                             for x in zip(*self.kernel.PATTERN)) or (np.zeros(0, np.intp),) * 2


class AssembledModel:
    """The generated-module interface (`mechsim.codegen`: phi, phi_q, phi_t, gamma,
    position_terms, terms, dynamics_terms of (q, [v,] t, p), with `M`, `N` and the
    Jacobian's pattern) for the joints and drivers `items` acting on `bodies`, evaluated
    from type kernels. `from_cache`: every kernel was in the cache (no sympy ran)."""

    COMPILED = False
    ASSEMBLED = True
    __file__ = None

    def __init__(self, bodies, items):
        tables, self.N, self.M, self.from_cache = placed(bodies, items)
        n = self.N
        groups, law_rows, self.laws, law_first = {}, [], [], []
        for t in tables:
            if t.key not in groups:
                groups[t.key] = _Group(t.kernel)
            g = groups[t.key]
            g.rows += range(t.row, t.row + t.kernel.ROWS)
            g.cols += t.cols
            g.params += t.params
            if t.law_first is not None:
                law_rows.append(t.row)
                self.laws.append(t.item.law)
                law_first.append(t.law_first)
        self.groups = list(groups.values())
        for g in self.groups:
            g.freeze(n)
        self.law_rows = np.array(law_rows, dtype=np.intp)
        # An expression's law evaluated by its generated code (`mechsim.assembly.laws`),
        # the numbers a fused model's functions compute; a table's by its spline.
        self._expression_laws = expression_laws(self.laws, law_first)
        pattern = [(g.rows[:, i], g.cols[:, j]) for g in self.groups for i, j in g.kernel.PATTERN]
        rows = np.concatenate([r for r, _ in pattern]) if pattern else np.zeros(0, np.intp)
        cols = np.concatenate([c for _, c in pattern]) if pattern else np.zeros(0, np.intp)
        self.JACOBIAN_ROWS, self.JACOBIAN_COLS = rows.tolist(), cols.tolist()
        # CSR of that pattern: entries in row-major order, and where each group's come from
        order = np.lexsort((cols, rows))
        self._csr_indices = cols[order]
        self._csr_indptr = np.searchsorted(rows[order], np.arange(self.M + 1))
        self._csr_template = None
        where = np.empty(order.size, np.intp)
        where[order] = np.arange(order.size)
        start = 0
        for g in self.groups:
            size = g.pattern[0].size * g.rows.shape[0]
            # the CSR slots of the group's pattern entries, (entries, joints)
            g.csr = where[start:start + size].reshape(g.pattern[0].size, -1)
            start += size
        self._seen_p = self._tables = None
        self._seen_t = self._law_values = self._seen_law_p = None

    # --- inputs --------------------------------------------------------------------------
    def _p(self, p):
        """Each group's parameter table (N, np) for the parameter values `p` (kept for
        the last `p` seen: a problem passes the same tuple every call)."""
        if p is not self._seen_p:
            values = np.asarray(p, dtype=float)
            self._tables = [values[g.params] for g in self.groups]
            self._seen_p = p
        return self._tables

    def _law(self, t, p):
        """(f, f', f'') of every driver's law at t, each shape (drivers,)."""
        if t != self._seen_t or p is not self._seen_law_p:
            jets = [None] * len(self.laws)
            if self._expression_laws is not None:
                laws, which = self._expression_laws
                values = laws(t, p)
                for k, i in enumerate(which):
                    jets[i] = values[3 * k:3 * k + 3]
            jets = [law.jet("t", t) if jet is None else jet
                    for law, jet in zip(self.laws, jets)]
            self._law_values = np.array(jets, dtype=float).reshape(-1, 3).T
            self._seen_t, self._seen_law_p = t, p
        return self._law_values

    # --- the constraint system --------------------------------------------------------------
    def _evaluate(self, function, outputs, q, v, t, p):
        """The system arrays named in `outputs` ("phi", "J", "phi_t", "gamma"), from each
        group's kernel `function` (returning those of them but Φ_t, in that order; None:
        no kernel) and the drivers' laws at t; Φ_q shaped (m, n), or "Jcsr": Φ_q as a
        CSR array of the pattern (`mechsim.linalg.sparse`)."""
        size = {"J": self.M * self.N, "Jcsr": self._csr_indices.size}
        arrays = [np.zeros(size.get(name, self.M)) for name in outputs]
        filled = [(a, name) for a, name in zip(arrays, outputs) if name != "phi_t"]
        if function is not None:
            q = np.asarray(q, dtype=float)
            v = None if v is None else np.asarray(v, dtype=float)
            for g, P in zip(self.groups, self._p(p)):
                fn = getattr(g.kernel, function)
                values = fn(q[g.cols], P) if v is None else fn(q[g.cols], v[g.cols], P)
                for (a, name), value in zip(filled, values if len(filled) > 1
                                            else (values,)):
                    if name == "Jcsr":
                        a[g.csr] = value[:, g.pattern[0], g.pattern[1]].T
                    else:
                        a[g.flat if name == "J" else g.rows] = value
        if self.laws:
            law = dict(zip(("phi", "phi_t", "gamma"),
                           self._law(t, p) * [[-1.0], [-1.0], [1.0]]))
            for a, name in zip(arrays, outputs):
                if name in law:
                    a[self.law_rows] += law[name]
        return tuple(a.reshape(self.M, self.N) if name == "J" else
                     self._csr(a) if name == "Jcsr" else a for a, name in zip(arrays, outputs))

    def _evaluate_many(self, function, output, Q, ts, p):
        """`output` ("phi", "J" or "Jcsr") at the states (ts[i], Q[i]): stacked, (k, M) or
        (k, M, N), or a list of CSR arrays as `phi_q_csr` gives them; each group's kernel
        called once for all of them (its joints of every state as rows), so many states
        cost about what one does."""
        Q = np.asarray(Q, dtype=float)
        k = Q.shape[0]
        width = {"J": self.M * self.N, "Jcsr": self._csr_indices.size}.get(output, self.M)
        out = np.zeros((k, width))
        for g, P in zip(self.groups, self._p(p)):
            joints = g.rows.shape[0]
            rows = Q[:, g.cols].reshape(k * joints, -1)
            value = getattr(g.kernel, function)(rows, np.tile(P, (k, 1)))
            if output == "Jcsr":
                value = np.reshape(value, (k, joints, *value.shape[1:]))
                out[:, g.csr] = value[..., g.pattern[0], g.pattern[1]].transpose(0, 2, 1)
            else:
                target = g.flat if output == "J" else g.rows
                out[:, target] = np.reshape(value, (k, *target.shape))
        if self.laws and output == "phi":
            for i, t in enumerate(ts):
                out[i, self.law_rows] -= self._law(t, p)[0]
        if output == "Jcsr":
            return [self._csr(row) for row in out]
        return out.reshape(k, self.M, self.N) if output == "J" else out

    def phi_many(self, Q, ts, p):
        """Φ at the states (ts[i], Q[i]), (k, M), as `phi` gives each."""
        return self._evaluate_many("phi", "phi", Q, ts, p)

    def phi_q_many(self, Q, ts, p):
        """Φ_q at the states (ts[i], Q[i]), (k, M, N), as `phi_q` gives each."""
        return self._evaluate_many("jacobian", "J", Q, ts, p)

    def phi_q_csr_many(self, Q, ts, p):
        """Φ_q at the states (ts[i], Q[i]), each as `phi_q_csr` gives it."""
        return self._evaluate_many("jacobian", "Jcsr", Q, ts, p)

    def _csr(self, data):
        """Φ_q's entries `data` as a CSR array of the pattern (scipy's constructor checks
        the structure once, for the first; the others share it: `sparse.with_data`)."""
        if self._csr_template is None:
            self._csr_template = sparse.template(self._csr_indices, self._csr_indptr,
                                                 (self.M, self.N))
        return sparse.with_data(self._csr_template, data)

    def phi(self, q, t, p):
        return self._evaluate("phi", ("phi",), q, None, t, p)[0]

    def phi_q(self, q, t, p):
        return self._evaluate("jacobian", ("J",), q, None, t, p)[0]

    def phi_t(self, q, t, p):
        return self._evaluate(None, ("phi_t",), q, None, t, p)[0]

    def gamma(self, q, v, t, p):
        return self._evaluate("gamma", ("gamma",), q, v, t, p)[0]

    def position_terms(self, q, t, p):
        return self._evaluate("position", ("phi", "J"), q, None, t, p)

    def terms(self, q, v, t, p):
        return self._evaluate("terms", ("phi", "J", "phi_t", "gamma"), q, v, t, p)

    def dynamics_terms(self, q, v, t, p):
        return self._evaluate("dynamics", ("J", "gamma"), q, v, t, p)

    def phi_q_csr(self, q, t, p):
        """Φ_q as a `scipy.sparse.csr_array` of the fixed pattern (`JACOBIAN_ROWS`,
        `JACOBIAN_COLS`; structural zeros are kept, so every call has the same indices:
        `mechsim.linalg.sparse`)."""
        return self._evaluate("jacobian", ("Jcsr",), q, None, t, p)[0]

    def position_terms_csr(self, q, t, p):
        """`position_terms` with Φ_q as `phi_q_csr` gives it."""
        return self._evaluate("position", ("phi", "Jcsr"), q, None, t, p)

    def dynamics_terms_csr(self, q, v, t, p):
        """`dynamics_terms` with Φ_q as `phi_q_csr` gives it."""
        return self._evaluate("dynamics", ("Jcsr", "gamma"), q, v, t, p)
