"""Drivers: a prescribed joint coordinate as a function of time."""

from __future__ import annotations

from ._checks import ModelError
from .joints import Joint


class Driver:
    """Prescribe the coordinate of `joint` (relative angle of a revolute, translation of a
    prismatic) as `expression` in t, measured from its value in the initial configuration:

        coordinate(q) − coordinate(q₀) = f(t)

    so `Driver(crank_pivot, "150*t")` turns the crank at 150 rad/s from where it was drawn. If
    f(0) ≠ 0, `Mechanism.assemble` moves the joint there. `expression` is any sympy-parsable
    string in `t` (or a number).
    """

    kind = "driver"
    parameter_names = ("offset",)
    equation_labels = ("coordinate",)

    def __init__(self, joint: Joint, expression, name: str | None = None):
        if not isinstance(joint, Joint):
            raise ModelError(f"driver: `joint` must be a joint, got {joint!r}")
        if type(joint).coordinate is Joint.coordinate:
            raise ModelError(f"driver on joint '{joint.name}': a {joint.kind} joint has no "
                             "coordinate to prescribe")
        if isinstance(expression, (int, float)):
            expression = repr(float(expression))
        if not isinstance(expression, str) or not expression.strip():
            raise ModelError(f"driver on joint '{joint.name}': `expression` must be a "
                             f"non-empty string in t, got {expression!r}")
        self.joint = joint
        self.expression = expression.strip()
        self.name = name or f"driver({joint.name})"

    @property
    def n_equations(self) -> int:
        return 1

    def parameter_values(self):
        return (self.joint.initial_coordinate(),)

    def equations(self, ctx, p):
        f = ctx.time_function(self.expression, owner=f"driver '{self.name}'")
        return [self.joint.coordinate(ctx, ctx.parameters(self.joint)) - p["offset"] - f]

    def structure(self) -> tuple:
        return (self.kind, self.name, self.joint.name, self.expression)

    def __repr__(self):
        return f"Driver({self.joint.name!r}, {self.expression!r})"
