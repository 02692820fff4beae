"""Building a scene's mechanism from its checked tables (`mechsim.app.scene`): bodies from
their shapes, joints, drivers, gears, loads, speeds and channels, each error re-raised
naming the table it came from."""

from __future__ import annotations

import math

import numpy as np

from ..facade import Mechanism
from ..model import Channel, Driver, FlexibleBeam, Force, Friction, Gear, ModelError, PointOnCurve, Prismatic, Revolute, RigidBody, RotationalSpring, Spring, Stop, Torque
from ..model.channels import channel_names
from ..model.expressions import parse


class SceneError(ModelError):
    """A scene file is malformed; the message names the file, the table and the key."""


def body_named(r, mech, name, where):
    try:
        return mech.body(name)
    except KeyError:
        raise r.error(where, f"no body named {name!r}; bodies: "
                             f"{', '.join(b.name for b in [mech.ground] + mech.bodies)}") from None


# Elements on a joint: their scene table, class and keyword arguments.
ON_JOINTS = {"stop": (Stop, ("lower", "upper", "restitution", "rest_speed", "name")),
             "friction": (Friction, ("mu", "mu_static", "radius", "length",
                                     "transition_velocity", "preload", "name"))}


def joint_named(r, joints, name, where):
    """The joint called `name` among those built (`joints`: name -> joint), else a
    SceneError naming the table and the joints there are."""
    if name not in joints:
        raise r.error(where, f"no joint named {name!r}; joints: {', '.join(joints) or '(none)'}")
    return joints[name]


def build(r, name, gravity, tables) -> Mechanism:
    """The Mechanism from the checked tables; a ModelError is re-raised naming the table."""
    def make(where, build):
        try:
            return build()
        except SceneError:
            raise
        except ModelError as exc:
            raise r.error(where, str(exc)) from None

    mech = make("name", lambda: Mechanism(name, gravity=gravity))
    for where, t in tables["body"]:
        body = make(where, lambda: _body_from(r, t, where))
        make(where, lambda: mech.add(body))
    joints = {}
    for where, t in tables["joint"]:
        a, b = (body_named(r, mech, n, where) for n in t["bodies"])
        stray = [k for k in ("centre", "line", "circle", "polar", "polar_points") if k in t]
        if stray and t["type"] != "curve":
            raise r.error(where, f"a {t['type']} joint has no `{stray[0]}` (a curve joint has)")
        if t["type"] == "revolute":
            if "axis" in t:
                raise r.error(where, "a revolute joint has no `axis`")
            kw = {k: t[k] for k in ("at", "local_a", "local_b") if k in t}
            joint = make(where, lambda: Revolute(a, b, name=t.get("name"), **kw))
        elif t["type"] == "prismatic":
            if "axis" not in t or "at" not in t:
                raise r.error(where, "a prismatic joint needs `axis` and `at`")
            joint = make(where, lambda: Prismatic(a, b, axis=t["axis"], at=t["at"],
                                                  name=t.get("name")))
        else:
            forms = [k for k in ("line", "circle", "polar", "polar_points") if k in t]
            if len(forms) != 1 or "at" not in t:
                raise r.error(where, "a curve joint needs `at` and one of `line`, `circle`, "
                                     "`polar`, `polar_points`")
            form = forms[0].removesuffix("_points")
            joint = make(where, lambda: PointOnCurve(a, b, at=t["at"], centre=t.get("centre"),
                                                     curve=(form, t[forms[0]]),
                                                     name=t.get("name")))
        make(where, lambda: mech.add(joint))
        joints[joint.name] = joint
    for where, t in tables["driver"]:
        joint = joint_named(r, joints, t["joint"], where)
        if ("expression" in t) == ("table" in t):
            raise r.error(where, "needs an `expression` or a `table`, one of them")
        make(where, lambda: mech.add(Driver(joint, t.get("expression"), name=t.get("name"),
                                            table=t.get("table"),
                                            values=_law_values(r, t.get("expression")))))
    for key, (kind, keys) in ON_JOINTS.items():
        for where, t in tables[key]:
            joint = joint_named(r, joints, t["joint"], where)
            make(where, lambda: mech.add(kind(joint, **{k: t[k] for k in keys if k in t})))
    for where, t in tables["gear"]:
        make(where, lambda: mech.add(_gear(r, mech, joints, t, where)))
    for where, t in tables["spring"]:
        a, b = (body_named(r, mech, n, where) for n in t["bodies"])
        kw = {k: t[k] for k in ("rest_length", "damping", "name") if k in t}
        make(where, lambda: mech.add(Spring(a, b, t["at_a"], t["at_b"], t["stiffness"], **kw)))
    for where, t in tables["force"]:
        body = body_named(r, mech, t["body"], where)
        kw = {k: t[k] for k in ("at", "name") if k in t}
        make(where, lambda: mech.add(Force(body, t["force"], **kw)))
    for where, t in tables["torque"]:
        body = body_named(r, mech, t["body"], where)
        make(where, lambda: mech.add(Torque(body, t["torque"], name=t.get("name"))))
    for where, t in tables["rotational_spring"]:
        a, b = (body_named(r, mech, n, where) for n in t["bodies"])
        kw = {k: t[k] for k in ("damping", "rest_angle", "name") if k in t}
        make(where, lambda: mech.add(RotationalSpring(a, b, t["stiffness"], **kw)))
    for where, t in tables["speed"]:
        joint = joint_named(r, joints, t["joint"], where)
        make(where, lambda: mech.set_speed(joint, t["rate"]))
    for where, t in tables["channel"]:
        make(where, lambda: mech.add(_channel(r, mech, t, where)))
    return mech


