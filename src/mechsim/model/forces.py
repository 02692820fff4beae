"""Applied loads: spring–dampers between body points, torsion spring–dampers, point forces
and torques.

These hold data only; `mechsim.problem` evaluates them numerically. A force or torque is a
constant or a function, called with

- `t` (the default): `f(t)`;
- `joint=j`: `f(t, s, ṡ)` with the coordinate s of joint j (its relative angle or slide)
  and its rate, e.g. a motor's torque–speed curve `lambda t, angle, rate: 12*(1 - rate/300)`;
- `state=True`: `f(t, q, v)` with copies of all coordinates and velocities (in the order of
  `Mechanism.coordinate_names`).

Its power enters the energy balance like any load's.
"""

from __future__ import annotations

import inspect

import numpy as np

from . import parameters as dual
from .checks import (ModelError, name_or_default, scalar, scalar_exact, scalar_or_function,
                     vector2, vector2_exact)
from .bodies import Body
from .joints import Joint


class TimeLaw:
    """A load given as expressions of the time t, as a scene writes it (`torque =
    "2*sin(3*t)"`): one expression (a torque) or two (a force's x and y), each parsed by
    `mechsim.model.expressions` (never executed). Called with t it gives the torque, or the
    force as a 2-vector; `texts` are the expressions (what a saved scene holds)."""

    def __init__(self, texts, owner: str):
        from .expressions import parse
        self.laws = [parse(text, {"t"}, f"{owner} `{'torque' if len(texts) == 1 else 'force'}`")
                     for text in texts]
        self.texts = [law.text for law in self.laws]

    def __call__(self, t):
        values = [law.value(t=t) for law in self.laws]
        return values[0] if len(values) == 1 else np.array(values)

    def __repr__(self):
        return f"TimeLaw({', '.join(self.texts)})"


def _check_body(body, role: str, owner: str) -> Body:
    if not isinstance(body, Body):
        raise ModelError(f"{owner}: `{role}` must be a body, got {body!r}")
    return body


class _Constants:
    """Stiffness, damping and a rest value (`rest_name`: a length, or an angle) that take
    Parameters: their floats for the runs, the numbers as given kept (`exact_numbers`)
    and taken again after the Parameters took new values (`refresh_numbers`)."""
    rest_name = "rest_length"
    owner_kind = "spring"

    def _take_constants(self, owner, stiffness, damping, rest, initial) -> None:
        """Checked (a ModelError naming `owner` and the argument); `rest` None: `initial`
        (the rest value as built)."""
        self.exact_stiffness = scalar_exact(stiffness, "stiffness", owner, nonnegative=True)[1]
        self.exact_damping = scalar_exact(damping, "damping", owner, nonnegative=True)[1]
        self.exact_rest = initial if rest is None else scalar_exact(
            rest, self.rest_name, owner, nonnegative=self.rest_name == "rest_length")[1]
        self._floats(owner)

    def _floats(self, owner) -> None:
        self.stiffness = scalar(dual.value_of(self.exact_stiffness), "stiffness", owner,
                                nonnegative=True)
        self.damping = scalar(dual.value_of(self.exact_damping), "damping", owner,
                              nonnegative=True)
        setattr(self, self.rest_name,
                scalar(dual.value_of(self.exact_rest), self.rest_name, owner,
                       nonnegative=self.rest_name == "rest_length"))

    def exact_numbers(self) -> list:
        """Stiffness, damping and rest value as given (Parameters kept)."""
        return [self.exact_stiffness, self.exact_damping, self.exact_rest]

    def refresh_numbers(self) -> None:
        """Their values again, after the Parameters took new ones."""
        self._floats(f"{self.owner_kind} '{self.name}'")


class Spring(_Constants):
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
        self._take_constants(owner, stiffness, damping, rest_length,
                             float(np.hypot(*(self.at_b - self.at_a))))

    @property
    def bodies(self):
        return (self.body_a, self.body_b)


def _inputs(function, joint, state, owner) -> tuple[str, Joint | None]:
    """What a load's function is called with ("t", "joint" or "state"), checked against its
    signature now, so a function that cannot take them is refused before any work."""
    if joint is not None and state:
        raise ModelError(f"{owner}: give either `joint` or `state=True`, not both")
    if joint is not None and not isinstance(joint, Joint):
        raise ModelError(f"{owner}: `joint` must be a joint, got {joint!r:.60}")
    if joint is not None and type(joint).coordinate is Joint.coordinate:
        raise ModelError(f"{owner}: a {joint.kind} joint has no coordinate to read")
    if not isinstance(state, (bool, np.bool_)):
        raise ModelError(f"{owner}: `state` must be true or false, got {state!r:.60}")
    kind = "joint" if joint is not None else "state" if state else "t"
    if not callable(function):
        if kind != "t":
            raise ModelError(f"{owner}: `joint` and `state` need a function, got a constant")
        return kind, joint
    arguments = {"t": ("t",), "joint": ("t", "s", "rate"), "state": ("t", "q", "v")}[kind]
    try:
        inspect.signature(function).bind(*arguments)
    except TypeError:
        raise ModelError(f"{owner}: its function must take ({', '.join(arguments)})"
                         + ("" if kind == "t" else f" (with `{kind}`)")) from None
    except ValueError:
        pass                        # no signature to read (a builtin): taken on trust
    return kind, joint


