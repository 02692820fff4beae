"""Gear pairs: a constraint between the coordinates of two joints.

A spur pair meshes two gears turning on pins; a rack and pinion meshes a gear on a pin with
a rack sliding in a guide. Either way the pitch circles roll on each other without slip,
which ties the two joints' coordinates: their changes keep a fixed ratio. Written on the
joints' own coordinates (`Joint.coordinate`: relative angle of a revolute, slide of a
prismatic), so the pair works on any carrier, moving or not (a planetary stage), and its
equation is one row of Φ like any joint's.
"""

from __future__ import annotations

import math

import numpy as np

from . import parameters as dual
from .checks import ModelError, name_or_default, rotation, scalar
from .joints import Joint, coordinate_joint


def _number(value, what: str, owner: str, positive: bool = False):
    """`value` as given where it is a Parameter (or computed from one), else checked as a
    number (`scalar`); ModelError naming `owner` where it is not finite (or not positive)."""
    if not dual.is_exact(value):
        return scalar(value, what, owner, positive=positive)
    x = dual.value_of(value)
    if not math.isfinite(x) or (positive and not x > 0.0):
        raise ModelError(f"{owner}: `{what}` must be a finite{' positive' if positive else ''}"
                         f" number, got {x:g}")
    return value


class Gear:
    """A gear pair: `Gear.spur` (two gears on pins), `Gear.rack` (a pinion on a pin and a
    rack in a guide), or `Gear(joint_a, joint_b, ratio)`, a plain coupling of two joints'
    coordinates:

        s_b − s_b(0) = ratio · (s_a − s_a(0))

    The plain coupling acts on the joints' coordinates only (a torque, or a force along a
    guide): it moves the mechanism right but puts no load on the bearings. The spur pair
    and the rack are written on the gears' centres, so the tooth force also loads the
    pins and the guide as a real mesh does (`SimulationResult.gear_force`). Both joints
    must be in the mechanism before the gear. The ratio and the radii may be Parameters
    (`mechsim.model.parameters`): the gear carries their derivatives into its equation
    and `Mechanism.set_parameters` changes them without a build."""

    kind = "gear"
    form = "ratio"
    equation_labels = ("mesh",)
    parameter_names = ("ratio", "offset")
    internal = False
    # Its parameters carry the derivatives of Parameters in its numbers and its joints'
    # bodies' frames (`parameter_values`).
    carries_parameters = True

    def __init__(self, joint_a: Joint, joint_b: Joint, ratio: float, name: str | None = None):
        for joint in (joint_a, joint_b):
            coordinate_joint(joint, "gear", "gear")
        if joint_a is joint_b:
            raise ModelError(f"gear: couples joint '{joint_a.name}' to itself")
        self.joint_a, self.joint_b = joint_a, joint_b
        self.name = name_or_default(name, f"gear({joint_a.name},{joint_b.name})", "gear")
        self.owner = f"gear '{self.name}'"
        self.exact_ratio = _number(ratio, "ratio", self.owner)
        self.refresh_numbers()

    def exact_numbers(self) -> list:
        """Its ratio as given (Parameters kept; a spur pair's and a rack's from their
        radii)."""
        return [self.exact_ratio]

    def refresh_numbers(self) -> None:
        """Its numbers' values again, after the Parameters took new ones."""
        self.ratio = dual.value_of(self.exact_ratio)
        if self.ratio == 0.0:
            raise ModelError(f"{self.owner}: `ratio` must not be 0 (that locks joint "
                             f"'{self.joint_b.name}')")

    @staticmethod
    def spur(pin_a: Joint, pin_b: Joint, radius_a: float, radius_b: float,
             internal: bool = False, name: str | None = None, carrier=None) -> "SpurGear":
        """A spur pair (`SpurGear`)."""
        return SpurGear(pin_a, pin_b, radius_a, radius_b, internal, name, carrier)

    @staticmethod
    def rack(pin: Joint, slide: Joint, radius: float, name: str | None = None) -> "RackGear":
        """A rack and pinion (`RackGear`)."""
        return RackGear(pin, slide, radius, name)

    @property
    def joints(self) -> tuple[Joint, Joint]:
        return (self.joint_a, self.joint_b)

    @property
    def extra_bodies(self) -> list:
        """Bodies its equation reads besides its joints' (a planetary pair's arm)."""
        return []

    @property
    def n_equations(self) -> int:
        return 1

    def parameter_values(self):
        r = self.exact_ratio
        return self.finite((r, self.joint_b.exact_initial_coordinate()
                            - r * self.joint_a.exact_initial_coordinate()))

    def finite(self, values):
        if not all(math.isfinite(dual.value_of(x)) for x in values):
            raise ModelError(f"{self.owner}: its joints' initial coordinates are not finite")
        return values

    def equations(self, ctx, p):
        s_a = self.joint_a.coordinate(ctx, ctx.parameters(self.joint_a))
        s_b = self.joint_b.coordinate(ctx, ctx.parameters(self.joint_b))
        return [s_b - p["ratio"] * s_a - p["offset"]]

    def structure(self, index) -> tuple:
        """Its form, its joints' positions `index(joint)` and those of its extra bodies
        (radii and ratio are parameters)."""
        return (self.kind, self.form, index(self.joint_a), index(self.joint_b),
                [index(b) for b in self.extra_bodies])

    def __repr__(self):
        return f"{type(self).__name__}({self.joint_a.name!r}, {self.joint_b.name!r}, " \
               f"ratio={self.ratio:g})"


