"""Φ(q, t; p) from the joints and drivers of a mechanism, and Φ_q, Φ_t, γ derived from it.

Only Φ is stored; the derivatives are computed on first use and cached (sympy's
`KanesMethod` keeps its intermediate matrices the same way).

    γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt        (acceleration right-hand side, Φ_q q̈ = γ)
"""

from __future__ import annotations

from functools import cached_property

import sympy as sp

from ..model.context import JointContext


class PeriodicSpline(sp.Function):
    """The `order`-th derivative of a periodic cubic spline at φ: PeriodicSpline(order, φ,
    k, first), its 5k + 1 knots and coefficients (`mechsim.model.splines`) the entries of
    the parameter vector from index `first` on (a number, not the symbols: a derivative
    in q looks at four arguments, and the generated code reads them as one slice).
    Printed as a call of `mechsim.model.splines.evaluate` in Python and of
    `mechsim_pspline` (codegen/spline.c) in C; its derivative in φ is the next order."""

    is_real = True

    def fdiff(self, argindex=2):
        if argindex != 2:
            raise sp.ArgumentIndexError(self, argindex)
        order, phi, k, first = self.args
        return PeriodicSpline(order + 1, phi, k, first)


class TableSpline(PeriodicSpline):
    """The `order`-th derivative of a driver's table at t: TableSpline(order, t, k, first),
    the (not periodic) cubic spline of k pieces whose knots and coefficients are the
    parameters from index `first` on (`mechsim.model.splines.evaluate_table`; in C
    `mechsim_tspline`); its derivative in t is the next order."""

    def fdiff(self, argindex=2):
        if argindex != 2:
            raise sp.ArgumentIndexError(self, argindex)
        order, t, k, first = self.args
        return TableSpline(order + 1, t, k, first)


class SymbolicContext(JointContext):
    """What a joint sees while writing its equations: the symbols of the bodies' frames and
    the parameter symbols of every constraint item.

    Symbols are named by position, never by the user's names (`b<i>_<coordinate>` for the
    i-th body, `c<k>_<parameter>` for the k-th joint or driver): nothing a user wrote
    reaches generated code, and models that differ only in names share one cache entry.
    With `laws`, the numbers of each driver's law are parameters too (`c<k>_law<j>`, after
    all the others: `Driver.law_constants`)."""

    def __init__(self, bodies, items, laws: bool = True):
        self.t = sp.Symbol("t", real=True)
        self.q: list[sp.Symbol] = []
        self.v: list[sp.Symbol] = []
        self._frames = {}
        for i, body in enumerate(bodies):
            stem = f"b{i}"
            syms = [sp.Symbol(f"{stem}_{c}", real=True) for c in body.coordinate_names]
            self.q += syms
            self.v += [sp.Symbol(f"{stem}_{c}_dot", real=True) for c in body.coordinate_names]
            self._frames[id(body)] = syms
        self.p: list[sp.Symbol] = []
        self._params = {}
        for k, item in enumerate(items):
            stem = f"c{k}"
            syms = {n: sp.Symbol(f"{stem}_{n}", real=True) for n in item.parameter_names}
            self.p += list(syms.values())
            self._params[id(item)] = syms
        # The numbers of the drivers' laws come after every item's own parameters (the
        # assembled model, which evaluates laws itself, reads only those before them).
        self._laws = {}
        for k, item in enumerate(items):
            syms = [sp.Symbol(f"c{k}_law{j}", real=True)
                    for j in range(len(getattr(item, "law_constants", ())) if laws else 0)]
            self.p += syms
            self._laws[id(item)] = syms

    def frame(self, body):
        """(x, y, angle) of the body's frame; zeros for the ground."""
        return self._frames.get(id(body), (sp.S.Zero, sp.S.Zero, sp.S.Zero))[:3]

    def modal(self, body):
        """The modal amplitudes η of a flexible body (empty for rigid bodies)."""
        return self._frames.get(id(body), ())[3:]

    cos, sin, atan2 = staticmethod(sp.cos), staticmethod(sp.sin), staticmethod(sp.atan2)
    sqrt = staticmethod(sp.sqrt)

    def curve(self, law, phi, parameters=()):
        """A curve's r(φ) at the angle φ, as sympy: an `Expression` in phi, or a periodic
        spline (`mechsim.model.splines`) whose knots and coefficients are `parameters`
        (symbols of this context's parameter vector, in order)."""
        if hasattr(law, "coefficients"):
            return PeriodicSpline(0, phi, law.k, self.p.index(parameters[0]))
        return law.to_sympy({"phi": phi})

    def table(self, pieces: int, t, parameters):
        """A driver's table f(t) as sympy: the spline of `pieces` cubic pieces whose knots
        and coefficients are `parameters` (symbols of this context's parameter vector, in
        order: `TableLaw.constants`)."""
        return TableSpline(0, t, pieces, self.p.index(parameters[0]))

    def parameters(self, item) -> dict:
        return self._params[id(item)]

    def law_constants(self, item) -> list:
        """The symbols of a driver's law's numbers (`Driver.law_constants`)."""
        return self._laws[id(item)]