class Force:
    """A force of fixed global direction on `body` at the global point `at` (default: the
    body's frame origin, its centre of mass). `force` is a 2-vector or a function giving one:
    of t, of (t, s, ṡ) of a `joint`, or of (t, q, v) with `state=True` (module docstring);
    or two expressions in t (`["0", "50*sin(10*t)"]`, a `TimeLaw`: saved with the model).
    A constant force's components may be Parameters (a payload, a preload: the
    sensitivities differentiate through them).
    """

    def __init__(self, body: Body, force, at=None, name: str | None = None, *,
                 joint: Joint | None = None, state: bool = False):
        self.name = name_or_default(name, f"force({getattr(body, 'name', '?')})", "force")
        owner = f"force '{self.name}'"
        self.body = _check_body(body, "body", owner)
        if isinstance(force, (list, tuple)) and len(force) == 2 and \
                any(isinstance(x, str) for x in force):
            force = TimeLaw([x if isinstance(x, str) else float(x) for x in force], owner)
        self.exact_force = ()
        if callable(force):
            self.force = force
        else:
            self.force, exact = vector2_exact(force, "force", owner)
            self.exact_force = tuple(exact)
        self.at = body.position.copy() if at is None else vector2(at, "at", owner)
        self.inputs, self.joint = _inputs(force, joint, state, owner)

    @property
    def bodies(self):
        return (self.body,)

    def exact_numbers(self) -> list:
        """A constant force's components as given (Parameters kept); none for a function."""
        return list(self.exact_force)

    def refresh_numbers(self) -> None:
        """A constant force's components again, after the Parameters took new values."""
        if self.exact_force:
            self.force = vector2(dual.values(self.exact_force), "force",
                                 f"force '{self.name}'")


class Torque:
    """A torque on `body` (N·m, counter-clockwise positive): a constant or a function of t,
    of (t, s, ṡ) of a `joint`, or of (t, q, v) with `state=True` (module docstring); or an
    expression in t (`"2*sin(3*t)"`, a `TimeLaw`: saved with the model). A constant
    torque may be a Parameter."""

    def __init__(self, body: Body, torque, name: str | None = None, *,
                 joint: Joint | None = None, state: bool = False):
        self.name = name_or_default(name, f"torque({getattr(body, 'name', '?')})", "torque")
        owner = f"torque '{self.name}'"
        self.body = _check_body(body, "body", owner)
        if isinstance(torque, str):
            torque = TimeLaw([torque], owner)
        self.exact_torque = ()
        if callable(torque):
            self.torque = scalar_or_function(torque, "torque", owner)
        else:
            self.torque, exact = scalar_exact(torque, "torque", owner)
            self.exact_torque = (exact,)
        self.inputs, self.joint = _inputs(torque, joint, state, owner)

    @property
    def bodies(self):
        return (self.body,)

    def exact_numbers(self) -> list:
        """A constant torque as given (a Parameter kept); none for a function."""
        return list(self.exact_torque)

    def refresh_numbers(self) -> None:
        """A constant torque again, after the Parameters took new values."""
        if self.exact_torque:
            self.torque = scalar(dual.value_of(self.exact_torque[0]), "torque",
                                 f"torque '{self.name}'")


class RotationalSpring(_Constants):
    """A torsion spring–damper between body_a and body_b (either may be the ground).

    The torque on body_b is −k (θ_b − θ_a − rest_angle) − c (ω_b − ω_a), the opposite on
    body_a; θ is a body's frame angle (a beam's floating frame). `rest_angle` defaults to
    the relative angle as built, so the spring is relaxed in the initial configuration.
    """
    rest_name = "rest_angle"
    owner_kind = "rotational spring"

    def __init__(self, body_a: Body, body_b: Body, stiffness: float, damping: float = 0.0,
                 rest_angle: float | None = None, name: str | None = None):
        self.name = name_or_default(
            name, f"rotational_spring({getattr(body_a, 'name', '?')},"
                  f"{getattr(body_b, 'name', '?')})", "rotational spring")
        owner = f"rotational spring '{self.name}'"
        self.body_a = _check_body(body_a, "body_a", owner)
        self.body_b = _check_body(body_b, "body_b", owner)
        if body_a is body_b:
            raise ModelError(f"{owner}: connects body '{body_a.name}' to itself")
        self.rest_from_bodies = rest_angle is None
        self._take_constants(owner, stiffness, damping, rest_angle,
                             float(body_b.angle - body_a.angle))

    @property
    def bodies(self):
        return (self.body_a, self.body_b)


def load_points(ld) -> list:
    """(body, global point) of each attachment of a spring or force."""
    if isinstance(ld, Spring):
        return [(ld.body_a, ld.at_a), (ld.body_b, ld.at_b)]
    if isinstance(ld, Force):
        return [(ld.body, ld.at)]
    return []