class _Meshed(Gear):
    """A pair on a carrier: by default the body both joints share (else `carrier`, the arm
    of a planetary stage that holds the line of centres); for each joint the side ("a" or
    "b") of the body that is not the gear and of its gear body (body_b, unless that is
    the carrier)."""

    def __init__(self, joint_a, joint_b, ratio, name, carrier=None):
        super().__init__(joint_a, joint_b, ratio, name)
        shared = [b for b in (joint_a.body_a, joint_a.body_b)
                  if b is joint_b.body_a or b is joint_b.body_b]
        if carrier is None and not shared:
            raise ModelError(f"{self.owner}: joints '{joint_a.name}' and '{joint_b.name}' "
                             "share no body: both must sit on the carrier (the ground, a "
                             "frame or an arm), or give the `carrier` (a planetary arm)")
        self.carrier = shared[0] if carrier is None else carrier
        self.carrier_given = carrier is not None      # (a saved scene names it then)
        self.side = {}
        for key, joint in (("a", joint_a), ("b", joint_b)):
            c = "a" if joint.body_a is self.carrier or joint.body_b is not self.carrier \
                else "b"
            self.side[key] = (c, "b" if c == "a" else "a")

    @property
    def extra_bodies(self) -> list:
        held = [b for j in self.joints for b in (j.body_a, j.body_b)]
        return [] if any(b is self.carrier for b in held) else [self.carrier]

    def carrier_angle(self, ctx, pa):
        ca = self.side["a"][0]
        if self.body("a", ca) is self.carrier:
            return ctx.angle(self.carrier, pa, ca)
        return ctx.angle(self.carrier)

    def body(self, key, role):
        joint = self.joint_a if key == "a" else self.joint_b
        return joint.body_a if role == "a" else joint.body_b

    def centre(self, key, role) -> np.ndarray:
        """The global point of joint `key`'s pin on its `role` body, as built."""
        joint = self.joint_a if key == "a" else self.joint_b
        body = self.body(key, role)
        local = joint.attachment_points()[0 if role == "a" else 1]
        return body.position + rotation(body.angle) @ np.asarray(local, float)

    def exact_centre(self, key, role) -> np.ndarray:
        """`centre` carrying the derivatives of Parameters (an object array of two)."""
        joint = self.joint_a if key == "a" else self.joint_b
        body = self.body(key, role)
        local = np.asarray(joint.exact_attachment_points()[0 if role == "a" else 1], object)
        return np.asarray(body.exact_position, object) + \
            dual.rotation(dual.lift(body.exact_angle)) @ local

    def pinion(self, ctx, pa):
        """(carrier's angle, gear a's centre, gear a's angle) in `ctx`."""
        ga = self.side["a"][1]
        gear = self.body("a", ga)
        return (self.carrier_angle(ctx, pa),
                ctx.point(gear, pa[f"{ga}x"], pa[f"{ga}y"], pa, ga), ctx.angle(gear, pa, ga))