class SymbolicSystem:
    """Φ and its derivatives for one mechanism structure.

    Attributes: `q`, `v` (coordinate and velocity symbols, n each), `t`, `p` (parameter
    symbols), `phi` (m × 1). Derived on first access: `phi_q` (m × n), `phi_t`, `gamma`.
    """

    def __init__(self, ctx: SymbolicContext, phi: list):
        self.ctx = ctx
        self.q, self.v, self.t, self.p = ctx.q, ctx.v, ctx.t, ctx.p
        self.phi = sp.Matrix(phi) if phi else sp.zeros(0, 1)

    @cached_property
    def phi_q(self) -> sp.Matrix:
        return jacobian_of(self.phi, self.q)

    @cached_property
    def phi_t(self) -> sp.Matrix:
        return self.phi.diff(self.t)

    @cached_property
    def gamma(self) -> sp.Matrix:
        return -second_derivative_along(self.phi, self.q, self.v, self.t, self.phi_q)


def jacobian_of(phi: sp.Matrix, q) -> sp.Matrix:
    """Φ_q, row by row: a row built of rotations (`second_derivative_along` says which) by
    sympy's derivative in each coordinate, any other by reverse accumulation through its
    shared terms (`_gradient`), whose result is smaller there and found faster
    (docs/benchmarks.md has the measurements)."""
    q = list(q)
    if not q:
        return sp.zeros(phi.rows, 0)
    return sp.Matrix([[row.diff(x) for x in q] if _of_rotations(row) else _gradient(row, q)
                      for row in phi]) if phi.rows else sp.zeros(0, len(q))


def _gradient(expr, xs) -> list:
    """[∂expr/∂x for x in xs] by reverse accumulation through the shared terms of `expr`
    (sympy.cse): each term's partial derivatives in its own arguments, weighted by the
    term's adjoint (a symbol, complete once every term using it is done: the terms are
    visited last to first), the chain put back together at the end."""
    terms, (reduced,) = sp.cse([expr], symbols=sp.numbered_symbols(cls=sp.Dummy))
    wanted = set(xs) | {x for x, _ in terms}
    adjoint, chain = {}, []

    def spread(e, weight):
        for u in sorted(e.free_symbols & wanted, key=sp.default_sort_key):
            d = e.diff(u)
            if d != 0:
                adjoint[u] = adjoint.get(u, sp.Integer(0)) + weight * d

    spread(reduced, sp.Integer(1))
    for x, e in reversed(terms):
        if x in adjoint:
            weight = sp.Dummy()
            chain.append((weight, adjoint.pop(x)))
            spread(e, weight)
    whole = {}
    for x, e in terms + chain:
        whole[x] = e.xreplace(whole)
    return [adjoint.get(x, sp.Integer(0)).xreplace(whole) for x in xs]


