"""MechanismModel: the container users build, declarative (`mechsim.build` turns it into
a NumericProblem; `mechsim.Mechanism` adds the analyses on it)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .checks import ModelError, name_or_default, vector2
from .bodies import Body, Ground
from .channels import Channel, channel_names
from .drivers import Driver
from .forces import Force, RotationalSpring, Spring, Torque, load_points
from .gears import Gear
from .friction import Friction
from .stops import Stop
from .joints import Joint
from .parameters import finite_value, gradient, leaves, parameter_names, refresh


class AssemblyError(ModelError):
    """The initial configuration cannot be made to satisfy the constraints."""


@dataclass
class DofReport:
    """Degrees of freedom from the rank of Φ_q (Grübler counts are wrong for special
    geometry, the rank is not)."""
    coordinates: int
    constraints: int
    rank: int
    dof: int
    redundant: int
    redundant_joints: list[str] = field(default_factory=list)
    singular_values: np.ndarray | None = None

    def __str__(self):
        s = (f"{self.coordinates} coordinates, {self.constraints} constraint equations, "
             f"rank {self.rank}: {self.dof} degree(s) of freedom")
        if self.redundant:
            s += (f"; {self.redundant} redundant constraint equation(s) among "
                  f"{', '.join(repr(j) for j in self.redundant_joints)}")
        return s


@dataclass
class AssemblyReport:
    q: np.ndarray
    v: np.ndarray
    iterations: int
    position_change: float      # max |Δq|
    velocity_change: float      # max |Δv|
    residual: float             # max |Φ| after assembly

    def __str__(self):
        return (f"assembled in {self.iterations} Newton iteration(s): max |Δq| = "
                f"{self.position_change:.3g}, max |Δv| = {self.velocity_change:.3g}, "
                f"max |Φ| = {self.residual:.3g}")


class MechanismModel:
    """A planar mechanism as the user builds it: bodies, joints, drivers and loads, checked
    as they are added. What it does (build, assemble, simulate, analyse) is
    `mechsim.Mechanism`, its subclass."""

    def __init__(self, name: str = "mechanism", gravity=(0.0, -9.81)):
        self.name = name_or_default(name, "mechanism", "mechanism")
        self.gravity = vector2(gravity, "gravity", f"mechanism '{name}'")
        self.ground = Ground()
        self.bodies: list[Body] = []          # moving bodies, in coordinate order
        self.joints: list[Joint] = []
        self.drivers: list[Driver] = []
        self.gears: list[Gear] = []          # gear pairs between joints' coordinates
        self.stops: list[Stop] = []          # end stops on joints' coordinates
        self.frictions: list[Friction] = []  # dry friction in joints
        self.loads: list = []                 # springs, rotational springs, forces, torques
        self.channels: list[Channel] = []    # the user's recorded quantities
        self.speeds: dict[str, float] = {}   # joint name -> its prescribed initial rate
        self._problem = None
        self._build = None                    # the build asked for by `problem(build=)`
        self._assembled: AssemblyReport | None = None
        self._state = None               # (q, v) set by `set_state`: where assembly starts
        self._lookup = None                   # see `_names`

    # --- building ----------------------------------------------------------------------------
    def add(self, item):
        """Add a body, joint, driver, gear, stop, friction, spring, rotational spring, force,
        torque or channel; returns it. A channel's expression is checked against the bodies and joints added
        before it; it changes no equation (nothing is rebuilt for it)."""
        owner = f"mechanism '{self.name}'"
        if isinstance(item, Channel):
            if any(c.name == item.name for c in self.channels):
                raise ModelError(f"{owner}: a channel named '{item.name}' exists already")
            item.parsed(channel_names(self))
            self.channels.append(item)
            return item
        if isinstance(item, Body):
            if isinstance(item, Ground):
                raise ModelError(f"{owner}: the ground exists already as `mechanism.ground`")
            if item.name in self._names()[0]:
                raise ModelError(f"{owner}: a body named '{item.name}' exists already")
            self.bodies.append(item)
            self._noted(item)
        elif isinstance(item, Joint):
            self._check_names(item)
            for body in (item.body_a, item.body_b):
                self._check_member(body, f"{item.kind} joint '{item.name}'")
            self.joints.append(item)
            self._noted(item)
        elif isinstance(item, Driver):
            self._check_joint(item, "driver")
            if any(d.joint is item.joint for d in self.drivers):
                raise ModelError(f"driver '{item.name}': joint '{item.joint.name}' is driven already")
            self._check_names(item)
            self.drivers.append(item)
            self._noted(item)
        elif isinstance(item, Stop):
            self._check_joint(item, "stop")
            if any(d.joint is item.joint for d in self.drivers):
                raise ModelError(f"stop '{item.name}': joint '{item.joint.name}' is driven; "
                                 "a driven joint goes where its law says")
            self.stops.append(item)             # its holding force is part of the problem
        elif isinstance(item, Friction):
            self._check_joint(item, "friction")
            if any(f.joint is item.joint for f in self.frictions):
                raise ModelError(f"friction '{item.name}': joint '{item.joint.name}' has "
                                 "friction already")
            self.frictions.append(item)
        elif isinstance(item, Gear):
            for joint in item.joints:
                if not any(j is joint for j in self.joints):
                    raise ModelError(f"gear '{item.name}': joint '{joint.name}' is not in "
                                     f"{owner}; add the joint first")
            self._check_names(item)
            self.gears.append(item)
            self._noted(item)
        elif isinstance(item, (Spring, Force, Torque, RotationalSpring)):
            for body in item.bodies:
                self._check_member(body, f"'{item.name}'")
            joint = getattr(item, "joint", None)
            if joint is not None and not any(j is joint for j in self.joints):
                raise ModelError(f"'{item.name}': joint '{joint.name}' is not in {owner}; "
                                 "add the joint first")
            for body, at in load_points(item):
                body.attachment_values(body.local_point(at), f"'{item.name}'")
            self.loads.append(item)
        else:
            raise ModelError(f"{owner}: cannot add {item!r}; expected a body, joint, driver, "
                             "gear, stop, friction, spring, rotational spring, force, torque "
                             "or channel")
        self._problem = None
        self._assembled = None
        self._state = None
        return item

    def _check_joint(self, item, what: str) -> None:
        """ModelError where the joint `item` acts on is not in this mechanism."""
        if not any(j is item.joint for j in self.joints):
            raise ModelError(f"{what} '{item.name}': joint '{item.joint.name}' is not in "
                             f"mechanism '{self.name}'; add the joint first")

    def _all_bodies(self):
        return [self.ground] + self.bodies

    def _lookup_key(self):
        """What tells whether the lists changed since `_names` looked: their lengths and
        last items."""
        return tuple((len(x), id(x[-1]) if x else None)
                     for x in (self.bodies, self.joints, self.drivers, self.gears))

    def _names(self):
        """(body names, ids of the bodies, joint and driver names), kept current by `add`
        and rebuilt where the lists were changed otherwise: building a mechanism costs
        O(n), not a scan of every earlier item per item."""
        key = self._lookup_key()
        if self._lookup is None or self._lookup[0] != key:
            bodies = self._all_bodies()
            self._lookup = (key, {b.name for b in bodies}, {id(b) for b in bodies},
                            {x.name for x in self.constraint_items})
        return self._lookup[1:]

    def _noted(self, item):
        """Add the item just appended to the lookup of `_names` (current before it)."""
        _, names, ids, joint_names = self._lookup
        if isinstance(item, Body):
            names.add(item.name)
            ids.add(id(item))
        else:
            joint_names.add(item.name)
        self._lookup = (self._lookup_key(), names, ids, joint_names)

    def _check_member(self, body, who):
        if id(body) not in self._names()[1]:
            raise ModelError(f"{who}: body '{body.name}' is not in mechanism '{self.name}'; "
                             "add the body first")

    def _check_names(self, item):
        if item.name in self._names()[2]:
            raise ModelError(f"a joint, driver or gear named '{item.name}' exists already; "
                             "give it a `name=`")

    def body(self, name: str) -> Body:
        for b in self._all_bodies():
            if b.name == name:
                return b
        raise KeyError(f"mechanism '{self.name}' has no body '{name}'; bodies: "
                       f"{', '.join(b.name for b in self._all_bodies())}")

    def driver(self, driver) -> Driver:
        """The driver given as itself or by name; KeyError listing the drivers."""
        for d in self.drivers:
            if d is driver or d.name == getattr(driver, "name", driver):
                return d
        raise KeyError(f"mechanism '{self.name}' has no driver {driver!r:.60}; drivers: "
                       f"{', '.join(d.name for d in self.drivers) or '(none)'}")

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(f"mechanism '{self.name}' has no joint '{name}'; joints: "
                       f"{', '.join(j.name for j in self.joints) or '(none)'}")

    # --- coordinates ---------------------------------------------------------------------------
    @property
    def coordinate_names(self) -> list[str]:
        return [f"{b.name}.{c}" for b in self.bodies for c in b.coordinate_names]

    def initial_coordinates(self) -> np.ndarray:
        return np.concatenate([b.initial_coordinates for b in self.bodies]) if self.bodies \
            else np.zeros(0)

    def initial_velocities(self) -> np.ndarray:
        return np.concatenate([b.initial_velocities for b in self.bodies]) if self.bodies \
            else np.zeros(0)

    def initial_partials(self, names) -> tuple[np.ndarray, np.ndarray]:
        """(∂q/∂k, ∂v/∂k), each (n, K), of the initial coordinates and velocities as given
        (before assembly) to the Parameters `names`."""
        states = [b.exact_initial_state() for b in self.bodies]
        return (gradient([x for q, _ in states for x in q], names),
                gradient([x for _, v in states for x in v], names))

    # --- the numeric problem -----------------------------------------------------------------
    def structure(self) -> dict:
        """What the generated code depends on (not parameter values, not names): the cache
        key. Bodies and joints are referred to by position."""
        index = {id(self.ground): -1, **{id(b): i for i, b in enumerate(self.bodies)},
                 **{id(j): k for k, j in enumerate(self.joints)}}
        return {"bodies": [(type(b).__name__, list(b.coordinate_names)) for b in self.bodies],
                "constraints": [list(item.structure(lambda x: index[id(x)]))
                                for item in self.constraint_items]}

    def _exact_numbers(self) -> list:
        """Every number of the bodies and joints that may be a Parameter or computed from
        them (`mechsim.model.parameters`)."""
        return [x for owner in self._parametrized() for x in owner.exact_numbers()]

    def _parametrized(self) -> list:
        """Bodies, joints, drivers, gears, springs, loads and frictions: what holds numbers
        that may be Parameters."""
        return self.bodies + self.joints + self.drivers + self.gears + \
            [ld for ld in self.loads if hasattr(ld, "exact_numbers")] + \
            list(self.frictions)

    def parameter_blind_loads(self) -> list[str]:
        """The loads that depend on Parameters but do not carry their derivatives (a
        spring's or force's point on a body whose frame moves with a Parameter, a torsion
        spring relaxed at such bodies' angles): what depends on the loads (a simulation,
        the multipliers of a driven motion) refuses sensitivities through them, naming
        them."""
        return [ld.name for ld in self.loads if _blind_load(ld)]

    def parameter_blind(self) -> list[str]:
        """The constraints that depend on Parameters but do not carry their derivatives
        into the equations (a gear, a point on a curve on a body whose frame is a
        Parameter's): sensitivities through them are refused, naming them."""
        out = []
        for item in self.constraint_items:
            if getattr(item, "carries_parameters", False):
                continue
            joints = list(getattr(item, "joints", ()) or ())
            joints += [j for j in (getattr(item, "joint", None),) if j is not None]
            bodies = [b for b in (getattr(item, "body_a", None), getattr(item, "body_b", None),
                                  getattr(item, "carrier", None)) if b is not None]
            bodies += [b for j in joints for b in (j.body_a, j.body_b)]
            numbers = [x for b in bodies for x in b.exact_numbers()]
            numbers += [x for j in joints for x in j.exact_numbers()]
            if leaves(numbers):
                out.append(item.name)
        return out

    @property
    def parameters(self) -> list[str]:
        """The names of the Parameters (`mechsim.model.parameters`) this mechanism's
        numbers depend on, sorted: its bodies' frames, masses and inertias and its joints'
        geometry."""
        return sorted(leaves(self._exact_numbers()))

    def parameter_values(self) -> dict[str, float]:
        """name -> present value of each Parameter of `parameters`."""
        return {name: p.value for name, p in sorted(leaves(self._exact_numbers()).items())}

    def set_parameters(self, **values) -> None:
        """Give the named Parameters new values and compute every number of the model
        that depends on them again (bodies' frames, masses and inertias, joints' points and
        axes): the generated equations take the geometry as parameters, so the next run
        needs no new build. ModelError naming what is wrong, before anything changes, for
        an unknown name or a value that is not a finite number; where the new values make
        the model invalid (a zero axis, a point off a beam's nodes), the old values are
        restored and a ModelError says why."""
        numbers = self._exact_numbers()
        found = leaves(numbers)
        for name, value in values.items():
            if name not in found:
                raise ModelError(f"mechanism '{self.name}': set_parameters names {name!r}, which "
                                 f"is no Parameter of it; its parameters: "
                                 f"{', '.join(sorted(found)) or '(none)'}")
            finite_value(value, name)
        before = {name: found[name].value for name in values}
        try:
            self._take(found, values, numbers)
        except (ModelError, ArithmeticError, ValueError) as exc:
            self._take(found, before, numbers)
            raise ModelError(f"mechanism '{self.name}': the values {values} make it invalid "
                             f"({exc}); the old values are kept") from exc

    def _take(self, found, values, numbers) -> None:
        """Set the Parameters `values` and compute the model's numbers again."""
        for name, value in values.items():
            found[name].set(value)
        refresh(numbers)
        for owner in self._parametrized():
            owner.refresh_numbers()
        self._problem = None
        self._assembled = None
        self._state = None

    @property
    def constraint_items(self) -> list:
        """Everything that writes rows of Φ, in row order: joints, drivers, gears."""
        return self.joints + self.drivers + self.gears

    def placement_warnings(self) -> list[str]:
        """What is likely a mistake in how the mechanism is put together, though it can be
        simulated: a body joined to nothing (it moves freely: a joint left out?), and a
        pin whose point (global `at`) lies farther from each of its moving bodies than
        the mechanism's own size (the largest distance between two bodies' frames, or the
        largest body: √(12 I/m), a rod's length; a beam's length) — a point typed wrong.
        Checked where there are two moving bodies or more. `Mechanism.problem` warns of
        each once."""
        out = []
        joined = {id(b) for item in self.joints + self.loads
                  for b in (getattr(item, "body_a", None), getattr(item, "body_b", None),
                            getattr(item, "body", None)) if b is not None}
        for body in self.bodies:
            if id(body) not in joined:
                out.append(f"body '{body.name}' is joined to nothing: it moves freely (a "
                           "joint left out?)")
        if len(self.bodies) < 2:
            return out
        frames = np.array([b.position for b in self.bodies])
        apart = float(np.max(np.hypot(*(frames[:, None, :] - frames[None, :, :]).transpose(
            2, 0, 1))))
        sizes = [float(getattr(b, "length", 0.0)) or
                 math.sqrt(12.0 * b.inertia / b.mass) for b in self.bodies]
        size = max(apart, *sizes)
        for joint in self.joints:
            # A pin's point is on its bodies; a slider's only places its axis, anywhere.
            at = getattr(joint, "at", None) if joint.kind == "revolute" else None
            moving = [b for b in (joint.body_a, joint.body_b) if b.coordinate_names]
            if at is None or not moving:
                continue
            far = [float(np.hypot(*(at - b.position))) for b in moving]
            if min(far) > size:
                where = " and ".join(f"{d:.3g} m from body '{b.name}'"
                                     for d, b in zip(far, moving))
                out.append(f"joint '{joint.name}' is at ({at[0]:.4g}, {at[1]:.4g}), {where}: "
                           f"farther than the mechanism's own size ({size:.3g} m); check its "
                           "`at` (a global point in the initial configuration)")
        return out

    def set_speed(self, joint, rate: float) -> None:
        """Start the joint's coordinate (relative angle of a revolute, slide of a prismatic)
        at `rate` [rad/s or m/s]: assembly then finds the velocities of every body that move
        it so (nearest the bodies' given velocities in the mass metric), instead of
        re-projecting body velocities that do not fit the joints. A driven joint's rate is
        its driver's."""
        owner = f"mechanism '{self.name}': set_speed"
        joint = self.joint(joint) if isinstance(joint, str) else joint
        if not any(j is joint for j in self.joints):
            raise ModelError(f"{owner}: {joint!r} is not a joint of this mechanism")
        if type(joint).coordinate is Joint.coordinate:
            raise ModelError(f"{owner}: a {joint.kind} joint has no rate to set")
        if any(d.joint is joint for d in self.drivers):
            raise ModelError(f"{owner}: joint '{joint.name}' is driven; its driver sets its rate")
        from .checks import scalar
        self.speeds[joint.name] = scalar(rate, "rate", f"{owner}({joint.name!r})")
        self._assembled = None

    def save(self, path):
        """Write the mechanism as a scene (`mechsim.app.scene`'s schema; JSON where `path` ends
        in .json, else TOML): bodies, joints, drivers, springs, constant forces and torques,
        joint speeds, every number exact; `mechsim.load_mechanism(path)` builds it again. A
        ModelError names what a scene cannot hold (a load given as a function, a beam that
        starts deformed). A state set by `set_state` is not part of the model, and
        Parameters are written as their present values (the scene holds numbers). Returns
        the path."""
        from .scene_save import scene_data, write_scene
        return write_scene(scene_data(self), path)

    def check_tables(self, t_start, t_end) -> None:
        """ModelError naming the first driver given by a table (`TableLaw`) whose times do
        not cover [t_start, t_end]: its law is data, not defined beyond them."""
        for d in self.drivers:
            domain = getattr(d.law, "domain", None)
            if domain is None or t_end is None:
                continue
            lo, hi = domain
            slack = 1e-12 * max(1.0, abs(lo), abs(hi))
            if float(t_start) < lo - slack or float(t_end) > hi + slack:
                raise ModelError(f"driver '{d.name}' is given by {d.expression}; the run "
                                 f"asks for [{float(t_start):g}, {float(t_end):g}] s: give "
                                 "a table that covers it, or a shorter run")

    def __repr__(self):
        return (f"Mechanism({self.name!r}: {len(self.bodies)} bodies, {len(self.joints)} joints, "
                f"{len(self.drivers)} drivers, {len(self.loads)} loads)")


def _blind_load(ld) -> bool:
    """Does the load `ld` read numbers of the model that depend on Parameters (a body-fixed
    point, computed from its global point and a body frame that is a Parameter's, or a
    rest angle taken from such frames)?"""
    def moves(numbers) -> bool:
        flat = list(np.ravel(np.asarray(numbers, dtype=object)))
        return bool(np.any(gradient(flat, parameter_names(flat))))
    if any(moves(body.exact_local_point(at)) for body, at in load_points(ld)):
        return True
    return isinstance(ld, RotationalSpring) and ld.rest_from_bodies and \
        moves([b.exact_angle for b in ld.bodies])
