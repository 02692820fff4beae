"""End stops: unilateral limits on a joint's coordinate (`mechsim.engineering.impacts` runs them)."""

from __future__ import annotations

from .checks import ModelError, name_or_default, scalar
from .joints import Joint, coordinate_joint


class Stop:
    """A limit on `joint`'s coordinate (the relative angle of a revolute, the slide of a
    prismatic from where it was built, as `SimulationResult.joint_coordinate` reads it):
    `lower` ≤ s ≤ `upper` (either may be None). Reaching one is an impact, located in
    time to 1e-13 s: Newton's law with `restitution` e turns the joint's rate s' into
    −e s' through the mechanism's constrained mass matrix (every joint holds through the
    impact, an impulse its reactions carry), and the kinetic energy lost is recorded
    (`SimulationResult.impacts`). An impact slower than `rest_speed` (rad/s or m/s), or
    any with e = 0, leaves the joint resting on the stop: held there as a constraint
    while the stop pushes, let go when it would have to pull."""

    kind = "stop"

    def __init__(self, joint: Joint, lower=None, upper=None, restitution: float = 0.5,
                 rest_speed: float = 1e-3, name: str | None = None):
        self.joint = coordinate_joint(joint, "stop", "limit")
        self.name = name_or_default(name, f"stop({joint.name})", "stop")
        owner = f"stop '{self.name}'"
        self.lower = None if lower is None else scalar(lower, "lower", owner)
        self.upper = None if upper is None else scalar(upper, "upper", owner)
        if self.lower is None and self.upper is None:
            raise ModelError(f"{owner}: give `lower`, `upper` or both")
        if self.lower is not None and self.upper is not None and not self.lower < self.upper:
            raise ModelError(f"{owner}: `lower` ({self.lower:g}) must be below `upper` "
                             f"({self.upper:g})")
        self.restitution = scalar(restitution, "restitution", owner, nonnegative=True)
        if self.restitution > 1.0:
            raise ModelError(f"{owner}: `restitution` must be between 0 and 1, got "
                             f"{self.restitution:g}")
        self.rest_speed = scalar(rest_speed, "rest_speed", owner, positive=True)

    def limits(self):
        """[(+1, lower), (−1, upper)] for the limits it has: s − lower ≥ 0, upper − s ≥ 0."""
        return [(sign, value) for sign, value in ((1.0, self.lower), (-1.0, self.upper))
                if value is not None]

    def check_start(self, s: float) -> None:
        """ModelError where the joint starts beyond a limit (by more than 1e-9)."""
        for sign, value in self.limits():
            if sign * (s - value) < -1e-9 * max(1.0, abs(value)):
                side = "below `lower`" if sign > 0 else "above `upper`"
                raise ModelError(f"stop '{self.name}': joint '{self.joint.name}' starts at "
                                 f"{s:.9g}, {side} = {value:g}")

    def __repr__(self):
        return (f"Stop({self.joint.name!r}, lower={self.lower}, upper={self.upper}, "
                f"restitution={self.restitution:g})")

