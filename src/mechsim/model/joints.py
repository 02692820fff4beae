"""Joints: each one a short class that states its constraint equations Φ = 0.

A joint declares named parameters (body-fixed attachment points, axes, initial offsets) whose
values come from the initial configuration, and writes its equations through a context `ctx`
supplied by the symbolic layer. The parameters become arguments of the generated code, so one
compiled structure serves every geometry. A joint never imports sympy: `ctx` hands it
expressions and it only does arithmetic on them.

Contract for a new joint (sympy's `Joint` builds itself through a few hooks in the same way):
  1. `kind` and `parameter_names`;
  2. `parameter_values()` -> floats in the order of `parameter_names`;
  3. `equations(ctx, p)` -> list of expressions, `p` maps parameter names to symbols;
  4. optionally `coordinate(ctx, p)` and `initial_coordinate()` so a `Driver` can prescribe it.

A side attached to a flexible beam adds the mode shapes of its node as parameters (`a_u1`,
`a_v1`, `a_r1`, … for body_a): `ctx.point(body, sx, sy, p, "a")` moves the point with the
modes and `ctx.angle(body, p, "a")` turns with the node.
"""

from __future__ import annotations

import math

import numpy as np

from . import parameters as dual
from .checks import ModelError, name_or_default, vector2, vector2_exact
from .bodies import Body


class Joint:
    kind = "joint"
    parameter_names: tuple[str, ...] = ()

    def __init__(self, body_a: Body, body_b: Body, name: str | None = None):
        for role, body in (("body_a", body_a), ("body_b", body_b)):
            if not isinstance(body, Body):
                raise ModelError(f"{self.kind} joint: `{role}` must be a body, got {body!r}")
        if body_a is body_b:
            raise ModelError(f"{self.kind} joint: connects body '{body_a.name}' to itself")
        self.body_a, self.body_b = body_a, body_b
        self.name = name_or_default(name, f"{self.kind}({body_a.name},{body_b.name})",
                                    f"{self.kind} joint")
        self.parameter_names = type(self).parameter_names + \
            body_a.attachment_parameter_names("a") + body_b.attachment_parameter_names("b")

    def attachment_points(self):
        """(body_a's point, body_b's point) in their body frames, from the global `at`."""
        return self.body_a.local_point(self.at), self.body_b.local_point(self.at)

    # `at` as given, Parameters kept (`mechsim.model.parameters`); None: `at` itself.
    _exact_at = None

    def exact_attachment_points(self):
        """`attachment_points` carrying the derivatives of Parameters the joint's point
        or its bodies' frames depend on (see `Body.exact_local_point`)."""
        at = self.at if self._exact_at is None else self._exact_at
        points = self.body_a.exact_local_point(at), self.body_b.exact_local_point(at)
        self._rigid_where_exact(points)
        return points

    def exact_numbers(self) -> list:
        """The numbers as given that may be Parameters or computed from them."""
        return [self._exact_at]

    def refresh_numbers(self) -> None:
        """Take the numbers computed from Parameters again (after
        `mechsim.model.parameters.refresh`), checked as when built."""
        if self._exact_at is not None and dual.is_exact(self._exact_at):
            self.at = vector2(dual.values(self._exact_at), "at", f"{self.kind} joint '{self.name}'")
        self._attachments(*self.attachment_points())

    def exact_relative_angle(self):
        """body_b's angle less body_a's as built (at the joint's nodes on flexible bodies),
        a Dual where the bodies' angles depend on Parameters."""
        sa, sb = self.attachment_points()
        return (self.body_b.exact_angle + self.body_b.initial_node_rotation(sb)
                - self.body_a.exact_angle - self.body_a.initial_node_rotation(sa))

    def _rigid_where_exact(self, points):
        """A ModelError where a point that depends on a Parameter lies on a flexible body
        (its mode shapes, fixed at a node, would not follow the point)."""
        for body, point in zip((self.body_a, self.body_b), points):
            if dual.is_exact(point) and body.attachment_parameter_names("a"):
                raise ModelError(f"{self.kind} joint '{self.name}': its point on the flexible "
                                 f"body '{body.name}' cannot depend on a Parameter")

    def _attachments(self, sa, sb) -> tuple[float, ...]:
        """Mode-shape parameter values of the attachment points sa (on body_a) and sb."""
        who = f"{self.kind} joint '{self.name}'"
        return self.body_a.attachment_values(sa, who) + self.body_b.attachment_values(sb, who)

    @property
    def n_equations(self) -> int:
        return len(self.equation_labels)

    equation_labels: tuple[str, ...] = ()

    def parameter_values(self) -> tuple[float, ...]:
        raise NotImplementedError

    def equations(self, ctx, p) -> list:
        raise NotImplementedError

    def coordinate(self, ctx, p):
        raise ModelError(f"joint '{self.name}' ({self.kind}) has no coordinate a driver can prescribe")

    def initial_coordinate(self) -> float:
        raise ModelError(f"joint '{self.name}' ({self.kind}) has no coordinate a driver can prescribe")

    def exact_initial_coordinate(self):
        """`initial_coordinate`, a Dual where it depends on Parameters
        (`mechsim.model.parameters`)."""
        return self.initial_coordinate()

    # Does it carry the derivatives of Parameters in its geometry and its bodies' frames
    # into its equations' parameters (`parameter_values`)?
    carries_parameters = False
    # Is its `coordinate` linear in q (its gradient the same at every state)?
    linear_coordinate = False

    def moved_by(self, names):
        """The first of the Parameters `names` that moves this joint's coordinate (through
        the numbers of its geometry, `parameter_values`), else None."""
        return _first_moving(self.parameter_values(), names)

    def structure(self, index) -> tuple:
        """What this joint's generated equations depend on: its kind and its bodies'
        positions `index(body)` (−1: the ground), with its parameter names."""
        return (self.kind, index(self.body_a), index(self.body_b), list(self.parameter_names))

    def __repr__(self):
        return f"{type(self).__name__}({self.name!r})"


