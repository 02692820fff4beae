"""Scene files: a mechanism, its simulation settings and requested outputs in TOML.

    name = "four-bar"
    gravity = [0.0, -9.81]

    [parameters]                 # numbers or expressions of earlier parameters
    L = 1.0
    tilt = "radians(10)"

    [[body]]                     # a uniform rod between two points …
    name = "crank"
    rod = [[0, 0], ["L*cos(tilt)", "L*sin(tilt)"]]
    mass = 1.0
    [[body]]                     # … or a general rigid body
    name = "slider"
    mass = 0.1
    inertia = 1e-5
    position = [0.45, 0]
    [[body]]                     # … or an elastic beam with modal coordinates
    type = "flexible_beam"
    name = "coupler"
    start = [0, 0]
    end = [1, 0]                 # or `length` and `angle`
    youngs_modulus = 117e9
    density = 8910
    area = 1e-4
    second_moment = "1e-8/12"
    n_elements = 10
    n_modes = 2
    boundary = "pinned-pinned"   # default; also "clamped-free", "free-free"
    damping_ratio = 0.0

    [[joint]]
    type = "revolute"            # or "prismatic" (with `axis`)
    name = "A"
    bodies = ["ground", "crank"]
    at = [0, 0]

    [[driver]]  joint = "A", expression = "150*t"
    [[spring]]  bodies = [a, b], at_a, at_b, stiffness, rest_length, damping
    [[force]]   body, force = [fx, fy], at
    [[torque]]  body, torque

    [simulation]                 # keyword arguments of Mechanism.simulate
    t_end = 2.0
    method = "baumgarte"

    [output]
    plots = ["energy"]           # written to the output directory
    save = true                  # result as <scene>.npz
    export = "motion.xdmf"       # meshio time series of the bodies (ParaView)
    points = [["coupler", [0.5, 0.0]]]   # final positions printed in the summary

Numbers may be given as expressions (+ − * / **, pi, sin, cos, tan, sqrt, radians, degrees,
…) of the parameters; they are evaluated by a small arithmetic evaluator, not by `eval`, so
a scene cannot run code.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .model.expressions import ExpressionError, parse
from .model import (Driver, FlexibleBeam, Force, Mechanism, ModelError, Prismatic, Revolute,
                    RigidBody, Spring, Torque)


class SceneError(ModelError):
    """A scene file is malformed; the message names the file, the table and the key."""


def evaluate(text, names: dict, where: str) -> float:
    """Value of a number or an arithmetic expression string over `names` (parsed by
    `mechsim.model.expressions`, never by `eval`)."""
    if isinstance(text, bool) or not isinstance(text, (int, float, str)):
        raise SceneError(f"{where}: expected a number or an expression, got "
                         f"{type(text).__name__} {text!r:.80}")
    try:
        expression = parse(text, set(names), where)
        return expression.value(**{k: names[k] for k in expression.names})
    except ExpressionError as exc:
        raise SceneError(str(exc)) from None
    except (ArithmeticError, ValueError) as exc:
        raise SceneError(f"{where}: {text!r:.200} cannot be evaluated: {exc}") from None


@dataclass
class Scene:
    """A loaded scene: the mechanism plus what to do with it."""
    path: Path
    mechanism: Mechanism
    simulation: dict = field(default_factory=dict)
    output: dict = field(default_factory=dict)

    def simulate(self, **overrides):
        settings = {**self.simulation, **overrides}
        return self.mechanism.simulate(**settings)


_KEYS = {
    "body": {"name", "mass", "inertia", "position", "angle", "velocity", "angular_velocity",
             "rod", "type"},
    "flexible_beam": {"type", "name", "start", "end", "length", "angle", "youngs_modulus",
                      "density", "area", "second_moment", "n_elements", "n_modes", "boundary",
                      "damping_ratio", "velocity", "angular_velocity"},
    "joint": {"type", "name", "bodies", "at", "local_a", "local_b", "axis"},
    "driver": {"joint", "expression", "name"},
    "spring": {"bodies", "at_a", "at_b", "stiffness", "rest_length", "damping", "name"},
    "force": {"body", "force", "at", "name"},
    "torque": {"body", "torque", "name"},
}
_SIMULATION_KEYS = {"t_end", "method", "rtol", "atol", "max_step", "output_step", "integrator",
                    "first_step", "t_start", "alpha", "beta", "projection", "projection_tol",
                    "h", "max_steps", "rcond", "regularization", "exact_projection"}
_OUTPUT_KEYS = {"plots", "save", "points", "directory", "export"}
_TOP_KEYS = {"name", "gravity", "parameters", "simulation", "output"} | set(_KEYS) - \
    {"flexible_beam"}


def load_scene(path) -> Scene:
    """Build the mechanism described by the TOML file at `path`."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise SceneError(f"scene file {str(path)!r} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path.name}: not valid TOML: {exc}") from None
    f = path.name
    _check_keys(data, _TOP_KEYS, f"{f}")
    names: dict[str, float] = {}
    for key, value in data.get("parameters", {}).items():
        names[key] = evaluate(value, names, f"{f}: [parameters] {key}")

    def num(value, where):
        return evaluate(value, names, where)

    def vec(value, where):
        if not isinstance(value, list) or len(value) != 2:
            raise SceneError(f"{where}: expected a list of two numbers, got {value!r}")
        return (num(value[0], where), num(value[1], where))

    def opt(table, key, where, conv):
        return {} if key not in table else {key: conv(table[key], f"{where} {key}")}

    mech = Mechanism(data.get("name", path.stem),
                     gravity=vec(data.get("gravity", [0.0, -9.81]), f"{f}: gravity"))
    by_name = {}

    def body_named(name, where):
        if name == "ground":
            return mech.ground
        if name not in by_name:
            raise SceneError(f"{where}: no body named {name!r}; bodies: "
                             f"{', '.join(['ground'] + list(by_name))}")
        return by_name[name]

    def wrap(where, build):
        try:
            return build()
        except SceneError:
            raise
        except ModelError as exc:
            raise SceneError(f"{where}: {exc}") from None

    for i, t in enumerate(data.get("body", [])):
        where = f"{f}: body[{i}]" + (f" ({t['name']!r})" if "name" in t else "")
        kind = t.get("type", "rigid")
        if kind not in ("rigid", "flexible_beam"):
            raise SceneError(f"{where}: `type` must be 'rigid' or 'flexible_beam', got {kind!r}")
        _check_keys(t, _KEYS["body" if kind == "rigid" else kind], where)
        if "name" not in t:
            raise SceneError(f"{where}: needs a `name`")
        kw = {**opt(t, "velocity", where, vec), **opt(t, "angular_velocity", where, num)}
        if kind == "flexible_beam":
            body = wrap(where, lambda: _beam(t, where, num, vec, opt, kw))
        elif "rod" in t:
            rod = t["rod"]
            if not isinstance(rod, list) or len(rod) != 2:
                raise SceneError(f"{where}: `rod` must be [start, end]")
            if "inertia" in t or "position" in t or "angle" in t:
                raise SceneError(f"{where}: a `rod` body takes its inertia, position and angle "
                                 "from its end points; remove them")
            body = wrap(where, lambda: RigidBody.rod(
                t["name"], vec(rod[0], f"{where} rod start"), vec(rod[1], f"{where} rod end"),
                num(t.get("mass"), f"{where} mass"), **kw))
        else:
            for key in ("mass", "inertia"):
                if key not in t:
                    raise SceneError(f"{where}: needs `{key}` (or give a `rod`)")
            body = wrap(where, lambda: RigidBody(
                t["name"], num(t["mass"], f"{where} mass"), num(t["inertia"], f"{where} inertia"),
                **opt(t, "position", where, vec), **opt(t, "angle", where, num), **kw))
        wrap(where, lambda: mech.add(body))
        by_name[body.name] = body

    joints = {}
    for i, t in enumerate(data.get("joint", [])):
        where = f"{f}: joint[{i}]" + (f" ({t['name']!r})" if "name" in t else "")
        _check_keys(t, _KEYS["joint"], where)
        bodies = t.get("bodies")
        if not isinstance(bodies, list) or len(bodies) != 2:
            raise SceneError(f"{where}: `bodies` must name two bodies")
        a, b = (body_named(n, where) for n in bodies)
        kind = t.get("type")
        if kind == "revolute":
            kw = {**opt(t, "at", where, vec), **opt(t, "local_a", where, vec),
                  **opt(t, "local_b", where, vec)}
            joint = wrap(where, lambda: Revolute(a, b, name=t.get("name"), **kw))
        elif kind == "prismatic":
            if "axis" not in t or "at" not in t:
                raise SceneError(f"{where}: a prismatic joint needs `axis` and `at`")
            joint = wrap(where, lambda: Prismatic(a, b, axis=vec(t["axis"], f"{where} axis"),
                                                  at=vec(t["at"], f"{where} at"),
                                                  name=t.get("name")))
        else:
            raise SceneError(f"{where}: `type` must be 'revolute' or 'prismatic', got {kind!r}")
        wrap(where, lambda: mech.add(joint))
        joints[joint.name] = joint

    for i, t in enumerate(data.get("driver", [])):
        where = f"{f}: driver[{i}]"
        _check_keys(t, _KEYS["driver"], where)
        if t.get("joint") not in joints:
            raise SceneError(f"{where}: no joint named {t.get('joint')!r}; joints: "
                             f"{', '.join(joints) or '(none)'}")
        wrap(where, lambda: mech.add(Driver(joints[t["joint"]], t.get("expression", ""),
                                            name=t.get("name"))))

    for i, t in enumerate(data.get("spring", [])):
        where = f"{f}: spring[{i}]"
        _check_keys(t, _KEYS["spring"], where)
        bodies = t.get("bodies")
        if not isinstance(bodies, list) or len(bodies) != 2:
            raise SceneError(f"{where}: `bodies` must name two bodies")
        a, b = (body_named(n, where) for n in bodies)
        kw = {**opt(t, "rest_length", where, num), **opt(t, "damping", where, num)}
        wrap(where, lambda: mech.add(Spring(
            a, b, vec(t.get("at_a"), f"{where} at_a"), vec(t.get("at_b"), f"{where} at_b"),
            num(t.get("stiffness"), f"{where} stiffness"), name=t.get("name"), **kw)))

    for i, t in enumerate(data.get("force", [])):
        where = f"{f}: force[{i}]"
        _check_keys(t, _KEYS["force"], where)
        body = body_named(t.get("body"), where)
        wrap(where, lambda: mech.add(Force(body, vec(t.get("force"), f"{where} force"),
                                           **opt(t, "at", where, vec), name=t.get("name"))))

    for i, t in enumerate(data.get("torque", [])):
        where = f"{f}: torque[{i}]"
        _check_keys(t, _KEYS["torque"], where)
        body = body_named(t.get("body"), where)
        wrap(where, lambda: mech.add(Torque(body, num(t.get("torque"), f"{where} torque"),
                                            name=t.get("name"))))

    simulation = dict(data.get("simulation", {}))
    _check_keys(simulation, _SIMULATION_KEYS, f"{f}: [simulation]")
    for key, value in simulation.items():
        if key == "max_steps":
            simulation[key] = int(num(value, f"{f}: [simulation] {key}"))
        elif key not in ("method", "integrator", "projection", "regularization",
                         "exact_projection"):
            simulation[key] = num(value, f"{f}: [simulation] {key}")
    if "t_end" not in simulation:
        raise SceneError(f"{f}: [simulation] needs `t_end`")
    output = dict(data.get("output", {}))
    _check_keys(output, _OUTPUT_KEYS, f"{f}: [output]")
    return Scene(path, mech, simulation, output)


