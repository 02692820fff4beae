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
        return self.phi.jacobian(self.q) if self.q else sp.zeros(self.phi.rows, 0)

    @cached_property
    def phi_t(self) -> sp.Matrix:
        return self.phi.diff(self.t)

    @cached_property
    def gamma(self) -> sp.Matrix:
        qd = sp.Matrix(self.v)
        if not self.q:
            return -self.phi_t.diff(self.t)
        jv = self.phi_q * qd
        return -(jv.jacobian(self.q) * qd) - 2 * (self.phi_t.jacobian(self.q) * qd) \
            - self.phi_t.diff(self.t)


def build_system(bodies, items) -> SymbolicSystem:
    """Collect Φ from the constraint `items` (joints, then drivers) acting on `bodies`."""
    ctx = SymbolicContext(bodies, items)
    phi = []
    for item in items:
        phi += item.equations(ctx, ctx.parameters(item))
    return SymbolicSystem(ctx, phi)