def _first_moving(values, names):
    """The first of the Parameters `names` some of the numbers `values` move with, else
    None."""
    moving = np.any(dual.gradient(values, names) != 0.0, axis=0)
    return next((name for name, moves in zip(names, moving) if moves), None)


def coordinate_joint(joint, role: str, purpose: str) -> Joint:
    """`joint` if it is a joint with a coordinate (revolute, prismatic); else a ModelError
    naming `role` (who asks: "driver", "stop on", …) and what it would do (`purpose`)."""
    if not isinstance(joint, Joint):
        raise ModelError(f"{role}: `joint` must be a joint, got {joint!r:.60}")
    if type(joint).coordinate is Joint.coordinate:
        raise ModelError(f"{role} on joint '{joint.name}': a {joint.kind} joint has no "
                         f"coordinate to {purpose}")
    return joint


class Revolute(Joint):
    """A pin: the point `at` of body_a coincides with the point `at` of body_b.

    Give `at` as a global point in the initial configuration, or the two body-fixed points
    `local_a` and `local_b` (then the initial configuration may be a rough guess that
    `Mechanism.assemble` closes).
    """

    kind = "revolute"
    carries_parameters = True
    linear_coordinate = True            # θ_b − θ_a, with a beam node's modal rotations
    parameter_names = ("ax", "ay", "bx", "by")
    equation_labels = ("x", "y")

    def __init__(self, body_a: Body, body_b: Body, at=None, *, local_a=None, local_b=None,
                 name: str | None = None):
        super().__init__(body_a, body_b, name)
        owner = f"revolute joint '{self.name}'"
        if at is not None:
            if local_a is not None or local_b is not None:
                raise ModelError(f"{owner}: give either `at` or `local_a` and `local_b`, not both")
            self.at, self._exact_at = vector2_exact(at, "at", owner)
            self.local_a = self.local_b = None
        else:
            if local_a is None or local_b is None:
                raise ModelError(f"{owner}: needs `at` (a global point) or both `local_a` and `local_b`")
            self.at = None
            self.local_a, self._exact_a = vector2_exact(local_a, "local_a", owner)
            self.local_b, self._exact_b = vector2_exact(local_b, "local_b", owner)
        self._attachments(*self.attachment_points())   # a point on a beam must be a node

    def parameter_values(self):
        """(ax, ay, bx, by, mode shapes…): numbers, or Duals where they depend on
        Parameters (`mechsim.model.parameters`)."""
        sa, sb = self.attachment_points()
        ea, eb = self.exact_attachment_points()
        return (ea[0], ea[1], eb[0], eb[1]) + self._attachments(sa, sb)

    def attachment_points(self):
        if self.at is not None:
            return super().attachment_points()
        return self.local_a, self.local_b

    def exact_numbers(self) -> list:
        if self.at is not None:
            return super().exact_numbers()
        return [self._exact_a, self._exact_b]

    def refresh_numbers(self) -> None:
        if self.at is None:
            owner = f"revolute joint '{self.name}'"
            self.local_a = vector2(dual.values(self._exact_a), "local_a", owner)
            self.local_b = vector2(dual.values(self._exact_b), "local_b", owner)
        super().refresh_numbers()

    def exact_attachment_points(self):
        if self.at is not None:
            return super().exact_attachment_points()
        points = self._exact_a, self._exact_b
        self._rigid_where_exact(points)
        return points

    def equations(self, ctx, p):
        pa = ctx.point(self.body_a, p["ax"], p["ay"], p, "a")
        pb = ctx.point(self.body_b, p["bx"], p["by"], p, "b")
        return [pb[0] - pa[0], pb[1] - pa[1]]

    def coordinate(self, ctx, p):
        """Relative angle of body_b with respect to body_a (at the joint's node for a
        flexible beam)."""
        return ctx.angle(self.body_b, p, "b") - ctx.angle(self.body_a, p, "a")

    def initial_coordinate(self):
        return dual.value_of(self.exact_initial_coordinate())

    def exact_initial_coordinate(self):
        return self.exact_relative_angle()

    def moved_by(self, names):
        """As `Joint.moved_by`; the coordinate (its bodies' angles' difference, with a
        beam node's modal rotations) does not move with the attachment points."""
        return _first_moving(self.parameter_values()[4:], names)