def _gear(r, mech, joints, t, where) -> Gear:
    """A [[gear]]: type "spur" (radii = [r_a, r_b], internal, carrier), "rack" (radius)
    or "ratio" (ratio) between its two `joints`."""
    missing = [n for n in t["joints"] if n not in joints]
    if missing:
        raise r.error(where, f"no joint named {missing[0]!r}; joints: "
                             f"{', '.join(joints) or '(none)'}")
    a, b = (joints[n] for n in t["joints"])
    need = {"spur": "radii", "rack": "radius", "ratio": "ratio"}[t["type"]]
    extra = [k for k in ("radii", "radius", "ratio", "internal", "carrier")
             if k in t and k != need and not (k in ("internal", "carrier") and
                                              t["type"] == "spur")]
    if need not in t or extra:
        raise r.error(where, f"a {t['type']} gear takes `{need}`" +
                      (f", not `{extra[0]}`" if extra else ""))
    if t["type"] == "spur":
        carrier = body_named(r, mech, t["carrier"], where) if "carrier" in t else None
        return Gear.spur(a, b, *t["radii"], internal=t.get("internal", False),
                         name=t.get("name"), carrier=carrier)
    if t["type"] == "rack":
        return Gear.rack(a, b, t["radius"], name=t.get("name"))
    return Gear(a, b, t["ratio"], name=t.get("name"))


def _law_values(r, text):
    """The scene's parameters a driver's law uses, {name: number or Parameter}: bound by
    `Driver(values=...)`, so that a design's Parameter in a law keeps its derivatives."""
    if not isinstance(text, str) or not r.names:
        return None
    names = parse(text, {"t", *r.names}, "law").names - {"t"}
    return {k: r.names[k] for k in sorted(names)} or None


def _channel(r, mech, t, where) -> Channel:
    """A [[channel]]: its expression in the mechanism's names (`Channel`) and the scene's
    parameters, the parameters bound to their values."""
    law = parse(t["expression"], channel_names(mech) | set(r.names),
                f"{r.file}: {where} expression")
    text = law.bind(**{k: r.names[k] for k in law.names if k in r.names}).text
    return Channel(t["name"], text, t.get("unit", "-"))


def _body_from(r, t, where):
    """A rigid body (from `mass` and `inertia`, or a shape: `rod`, `rectangle`, `disc`,
    `polygon`) or a flexible beam."""
    if t.get("type") == "flexible_beam":
        return _beam(r, t, where)
    shapes = [k for k in SHAPES if k in t]
    if len(shapes) > 1:
        raise r.error(where, f"give one shape, got {', '.join(f'`{k}`' for k in shapes)}")
    if "mass" not in t:
        raise r.error(where, "needs `mass`")
    kw = {k: t[k] for k in ("velocity", "angular_velocity") if k in t}
    if shapes:
        shape = shapes[0]
        for key in ("inertia", "outline", *SHAPES[shape][0]):
            if key in t:
                raise r.error(where, f"a `{shape}` body takes its inertia{SHAPES[shape][1]} "
                                     f"from its shape; remove `{key}`")
        if shape in ("rectangle", "disc") and "position" not in t:
            raise r.error(where, f"a `{shape}` body needs `position`, its centre")
        if shape == "rod":
            return RigidBody.rod(t["name"], *t["rod"], t["mass"], **kw)
        if shape == "rectangle":
            return RigidBody.rectangle(t["name"], t["position"], *t["rectangle"], t["mass"],
                                       angle=t.get("angle", 0.0), **kw)
        if shape == "disc":
            return RigidBody.disc(t["name"], t["position"], t["disc"], t["mass"], **kw)
        return RigidBody.polygon(t["name"], t["polygon"], t["mass"], **kw)
    if "inertia" not in t:
        raise r.error(where, "needs `inertia` (or a shape: " +
                      ", ".join(f"`{k}`" for k in SHAPES) + ")")
    kw.update({k: t[k] for k in ("position", "angle") if k in t})
    body = RigidBody(t["name"], t["mass"], t["inertia"], **kw)
    if "outline" in t:
        points = np.array(t["outline"], float)
        closed = np.allclose(points[0], points[-1], rtol=0, atol=1e-12 * np.ptp(points))
        body.outline = points if closed else np.vstack([points, points[:1]])
    return body


# A body's shape: (the keys it replaces besides `inertia`, what else it gives).
SHAPES = {"rod": (("position", "angle"), ", position and angle"),
          "rectangle": ((), ""),
          "disc": (("angle",), ""),
          "polygon": (("position", "angle"), ", position and angle")}


def _beam(r, t, where) -> FlexibleBeam:
    """A FlexibleBeam from its checked table: `start` plus `end`, or `length` and `angle`."""
    kw = {k: t[k] for k in ("youngs_modulus", "density", "area", "second_moment", "n_elements",
                            "n_modes", "boundary", "damping_ratio", "velocity",
                            "angular_velocity") if k in t}
    start = t["start"]
    if "end" in t:
        if "length" in t or "angle" in t:
            raise r.error(where, "give `end`, or `length` and `angle`, not both")
        end = t["end"]
        kw["length"] = math.hypot(end[0] - start[0], end[1] - start[1])
        kw["angle"] = math.atan2(end[1] - start[1], end[0] - start[0])
    elif "length" in t:
        kw["length"] = t["length"]
        if "angle" in t:
            kw["angle"] = t["angle"]
    else:
        raise r.error(where, "a flexible beam needs `end` or `length`")
    return FlexibleBeam(t["name"], start=start, **kw)
