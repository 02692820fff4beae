"""Drivers: a prescribed joint coordinate as a function of time."""

from __future__ import annotations

from .checks import ModelError, name_or_default
from .expressions import parse
from .joints import Joint


class Driver:
    """Prescribe the coordinate of `joint` (relative angle of a revolute, translation of a
    prismatic) as `expression` in t, measured from its value in the initial configuration:

        coordinate(q) − coordinate(q₀) = f(t)

    so `Driver(crank_pivot, "150*t")` turns the crank at 150 rad/s from where it was drawn. If
    f(0) ≠ 0, `Mechanism.assemble` moves the joint there. `expression` is a number or an
    arithmetic expression in `t` (`mechsim.model.expressions`: numbers, t, pi, e,
    ``+ − * / **``, parentheses and sin, cos, tan, asin, acos, atan, atan2, sinh, cosh, tanh,
    exp, log, sqrt, abs, hypot, radians, degrees). It is parsed here, not evaluated by
    Python: anything else, an unknown name among them, is a ModelError naming the driver.
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
        self.joint = joint
        self.name = name_or_default(name, f"driver({joint.name})", "driver")
        self.law = parse(expression, {"t"}, f"driver '{self.name}' `expression`")
        self.expression = self.law.text

    def value(self, t: float) -> float:
        """f(t), the prescribed change of the joint's coordinate (float arithmetic)."""
        return self.law.value(t=t)

    @property
    def n_equations(self) -> int:
        return 1

    def parameter_values(self):
        return (self.joint.initial_coordinate(),)

    @property
    def law_constants(self) -> list[float]:
        """The numbers of its law (`Expression.constants`): parameters of the compiled model,
        so that drivers whose laws differ only in them (a sweep over crank speeds) share one
        compiled structure."""
        return self.law.constants()

    def equations(self, ctx, p):
        law = self.law.to_sympy({"t": ctx.t}, constants=ctx.law_constants(self))
        return [self.displacement(ctx, p) - law]

    def displacement(self, ctx, p):
        """The joint's coordinate less its initial value: the equation's part that does not
        depend on time (Φ = displacement − f(t)). The type kernels of `mechsim.assembly`
        differentiate it once for every driver of its kind and take f from the law."""
        return self.joint.coordinate(ctx, ctx.parameters(self.joint)) - p["offset"]

    def structure(self, index) -> tuple:
        """Its kind, the driven joint's position `index(joint)` and its law's template (its
        numbers are parameters: `law_constants`)."""
        return (self.kind, index(self.joint), self.law.template)

    def __repr__(self):
        return f"Driver({self.joint.name!r}, {self.expression!r})"