class Prismatic(Joint):
    """A slider: body_b translates along `axis` (fixed in body_a) without relative rotation.

    `axis` is a global direction and `at` a global point in the initial configuration; the
    point `at` of body_b stays on the line through the point `at` of body_a along the axis.
    """

    kind = "prismatic"
    carries_parameters = True
    parameter_names = ("ax", "ay", "bx", "by", "ux", "uy", "angle0")
    equation_labels = ("angle", "normal")

    def __init__(self, body_a: Body, body_b: Body, axis=(1.0, 0.0), at=(0.0, 0.0),
                 name: str | None = None):
        super().__init__(body_a, body_b, name)
        owner = f"prismatic joint '{self.name}'"
        axis, exact_axis = vector2_exact(axis, "axis", owner)
        norm = float(np.hypot(*axis))
        if not norm > 1e-12:
            raise ModelError(f"{owner}: `axis` must be a non-zero direction, got {axis.tolist()}")
        self.axis = axis / norm
        self._exact_axis = exact_axis / dual.hypot(exact_axis[0], exact_axis[1]) \
            if dual.is_exact(exact_axis) else self.axis
        self.at, self._exact_at = vector2_exact(at, "at", owner)
        self._attachments(*self.attachment_points())

    def exact_numbers(self) -> list:
        return super().exact_numbers() + [self._exact_axis]

    def refresh_numbers(self) -> None:
        if dual.is_exact(self._exact_axis):
            self.axis = dual.values(self._exact_axis)
        super().refresh_numbers()

    def parameter_values(self):
        """(ax, ay, bx, by, ux, uy, angle0, mode shapes…): numbers, or Duals where they
        depend on Parameters (`mechsim.model.parameters`)."""
        sa, sb = self.attachment_points()
        ea, eb = self.exact_attachment_points()
        u = self.body_a.exact_local_direction(self._exact_axis)
        return (ea[0], ea[1], eb[0], eb[1], u[0], u[1], self.exact_relative_angle()) + \
            self._attachments(sa, sb)

    def _separation(self, ctx, p):
        pa = ctx.point(self.body_a, p["ax"], p["ay"], p, "a")
        pb = ctx.point(self.body_b, p["bx"], p["by"], p, "b")
        return [pb[0] - pa[0], pb[1] - pa[1]]

    def equations(self, ctx, p):
        d = self._separation(ctx, p)
        n = ctx.direction(self.body_a, -p["uy"], p["ux"], p, "a")
        return [ctx.angle(self.body_b, p, "b") - ctx.angle(self.body_a, p, "a") - p["angle0"],
                n[0] * d[0] + n[1] * d[1]]

    def coordinate(self, ctx, p):
        """Translation of body_b's point along the axis, measured from body_a's point."""
        d = self._separation(ctx, p)
        u = ctx.direction(self.body_a, p["ux"], p["uy"], p, "a")
        return u[0] * d[0] + u[1] * d[1]

    def initial_coordinate(self):
        return 0.0