def _beam(t, where, num, vec, opt, kw) -> FlexibleBeam:
    """A FlexibleBeam from its scene table: `start` plus `end`, or `length` and `angle`."""
    if "start" not in t:
        raise SceneError(f"{where}: a flexible beam needs `start`")
    start = vec(t["start"], f"{where} start")
    if "end" in t:
        if "length" in t or "angle" in t:
            raise SceneError(f"{where}: give `end`, or `length` and `angle`, not both")
        end = vec(t["end"], f"{where} end")
        kw["length"] = math.hypot(end[0] - start[0], end[1] - start[1])
        kw["angle"] = math.atan2(end[1] - start[1], end[0] - start[0])
    elif "length" in t:
        kw["length"] = num(t["length"], f"{where} length")
        kw.update(opt(t, "angle", where, num))
    else:
        raise SceneError(f"{where}: a flexible beam needs `end` or `length`")
    for key in ("youngs_modulus", "density", "area", "second_moment"):
        if key not in t:
            raise SceneError(f"{where}: a flexible beam needs `{key}`")
        kw[key] = num(t[key], f"{where} {key}")
    for key in ("n_elements", "n_modes"):
        if key in t:
            value = num(t[key], f"{where} {key}")
            if value != int(value):
                raise SceneError(f"{where}: `{key}` must be a whole number, got {value}")
            kw[key] = int(value)
    kw.update(opt(t, "damping_ratio", where, num))
    if "boundary" in t:
        kw["boundary"] = t["boundary"]
    return FlexibleBeam(t["name"], start=start, **kw)


def _check_keys(table, allowed, where):
    if not isinstance(table, dict):
        raise SceneError(f"{where}: expected a table, got {table!r}")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise SceneError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; valid keys: "
                         f"{', '.join(sorted(allowed))}")