class SpurGear(_Meshed):
    """A spur pair: the gear turning on revolute `pin_a` (pitch radius `radius_a`) meshes
    with the one on `pin_b`; both pins on one body, the carrier (the ground, a frame, an
    arm), or the gears on body_b of their pins and `carrier` the arm that holds their
    line of centres (a sun on the ground and a planet on the arm). External: the gears
    turn opposite ways, ω_b = −(r_a/r_b) ω_a relative to the carrier; `internal`: gear b
    is a ring around gear a, ω_b = (r_a/r_b) ω_a. Written on the line of centres φ
    (measured from the carrier, so the pair may turn with it): r_a (θ_a − φ) ± r_b (θ_b −
    φ) = const, whose multiplier is the tooth force along the pitch line, carried by both
    pins."""

    form = "spur"
    parameter_names = ("ra", "rb", "phi0", "offset")

    def __init__(self, pin_a: Joint, pin_b: Joint, radius_a: float, radius_b: float,
                 internal: bool = False, name: str | None = None, carrier=None):
        owner = f"gear '{name or 'spur'}'"
        ra = _number(radius_a, "radius_a", owner, positive=True)
        rb = _number(radius_b, "radius_b", owner, positive=True)
        self.exact_radii = (ra, rb)
        super().__init__(pin_a, pin_b, (ra if internal else -ra) / rb, name, carrier)
        for pin in (pin_a, pin_b):
            if pin.kind != "revolute":
                raise ModelError(f"{self.owner}: a spur pair turns on pins; joint "
                                 f"'{pin.name}' is {pin.kind}")
        self.internal = bool(internal)

    def refresh_numbers(self) -> None:
        self.radius_a, self.radius_b = (dual.value_of(r) for r in self.exact_radii)
        super().refresh_numbers()

    def drawn(self, points: int = 49) -> list:
        """[(gear body, its pitch circle as a closed polyline in its frame)] (`drawing`)."""
        out = []
        around = np.linspace(0.0, 2.0 * np.pi, points)
        for key, radius in (("a", self.radius_a), ("b", self.radius_b)):
            role = self.side[key][1]
            joint = self.joint_a if key == "a" else self.joint_b
            centre = np.asarray(joint.attachment_points()[0 if role == "a" else 1], float)
            out.append((self.body(key, role),
                        centre + radius * np.column_stack([np.cos(around), np.sin(around)])))
        return out

    def parameter_values(self):
        ga, gb = self.side["a"][1], self.side["b"][1]
        d = self.exact_centre("b", gb) - self.exact_centre("a", ga)
        if not np.hypot(*(dual.value_of(x) for x in d)) > 0.0:
            raise ModelError(f"{self.owner}: the two pins coincide; a spur pair's centres "
                             "lie apart")
        line = dual.atan2(d[1], d[0])
        ra, rb = self.exact_radii
        rb = -rb if self.internal else rb
        offset = ra * (self.body("a", ga).exact_angle - line) + \
            rb * (self.body("b", gb).exact_angle - line)
        return self.finite((ra, rb, line - self.carrier.exact_angle, offset))

    def equations(self, ctx, p):
        pa, pb = ctx.parameters(self.joint_a), ctx.parameters(self.joint_b)
        carrier, centre_a, angle_a = self.pinion(ctx, pa)
        gb = self.side["b"][1]
        gear_b = self.body("b", gb)
        centre_b = ctx.point(gear_b, pb[f"{gb}x"], pb[f"{gb}y"], pb, gb)
        d = [centre_b[0] - centre_a[0], centre_b[1] - centre_a[1]]
        ref = carrier + p["phi0"]
        c, s = ctx.cos(ref), ctx.sin(ref)
        # The line of centres from the carrier's axis turned by its initial angle: the
        # centres' offset across it over their distance along it, 0 wherever the pins
        # hold the centres on the carrier. There it has atan2's value and, along every
        # motion the pins allow, all its derivatives; a quotient's third derivatives (the
        # sensitivities') are far cheaper for sympy than atan2's (docs/benchmarks.md).
        line = ref + (c * d[1] - s * d[0]) / (c * d[0] + s * d[1])
        return [p["ra"] * (angle_a - line) + p["rb"] * (ctx.angle(gear_b, pb, gb) - line)
                - p["offset"]]


class RackGear(_Meshed):
    """A rack and pinion: the pinion turning on revolute `pin` with pitch radius
    abs(`radius`), the rack sliding in prismatic `slide`, both on one body (the carrier): the
    rack moves `radius` along the slide's axis per radian of the pinion relative to the
    carrier (a negative radius for a rack on the other side of the pinion). The tooth
    force pushes the rack along the slide and loads the pinion's pin."""

    form = "rack"
    parameter_names = ("r", "offset")

    def __init__(self, pin: Joint, slide: Joint, radius: float, name: str | None = None):
        r = _number(radius, "radius", f"gear '{name or 'rack'}'")
        super().__init__(pin, slide, r if dual.value_of(r) else 1.0, name)
        if pin.kind != "revolute" or slide.kind != "prismatic":
            raise ModelError(f"{self.owner}: a rack and pinion needs a revolute `pin` and a "
                             f"prismatic `slide`, got {pin.kind} and {slide.kind}")
        if dual.value_of(r) == 0.0:
            raise ModelError(f"{self.owner}: `radius` must not be 0")
        self.radius_a = dual.value_of(r)

    def parameter_values(self):
        turn = self.body("a", self.side["a"][1]).exact_angle - self.carrier.exact_angle
        r = self.exact_ratio
        return self.finite((r, self.joint_b.exact_initial_coordinate() - r * turn))

    def refresh_numbers(self) -> None:
        super().refresh_numbers()
        self.radius_a = self.ratio

    def equations(self, ctx, p):
        pa, pb = ctx.parameters(self.joint_a), ctx.parameters(self.joint_b)
        carrier, centre, angle = self.pinion(ctx, pa)
        ca = self.side["a"][0]           # the rack's carrier is shared: a body of the pin
        slide = self.joint_b
        u = ctx.direction(slide.body_a, pb["ux"], pb["uy"], pb, "a")
        held = ctx.point(self.carrier, pa[f"{ca}x"], pa[f"{ca}y"], pa, ca)
        # The slide, less the pinion centre's travel along the axis (zero in the motion:
        # the pin holds the centre on the carrier; it puts the tooth force on the pinion's
        # pin), less r times the pinion's turn.
        travel = u[0] * (centre[0] - held[0]) + u[1] * (centre[1] - held[1])
        return [slide.coordinate(ctx, pb) - travel - p["r"] * (angle - carrier)
                - p["offset"]]