class PointOnCurve(Joint):
    """A point of body_b kept on a curve fixed in body_a: a pin in a slot, a follower's
    roller centre on a cam's pitch curve. One equation; body_b may turn and slide along
    the curve. `at` is body_b's point (global, in the initial configuration), `centre`
    the curve's reference point (global, default `at`), and `curve` one of

    - ``("line", (ux, uy))``: the straight line through `centre` along (ux, uy) (global
      as built), a straight slot;
    - ``("circle", radius)``: the circle of `radius` about `centre`, a curved slot;
    - ``("polar", "expression in phi")``: the closed curve r(φ) about `centre`, φ the
      polar angle in body_a from the global x axis as built, r 2π-periodic (a cam's pitch
      curve: `"0.05 + 0.01*cos(phi)"`; parsed, never executed);
    - ``("polar", points)``: the same through the rows (φ, r) of `points` (at least 4, φ
      increasing within one turn): their periodic cubic spline (`PeriodicSpline`; its
      numbers are parameters, so other points need no new build).

    The point must be on the curve as built (within 1e-9 of its size); the multiplier is
    the force normal to the curve (`SimulationResult.joint_force`). The arguments may also
    come as (body_a, curve, body_b, point)."""

    kind = "curve"
    equation_labels = ("normal",)

    def __init__(self, body_a: Body, body_b: Body = None, at=None, curve=None, centre=None,
                 name: str | None = None, *, point=None):
        if isinstance(at, Body) and not isinstance(body_b, Body):
            # the order (body_a, curve, body_b, point) of the public API's first listing
            body_b, at, curve = at, curve, body_b
        at = point if at is None else at
        if at is None or curve is None:
            raise ModelError("point-on-curve joint: needs body_b's point `at` (or `point`) "
                             "and the `curve`")
        super().__init__(body_a, body_b, name)
        owner = f"point-on-curve joint '{self.name}'"
        self.at = vector2(at, "at", owner)
        self.centre = self.at.copy() if centre is None else vector2(centre, "centre", owner)
        if not (isinstance(curve, tuple) and len(curve) == 2 and
                curve[0] in ("line", "circle", "polar")):
            raise ModelError(f"{owner}: `curve` must be ('line', (ux, uy)), ('circle', "
                             f"radius) or ('polar', 'expression in phi'), got {curve!r:.80}")
        self.form = curve[0]
        if self.form == "line":
            u = vector2(curve[1], "curve direction", owner)
            norm = float(np.hypot(*u))
            if not norm > 1e-12:
                raise ModelError(f"{owner}: the line's direction must not be zero")
            self.shape = u / norm
            self.parameter_names = ("ax", "ay", "bx", "by", "nx", "ny") + \
                self.parameter_names[4:]
        elif self.form == "circle":
            from .checks import scalar
            self.shape = scalar(curve[1], "curve radius", owner, positive=True)
            self.parameter_names = ("ax", "ay", "bx", "by", "radius") + \
                self.parameter_names[4:]
        elif isinstance(curve[1], str):
            from .expressions import parse
            self.shape = parse(curve[1], {"phi"}, f"{owner} `curve`")
            self.parameter_names = ("ax", "ay", "bx", "by", "angle0") + \
                self.parameter_names[4:]
            self._periodic(owner)
        else:
            from .splines import PeriodicSpline
            self.shape = PeriodicSpline(curve[1], owner)
            self.parameter_names = ("ax", "ay", "bx", "by", "angle0") + \
                self.shape.parameter_names + self.parameter_names[4:]
        self._attachments(*self.attachment_points())
        gap = self._gap()
        size = max(1.0, float(np.hypot(*(self.at - self.centre))))
        if abs(gap) > 1e-9 * size:
            raise ModelError(f"{owner}: its point ({self.at[0]:.6g}, {self.at[1]:.6g}) is "
                             f"{abs(gap):.3g} off its {self.form} as built; place it on it")

    def _periodic(self, owner):
        """ModelError where the polar curve is not 2π-periodic (checked at 16 angles): the
        point's polar angle wraps round as body_a turns, and r must not jump there."""
        for phi in np.linspace(-math.pi, math.pi, 16, endpoint=False):
            try:
                a, b = self.shape.value(phi=phi), self.shape.value(phi=phi + 2.0 * math.pi)
            except (ArithmeticError, ValueError) as exc:
                raise ModelError(f"{owner}: the polar curve is not defined at phi = "
                                 f"{phi:.3g} ({exc})") from None
            if not abs(a - b) <= 1e-9 * max(1.0, abs(a)):
                raise ModelError(f"{owner}: the polar curve must repeat every 2π (a closed "
                                 f"cam); r({phi:.3g}) = {a:.6g} but r({phi:.3g} + 2π) = "
                                 f"{b:.6g}")

    def attachment_points(self):
        return self.body_a.local_point(self.centre), self.body_b.local_point(self.at)

    def _gap(self) -> float:
        d = self.at - self.centre
        if self.form == "line":
            return float(-self.shape[1] * d[0] + self.shape[0] * d[1])
        if self.form == "circle":
            return float(np.hypot(*d) - self.shape)
        return float(np.hypot(*d) - self.shape.value(phi=math.atan2(d[1], d[0])))

    def parameter_values(self):
        sa, sb = self.attachment_points()
        extra = ()
        if self.form == "line":
            n = self.body_a.local_direction(np.array([-self.shape[1], self.shape[0]]))
            extra = (float(n[0]), float(n[1]))
        elif self.form == "circle":
            extra = (self.shape,)
        else:
            extra = (float(self.body_a.angle),) + getattr(self.shape, "coefficients", ())
        return (sa[0], sa[1], sb[0], sb[1]) + extra + self._attachments(sa, sb)

    def equations(self, ctx, p):
        c = ctx.point(self.body_a, p["ax"], p["ay"], p, "a")
        pb = ctx.point(self.body_b, p["bx"], p["by"], p, "b")
        d = [pb[0] - c[0], pb[1] - c[1]]
        if self.form == "line":
            n = ctx.direction(self.body_a, p["nx"], p["ny"], p, "a")
            return [n[0] * d[0] + n[1] * d[1]]
        if self.form == "circle":
            return [ctx.sqrt(d[0] * d[0] + d[1] * d[1]) - p["radius"]]
        e1 = ctx.direction(self.body_a, 1.0, 0.0, p, "a")
        x = e1[0] * d[0] + e1[1] * d[1]              # d in body_a's axes
        y = -e1[1] * d[0] + e1[0] * d[1]
        phi = ctx.atan2(y, x) + p["angle0"]          # from the global x axis as built
        spline = [p[n] for n in getattr(self.shape, "parameter_names", ())]
        return [ctx.sqrt(x * x + y * y) - ctx.curve(self.shape, phi, spline)]

    def drawn(self, points: int = 97) -> list:
        """[(body_a, a polar curve as a closed polyline in its frame)]; [] for slots, which
        their bodies' own drawings carry (`drawing`)."""
        if self.form != "polar":
            return []
        phi = np.linspace(0.0, 2.0 * np.pi, points)
        r = np.array([self.shape.value(phi=f) for f in phi])
        turned = phi - self.body_a.angle                  # from the body's axes
        centre = np.asarray(self.attachment_points()[0], float)
        return [(self.body_a, centre + r[:, None] * np.column_stack([np.cos(turned),
                                                                       np.sin(turned)]))]

    def structure(self, index) -> tuple:
        """Its kind, bodies and parameter names, its curve's form and (a polar curve's)
        expression: what its generated equation depends on."""
        tag = self.shape.canonical if self.form == "polar" else self.form
        return super().structure(index) + (tag,)

    @property
    def kernel_tag(self) -> str:
        return self.shape.canonical if self.form == "polar" else self.form