def second_derivative_along(phi: sp.Matrix, q, v, t=None, jacobian=None) -> sp.Matrix:
    """d²/dε² Φ(q + ε v, t + ε) at ε = 0, that is (Φ_q v)_q v + 2 Φ_qt v + Φ_tt (t held
    where None: (Φ_q v)_q v), row by row. A row built of rotations (sines and cosines of
    angles times polynomials: pins, guides, drivers) takes the Jacobian of Φ_q v, whose
    terms the code shares with Φ_q's; any other (a root, a quotient, an atan2: a curve's
    contact point in its body's frame, a gear's) is differentiated forward along the path
    through its shared terms (`_along`), whose result is smaller there and found faster
    (docs/benchmarks.md has the measurements). `jacobian`: Φ_q where it is at hand."""
    q, v = list(q), list(v)
    rates = dict(zip(q, v))
    if t is not None:
        rates[t] = sp.Integer(1)
    rows = []
    for i, row in enumerate(phi):
        if _of_rotations(row):
            gradient = [row.diff(qj) for qj in q] if jacobian is None else jacobian[i, :]
            jv = sp.Add(*[g * vj for g, vj in zip(gradient, v)])
            second = sp.Add(*[jv.diff(qk) * vk for qk, vk in zip(q, v)])
            if t is not None:
                rate = row.diff(t)
                second += 2 * sp.Add(*[rate.diff(qk) * vk for qk, vk in zip(q, v)]) + \
                    rate.diff(t)
        else:
            second = _along(row, rates)
        rows.append(second)
    return sp.Matrix(rows) if rows else sp.zeros(0, 1)


def _along(expr, rates: dict):
    """d²/dε² expr(x + ε ẋ) at ε = 0 for the symbols x of `rates` ({x: ẋ}; others held):
    forward through the shared terms of `expr` (sympy.cse), each term's first and second
    derivatives along the path from its arguments' (the gradient and Hessian of one small
    term), the chain put back together at the end (its terms shared, as cse finds them
    again): each differentiation is of one small term, not of the whole expression."""
    terms, (reduced,) = sp.cse([expr], symbols=sp.numbered_symbols(cls=sp.Dummy))
    first, second, chain = dict(rates), {}, []

    def derivatives(e):
        free = sorted((u for u in e.free_symbols if u in first), key=sp.default_sort_key)
        grad = [e.diff(u) for u in free]
        d1 = sp.Add(*[g * first[u] for g, u in zip(grad, free)])
        d2 = sp.Add(*[g * second[u] for g, u in zip(grad, free) if u in second])
        for i, (g, a) in enumerate(zip(grad, free)):
            for b in free[i:]:
                h = g.diff(b)
                if h != 0:
                    d2 += (1 if a == b else 2) * h * first[a] * first[b]
        return d1, d2

    for x, e in terms:
        d1, d2 = derivatives(e)
        first[x], second[x] = sp.Dummy(), sp.Dummy()
        chain += [(x, e), (first[x], d1), (second[x], d2)]
    _, d2 = derivatives(reduced)
    whole = {}
    for x, e in chain:
        whole[x] = e.xreplace(whole)
    return d2.xreplace(whole)


def _of_rotations(expr) -> bool:
    """Whether `expr` is a polynomial in symbols, sines and cosines (no roots, quotients or
    other functions)."""
    return all(isinstance(f, (sp.sin, sp.cos)) for f in expr.atoms(sp.Function)) and \
        all(p.exp.is_Integer and p.exp > 0 for p in expr.atoms(sp.Pow))


def build_system(bodies, items) -> SymbolicSystem:
    """Collect Φ from the constraint `items` (joints, then drivers) acting on `bodies`."""
    ctx = SymbolicContext(bodies, items)
    phi = []
    for item in items:
        phi += item.equations(ctx, ctx.parameters(item))
    return SymbolicSystem(ctx, phi)
