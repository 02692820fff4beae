"""Joints evaluated in numbers: their coordinates, rates and the wrench their multipliers
apply, from the same `equations(ctx, p)` and `coordinate(ctx, p)` hooks that give sympy
their constraint equations (`mechsim.model.joints`).

A joint writes its equations through a context and only does arithmetic on what the context
hands it. `NumericContext` hands it forward-mode dual numbers (`Dual`: a value and its
derivatives along a few chosen directions of q) over any number of states at once, so one
pass over a joint gives, for every output sample,

- its coordinate and rate (the derivative along v): `joint_coordinates`;
- the derivatives of its equations with respect to one body's frame coordinates (x, y, θ),
  from which the force and moment its multipliers λ apply to that body follow:
  `joint_wrench`.

No new joint needs anything else: what a joint can write for sympy it can write here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..model.context import JointContext


class Dual:
    """x + d·ε: values `x` (shape S) with derivatives `d` (shape S + (k,)) along k directions.
    Supports what a joint's equations use: +, −, ×, / and the context's cos and sin."""
    __slots__ = ("x", "d")
    __array_ufunc__ = None          # an array on the left defers to Dual's reflected operators

    def __init__(self, x, d):
        self.x, self.d = x, d

    def __add__(self, o):
        if isinstance(o, Dual):
            return Dual(self.x + o.x, self.d + o.d)
        return Dual(self.x + o, self.d)

    __radd__ = __add__

    def __sub__(self, o):
        if isinstance(o, Dual):
            return Dual(self.x - o.x, self.d - o.d)
        return Dual(self.x - o, self.d)

    def __rsub__(self, o):
        return Dual(o - self.x, -self.d)

    def __neg__(self):
        return Dual(-self.x, -self.d)

    def __mul__(self, o):
        if isinstance(o, Dual):
            return Dual(self.x * o.x, self.d * _col(o.x) + o.d * _col(self.x))
        return Dual(self.x * o, self.d * _col(o))

    __rmul__ = __mul__

    def __truediv__(self, o):
        if isinstance(o, Dual):
            return Dual(self.x / o.x, (self.d * _col(o.x) - o.d * _col(self.x)) / _col(o.x * o.x))
        return Dual(self.x / o, self.d / _col(o))

    def __rtruediv__(self, o):
        return Dual(o / self.x, -self.d * _col(o / (self.x * self.x)))


def _col(x):
    """x with a trailing axis, to scale derivatives (plain numbers pass)."""
    return x[..., None] if isinstance(x, np.ndarray) else x


def cos(a):
    if isinstance(a, Dual):
        return Dual(np.cos(a.x), -_col(np.sin(a.x)) * a.d)
    return np.cos(a)


def sin(a):
    if isinstance(a, Dual):
        return Dual(np.sin(a.x), _col(np.cos(a.x)) * a.d)
    return np.sin(a)


def sqrt(a):
    if isinstance(a, Dual):
        root = np.sqrt(a.x)
        return Dual(root, a.d / _col(2.0 * root))
    return np.sqrt(a)


def atan2(y, x):
    if isinstance(y, Dual) or isinstance(x, Dual):
        yv, xv = value(y), value(x)
        k = (y.d if isinstance(y, Dual) else x.d).shape[-1]
        dy = derivative(y, yv.shape + (k,))
        dx = derivative(x, xv.shape + (k,))
        r2 = xv * xv + yv * yv
        return Dual(np.arctan2(yv, xv), (dy * _col(xv) - dx * _col(yv)) / _col(r2))
    return np.arctan2(y, x)


def curve(law, phi, parameters=()):
    """r(φ) of an `Expression` in phi or a periodic spline (whose `parameters` are its
    own numbers) at φ (a dual or an array): its value and, by the chain rule with its
    derivative (`jet`), its dual."""
    at = np.atleast_1d(value(phi))
    jets = np.array([law.jet("phi", float(a))[:2] for a in at.reshape(-1)]).reshape(at.shape + (2,))
    r, dr = jets[..., 0].reshape(np.shape(value(phi))), jets[..., 1].reshape(np.shape(value(phi)))
    if isinstance(phi, Dual):
        return Dual(r, phi.d * _col(dr))
    return r


def value(a):
    """The value of a dual or of a plain number, as an array."""
    return a.x if isinstance(a, Dual) else np.asarray(a, float)


def derivative(a, shape):
    """The derivatives of a dual (zeros of `shape` for a constant)."""
    return a.d if isinstance(a, Dual) else np.zeros(shape)


def _over_states(seeds, shape):
    """Seeds (n, k) or (N or 1, n, k) as a read-only (N, n, k) view, for states of `shape`
    (N, n)."""
    seeds = np.asarray(seeds, float)
    return np.broadcast_to(seeds, shape + seeds.shape[-1:])


class NumericContext(JointContext):
    """What a joint sees while writing its equations (`JointContext`), in dual numbers.

    Parameters
    ----------
    starts : dict id(body) -> index of the body's x in q (bodies absent: the ground)
    q : ndarray (N, n), the states
    seeds : ndarray (N, n, k) or (n, k): the derivative of each coordinate along each of k
        directions (None: values only, no derivatives)
    """

    def __init__(self, starts, q, seeds=None):
        self.starts = starts
        self.q = np.atleast_2d(np.asarray(q, float))
        # The seeds over every state, broadcast once (a coordinate takes a view of them).
        self.seeds = None if seeds is None else _over_states(seeds, self.q.shape)

    def coordinate(self, i):
        x = self.q[:, i]
        if self.seeds is None:
            return x
        return Dual(x, self.seeds[:, i, :])

    def frame(self, body):
        start = self.starts.get(id(body))
        if start is None:
            return 0.0, 0.0, 0.0
        return tuple(self.coordinate(start + c) for c in range(3))

    def modal(self, body):
        start = self.starts.get(id(body))
        k = len(body.coordinate_names) - 3
        if start is None or k <= 0:
            return ()
        return tuple(self.coordinate(start + 3 + c) for c in range(k))

    cos, sin = staticmethod(cos), staticmethod(sin)
    sqrt, atan2, curve = staticmethod(sqrt), staticmethod(atan2), staticmethod(curve)


class OneState(NumericContext):
    """`NumericContext` at one state q (n,): values are floats and derivatives rows (k,),
    so a joint's few dozen operations cost Python arithmetic, not numpy's per-call
    bookkeeping on arrays of one element (a friction joint's gradient and wrench at each
    right-hand side). The same functions of the same numbers as the context over states."""

    def __init__(self, starts, q, seeds=None):
        self.starts = starts
        self.q = np.asarray(q, float).tolist()
        self.seeds = None if seeds is None else np.asarray(seeds, float)

    def coordinate(self, i):
        if self.seeds is None:
            return self.q[i]
        return Dual(self.q[i], self.seeds[i])


class Jet:
    """x(τ) to second order along a path: the value `x` and its first and second derivatives
    `d1`, `d2` in τ (arrays of one shape). With q(τ) = q + τ v a joint's coordinate s gives
    s, ṡ = ∂s/∂q v and vᵀ (∂²s/∂q²) v, the part of s̈ that does not come from q̈. Supports
    what revolute and prismatic coordinates use: +, −, ×, / and cos, sin."""
    __slots__ = ("x", "d1", "d2")
    __array_ufunc__ = None

    def __init__(self, x, d1, d2):
        self.x, self.d1, self.d2 = x, d1, d2

    def __add__(self, o):
        if isinstance(o, Jet):
            return Jet(self.x + o.x, self.d1 + o.d1, self.d2 + o.d2)
        return Jet(self.x + o, self.d1, self.d2)

    __radd__ = __add__

    def __sub__(self, o):
        return self + (-o)

    def __rsub__(self, o):
        return (-self) + o

    def __neg__(self):
        return Jet(-self.x, -self.d1, -self.d2)

    def __mul__(self, o):
        if isinstance(o, Jet):
            return Jet(self.x * o.x, self.d1 * o.x + self.x * o.d1,
                       self.d2 * o.x + 2.0 * self.d1 * o.d1 + self.x * o.d2)
        return Jet(self.x * o, self.d1 * o, self.d2 * o)

    __rmul__ = __mul__

    def __truediv__(self, o):
        if not isinstance(o, Jet):
            return self * (1.0 / o)
        x = self.x / o.x
        d1 = (self.d1 - x * o.d1) / o.x
        return Jet(x, d1, (self.d2 - 2.0 * d1 * o.d1 - x * o.d2) / o.x)


def _jet_cos(a):
    if isinstance(a, Jet):                  # (its parts may be duals: `DualJetContext`)
        c, s = cos(a.x), sin(a.x)
        return Jet(c, -s * a.d1, -c * a.d1 * a.d1 - s * a.d2)
    return np.cos(a)


def _jet_sin(a):
    if isinstance(a, Jet):
        c, s = cos(a.x), sin(a.x)
        return Jet(s, c * a.d1, -s * a.d1 * a.d1 + c * a.d2)
    return np.sin(a)


class JetContext(NumericContext):
    """A `NumericContext` whose coordinates are `Jet`s along q + τ v (states q, v (N, n))."""

    def __init__(self, starts, q, v):
        super().__init__(starts, q)
        self.v = np.atleast_2d(np.asarray(v, float))

    def coordinate(self, i):
        x = self.q[:, i]
        return Jet(x, self.v[:, i], np.zeros_like(x))

    cos, sin = staticmethod(_jet_cos), staticmethod(_jet_sin)


class DualJetContext(NumericContext):
    """A `JetContext` along q + τ v + τ² q̈/2 whose parts are `Dual`s: the value and
    rate seeded with the directions dq, dv (N, n, k) (q̈'s seeds zero), so a coordinate's
    jet carries its exact derivatives along them — third derivatives of s from second-order
    jets (`joint_path_partials`)."""

    def __init__(self, starts, q, v, a, dq, dv):
        super().__init__(starts, q)
        self.v, self.a = np.atleast_2d(v), np.atleast_2d(a)
        self.dq, self.dv = _over_states(dq, self.q.shape), _over_states(dv, self.q.shape)

    def coordinate(self, i):
        x = self.q[:, i]
        k = self.dq.shape[-1]
        return Jet(Dual(x, self.dq[:, i, :]), Dual(self.v[:, i], self.dv[:, i, :]),
                   Dual(self.a[:, i], np.zeros(x.shape + (k,))))

    cos, sin = staticmethod(_jet_cos), staticmethod(_jet_sin)


@dataclass(frozen=True)
class JointGeometry:
    """One joint of a built mechanism, for numeric evaluation: the joint (its `equations`
    and `coordinate` hooks), its parameter values by name, the start in q of every body of
    the mechanism by id (the ground absent) and the joint's attachment point on each body,
    in that body's frame."""
    joint: object
    parameters: dict
    starts: dict
    local_a: tuple
    local_b: tuple

    @property
    def start_a(self):
        return self.starts.get(id(self.joint.body_a))

    @property
    def start_b(self):
        return self.starts.get(id(self.joint.body_b))

    @cached_property
    def _gradients(self) -> dict:
        return {}

    def constant_gradient(self, n: int) -> np.ndarray:
        """∂s/∂q (n,) of a joint whose coordinate is linear in q (`linear_coordinate`: a
        revolute's θ_b − θ_a with its nodes' modal rotations), evaluated once (read-only)."""
        row = self._gradients.get(n)
        if row is None:
            c = self.joint.coordinate(OneState(self.starts, np.zeros(n), np.eye(n)),
                                      self.parameters)
            row = np.array(derivative(c, (n,)), float)
            row.flags.writeable = False
            self._gradients[n] = row
        return row


def _broadcast(a, n):
    return np.broadcast_to(value(a), (n,))


def joint_coordinates(geometry: JointGeometry, q, v):
    """(s, ṡ), each shape (N,): the joint's coordinate (relative angle of a revolute, slide
    of a prismatic, as its `coordinate` hook defines it) and its rate along v, at the states
    q, v of shape (N, n)."""
    q, v = np.atleast_2d(q), np.atleast_2d(v)
    n = q.shape[0]
    c = geometry.joint.coordinate(NumericContext(geometry.starts, q, v[:, :, None]),
                                  geometry.parameters)
    return _broadcast(c, n).copy(), np.broadcast_to(derivative(c, (n, 1))[..., 0], (n,)).copy()


def joint_wrench(geometry: JointGeometry, q, lam, jacobian=None):
    """(F, M): the force (N, 2, global axes) the joint applies to its body_b and the moment
    (N,) about the joint's point on body_b, from the joint's multipliers `lam` (N, rows) at
    the states q (N, n). `jacobian`: the joint's rows of Φ_q there ((N, rows, n), or
    (rows, n) for all), if the caller has them; else they are evaluated here.

    The constraint forces are −Φ_qᵀ λ; on a body's frame coordinates (x, y, θ) they are the
    force and the moment about the frame origin R, so about the attachment point P the
    moment is M_R − (P − R) × F. Where body_b is the ground the wrench is found on body_a
    and turned by Newton's third law (a joint's equations move with both bodies)."""
    q = np.atleast_2d(q)
    n = q.shape[0]
    on_b = geometry.start_b is not None
    start = geometry.start_b if on_b else geometry.start_a
    if jacobian is not None and np.ndim(jacobian) == 2:     # the same rows at every state
        generalized = -(np.asarray(lam) @ np.asarray(jacobian)[:, start:start + 3])
    elif jacobian is not None:
        grad = np.broadcast_to(np.asarray(jacobian)[..., start:start + 3], (n, len(lam[0]), 3))
        generalized = -np.einsum("nr,nrc->nc", lam, grad)
    else:
        seeds = np.zeros((q.shape[1], 3))
        seeds[start:start + 3] = np.eye(3)
        rows = geometry.joint.equations(NumericContext(geometry.starts, q, seeds),
                                        geometry.parameters)
        grad = np.stack([np.broadcast_to(derivative(r, (n, 3)), (n, 3)) for r in rows], axis=1)
        generalized = -np.einsum("nr,nrc->nc", lam, grad)      # on (x, y, θ) of the body
    force = generalized[:, :2]
    if geometry.joint.kind == "revolute":       # a pin carries no moment about its point
        return (force if on_b else -force), np.zeros(n)
    P = _attachment(geometry, q, "b" if on_b else "a")
    r = P - q[:, start:start + 2]
    moment = generalized[:, 2] - (r[:, 0] * force[:, 1] - r[:, 1] * force[:, 0])
    if on_b:
        return force, moment
    # On body_b (the ground): the opposite wrench, its moment taken about body_b's point.
    d = P - joint_point(geometry, q)
    return -force, -moment - (d[:, 0] * force[:, 1] - d[:, 1] * force[:, 0])


def joint_point(geometry: JointGeometry, q) -> np.ndarray:
    """The joint's point on its body_b in global axes at the states q (N, n): (N, 2)."""
    return _attachment(geometry, np.atleast_2d(q), "b")


def _attachment(geometry: JointGeometry, q, role: str) -> np.ndarray:
    """(N, 2) global position of the joint's point on its body_a or body_b (`role` "a" or
    "b") at the states q (N, n)."""
    body, local = ((geometry.joint.body_b, geometry.local_b) if role == "b"
                   else (geometry.joint.body_a, geometry.local_a))
    if q.shape[0] == 1:
        x, y = OneState(geometry.starts, q[0]).point(body, local[0], local[1],
                                                     geometry.parameters, role)
        return np.array([[x, y]], float)
    x, y = NumericContext(geometry.starts, q).point(body, local[0], local[1],
                                                    geometry.parameters, role)
    return np.column_stack([_broadcast(x, q.shape[0]), _broadcast(y, q.shape[0])])


def joint_gradient(geometry: JointGeometry, q) -> np.ndarray:
    """∂s/∂q of the joint's coordinate s at the state q (n,): shape (n,) (its rate is ∂s/∂q v)."""
    return joint_gradients(geometry, np.asarray(q, float)[None])[0]


def joint_gradients(geometry: JointGeometry, q) -> np.ndarray:
    """`joint_gradient` at the states q (N, n) in one pass: shape (N, n)."""
    q = np.atleast_2d(np.asarray(q, float))
    shape = q.shape
    if geometry.joint.linear_coordinate:
        return np.tile(geometry.constant_gradient(shape[1]), (shape[0], 1))
    if shape[0] == 1:
        c = geometry.joint.coordinate(OneState(geometry.starts, q[0], np.eye(shape[1])),
                                      geometry.parameters)
        return np.reshape(derivative(c, shape[1:]), shape).copy()
    c = geometry.joint.coordinate(NumericContext(geometry.starts, q, np.eye(shape[1])),
                                  geometry.parameters)
    d = derivative(c, shape)
    return np.array(d if d.shape == shape else np.broadcast_to(d, shape))


def joint_path_rates(geometry: JointGeometry, q, v):
    """(s, ṡ, vᵀ (∂²s/∂q²) v), each shape (N,), of the joint's coordinate at the states
    q, v (N, n): then s̈ = (∂s/∂q) q̈ + the third (what holding a joint at ṡ = 0 needs)."""
    q, v = np.atleast_2d(q), np.atleast_2d(v)
    n = q.shape[0]
    c = geometry.joint.coordinate(JetContext(geometry.starts, q, v), geometry.parameters)
    if not isinstance(c, Jet):
        zero = np.zeros(n)
        return np.broadcast_to(value(c), (n,)).copy(), zero, zero.copy()
    return tuple(np.broadcast_to(x, (n,)).copy() for x in (c.x, c.d1, c.d2))


def _jet_derivatives(geometry, ctx, N, k):
    """(∂ṡ, ∂(vᵀ∂²s v + ∂s q̈)) along the seeded directions of a `DualJetContext`, (N, k)
    each (zeros where the coordinate does not move with them)."""
    c = geometry.joint.coordinate(ctx, geometry.parameters)
    if not isinstance(c, Jet):
        return np.zeros((N, k)), np.zeros((N, k))
    return (np.broadcast_to(derivative(c.d1, (N, k)), (N, k)),
            np.broadcast_to(derivative(c.d2, (N, k)), (N, k)))


def joint_path_partials(geometry: JointGeometry, q, v, a, dq, dv):
    """The changes of the joint's rate ṡ and of s̈ − (∂s/∂q) q̈ at the state (q, v, q̈ = a)
    (n,) along the directions (dq, dv) (n, k) of (q, v), each (k,): (∂s/∂q) dv +
    (∂²s/∂q² dq)·v, and (∂²s/∂q² dq)·q̈ + 2 vᵀ ∂²s/∂q² dv + ∂³s/∂q³[v, v, dq] (exact:
    the coordinate's second-order jet in dual numbers)."""
    k = dq.shape[1]
    ctx = DualJetContext(geometry.starts, q[None], v[None], a[None], dq[None], dv[None])
    rate, rest = _jet_derivatives(geometry, ctx, 1, k)
    return rate[0].copy(), rest[0].copy()


def joint_curvature(geometry: JointGeometry, q, W) -> np.ndarray:
    """(∂²s/∂q²) W at the state q (n,) of the joint's coordinate s, for the columns of W
    (n, k): shape (n, k) (each column the gradient of (∂s/∂q)·w in q)."""
    n, k = W.shape
    ctx = DualJetContext(geometry.starts, np.broadcast_to(q, (k, n)), W.T, np.zeros((k, n)),
                         np.eye(n)[None], np.zeros((1, n, n)))
    return _jet_derivatives(geometry, ctx, k, n)[0].T.copy()


def joint_coordinate_partials(geometry: JointGeometry, q, dq, parameters) -> np.ndarray:
    """d s/dk of the joint's coordinate at the states q (N, n) for the sensitivities dq
    (N, n, K) and `parameters`: the joint's parameters' derivatives {name: (K,)} (those
    absent do not move): ∂s/∂q q_k + ∂s/∂p ∂p/∂k, shape (N, K), in one pass of duals."""
    q = np.atleast_2d(q)
    N, K = q.shape[0], dq.shape[-1]
    values = {name: Dual(x, np.asarray(parameters[name], float)) if name in parameters else x
              for name, x in geometry.parameters.items()}
    c = geometry.joint.coordinate(NumericContext(geometry.starts, q, dq), values)
    return np.broadcast_to(derivative(c, (N, K)), (N, K)).copy()
