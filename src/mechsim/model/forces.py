"""Applied loads: spring–dampers between body points, point forces and torques.

These hold data only; `mechsim.problem` evaluates them numerically.
"""

from __future__ import annotations

import numpy as np

from .checks import ModelError, name_or_default, scalar, scalar_or_function, vector2
from .bodies import Body


def _check_body(body, role: str, owner: str) -> Body:
    if not isinstance(body, Body):
        raise ModelError(f"{owner}: `{role}` must be a body, got {body!r}")
    return body


class Spring:
    """A linear spring–damper between point `at_a` of body_a and `at_b` of body_b.

    Points are global in the initial configuration. Tension f = k (l − l₀) + c l̇ acts along
    the line between the points; `rest_length` defaults to the initial distance.
    """

    def __init__(self, body_a: Body, body_b: Body, at_a, at_b, stiffness: float,
                 rest_length: float | None = None, damping: float = 0.0,
                 name: str | None = None):
        self.name = name_or_default(
            name, f"spring({getattr(body_a, 'name', '?')},{getattr(body_b, 'name', '?')})", "spring")
        owner = f"spring '{self.name}'"
        self.body_a = _check_body(body_a, "body_a", owner)
        self.body_b = _check_body(body_b, "body_b", owner)
        self.at_a = vector2(at_a, "at_a", owner)
        self.at_b = vector2(at_b, "at_b", owner)
        self.stiffness = scalar(stiffness, "stiffness", owner, nonnegative=True)
        self.damping = scalar(damping, "damping", owner, nonnegative=True)
        initial = float(np.hypot(*(self.at_b - self.at_a)))
        self.rest_length = (initial if rest_length is None
                            else scalar(rest_length, "rest_length", owner, nonnegative=True))

    @property
    def bodies(self):
        return (self.body_a, self.body_b)


class Force:
    """A force of fixed global direction on `body` at the global point `at` (default: the
    body's frame origin, its centre of mass). `force` is a 2-vector or a callable t -> 2-vector.
    """

    def __init__(self, body: Body, force, at=None, name: str | None = None):
        self.name = name_or_default(name, f"force({getattr(body, 'name', '?')})", "force")
        owner = f"force '{self.name}'"
        self.body = _check_body(body, "body", owner)
        self.force = force if callable(force) else vector2(force, "force", owner)
        self.at = body.position.copy() if at is None else vector2(at, "at", owner)

    @property
    def bodies(self):
        return (self.body,)


class Torque:
    """A torque on `body` (N·m, counter-clockwise positive): a constant or a callable of t."""

    def __init__(self, body: Body, torque, name: str | None = None):
        self.name = name_or_default(name, f"torque({getattr(body, 'name', '?')})", "torque")
        owner = f"torque '{self.name}'"
        self.body = _check_body(body, "body", owner)
        self.torque = scalar_or_function(torque, "torque", owner)

    @property
    def bodies(self):
        return (self.body,)


def load_points(ld) -> list:
    """(body, global point) of each attachment of a spring or force."""
    if isinstance(ld, Spring):
        return [(ld.body_a, ld.at_a), (ld.body_b, ld.at_b)]
    if isinstance(ld, Force):
        return [(ld.body, ld.at)]
    return []
