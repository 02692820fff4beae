"""Scene files: a mechanism, its simulation settings and requested outputs in TOML (or the
same tables in JSON, for files ending in .json)::

    name = "four-bar"
    gravity = [0.0, -9.81]
    [parameters]                 # numbers or expressions of earlier parameters
    L = 1.0                      # e.g. tilt = "radians(10)"

    [[body]]                     # a uniform rod between two points …
    name = "crank"
    rod = [[0, 0], ["L", 0]]
    mass = 1.0
    [[body]]                     # … or a uniform plate: rectangle = [width, height] or
                                 # disc = radius at `position`, or polygon = its corners
    [[body]]                     # … or mass, inertia (0: a point mass on a prismatic
                                 # guide), position, angle, outline (drawn, body frame)
    [[body]]                     # … or an elastic beam with modal coordinates
    type = "flexible_beam"
    name = "coupler"
    start = [0, 0]
    end = [1, 0]                 # or `length` and `angle`
    youngs_modulus = 117e9       # and density, area, second_moment, n_elements,
    n_modes = 2                  # boundary ("pinned-pinned", …), damping_ratio

    [[joint]]
    type = "revolute"            # "prismatic" (`axis`); "curve" (centre, and line = [ux, uy],
                                 # circle = r, polar = "r(phi)" or polar_points = [[phi, r], …])
    name = "A"
    bodies = ["ground", "crank"]
    at = [0, 0]
    [[driver]]  joint = "A", expression = "150*t"   # or table = [[t, value], …] (a spline)
    [[spring]]  bodies = [a, b], at_a, at_b, stiffness, rest_length, damping
    [[rotational_spring]]  bodies = [a, b], stiffness, damping, rest_angle
    [[force]]   body, force = [fx, fy], at      [[torque]]  body, torque   # in t, too
    [[gear]]    type = "spur", joints = [a, b], radii, internal  # "rack": radius; "ratio"
    [[stop]]    joint, lower, upper, restitution, rest_speed     # an end stop (mechsim.Stop)
    [[friction]] joint, mu, mu_static, radius | length, transition_velocity, preload
    [[speed]]   joint, rate     # the joint's initial rate (Mechanism.set_speed)
    [[channel]] name, expression, unit   # recorded (mechsim.Channel): of t, "crank.angle",
                # "….rate", "….acceleration", "A.coordinate", "A.rate", the parameters
    [simulation]                 # keyword arguments of Mechanism.simulate
    t_end = 2.0
    method = "baumgarte"
    [output]
    plots = ["energy"]           # also "reactions", "efforts"
    reactions = ["A", "B"]       # joints whose peak forces the summary prints (true: all)
    efforts = true               # the drivers' peak and RMS effort and power
    animate = true               # <scene>.gif of the motion, tracing `points`
    save = true                  # result as <scene>.npz
    export = "motion.xdmf"       # meshio time series of the bodies (ParaView)
    table = "motion.csv"         # coordinates, rates, `points`, `reactions`, efforts, channels
    points = [["coupler", [0.5, 0.0]]]   # final positions printed in the summary
    directory = "out/four_bar"   # relative, inside the working directory

Numbers may be expressions (``+ − * / **``, pi, sin, …, radians, degrees) of the
parameters, parsed by `mechsim.model.expressions`, never by `eval`: a scene cannot run
code. Every table and key is checked against one schema (`SCHEMA`; `[simulation]` against
`mechsim.run.solver.simulate` and every method) before anything is built or run: an unknown
key (with the closest valid one), a wrong type, a missing key, an output path leaving the
output directory or an unknown plot is a `SceneError` naming file, table and key.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path, PurePath


from ..facade import Mechanism
from ..model.parameters import Dual, Parameter, value_of
from ..model.expressions import FUNCTIONS, ExpressionError, parse
from ..model.forces import TimeLaw
from .scene_build import SceneError, body_named, build
from ..options import unknown_names


MAX_SCENE_BYTES = 4 * 2 ** 20
PLOTS = ("energy", "reactions", "efforts")
MAX_VERTICES = 10_000           # points of a polygon or an outline
MAX_ROWS = 100_000              # rows of a driver's table


def evaluate(text, names: dict, where: str) -> float:
    """Value of a number or an arithmetic expression string over `names` (parsed by
    `mechsim.model.expressions`, never by `eval`): a Dual where it depends on a Parameter
    among `names` (`load_scene(path, parameters={"r": ms.Parameter("r", 0.05)})`)."""
    if isinstance(text, bool) or not isinstance(text, (int, float, str)):
        raise SceneError(f"{where}: expected a number or an expression, got "
                         f"{_kind(text)} {_show(text)}")
    try:
        expression = parse(text, set(names), where)
        return expression.exact_value(**{k: names[k] for k in expression.names})
    except ExpressionError as exc:
        raise SceneError(str(exc)) from None
    except (ArithmeticError, ValueError) as exc:
        raise SceneError(f"{where}: {_show(text)} cannot be evaluated: {exc}") from None


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _kind(value) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean"}.get(
        type(value), type(value).__name__)


@dataclass
class Scene:
    """A loaded scene: the mechanism, its simulation settings (keyword arguments of
    `Mechanism.simulate`) and its checked `[output]` table."""
    path: Path
    mechanism: Mechanism
    simulation: dict = field(default_factory=dict)
    output: dict = field(default_factory=dict)

    def simulate(self, **overrides):
        settings = {**self.simulation, **overrides}
        return self.mechanism.simulate(**settings)


# --- the schema ------------------------------------------------------------------------------
# Each key's kind: "name" (a non-empty string), "text" (a string), "number" (a number or an
# expression of the parameters), "vector" ([number, number]), "segment" ([vector, vector]),
# "bodies" ([name, name]), "count" (a whole number ≥ 1), a tuple of allowed strings, "flag"
# (true or false). A key in REQUIRED must be given.
SCHEMA = {
    "body": {"name": "name", "type": ("rigid", "flexible_beam"), "mass": "number",
             "inertia": "number", "position": "vector", "angle": "number",
             "velocity": "vector", "angular_velocity": "number", "rod": "segment",
             "rectangle": "vector", "disc": "number", "polygon": "polygon",
             "outline": "polygon"},
    "flexible_beam": {"type": ("flexible_beam",), "name": "name", "start": "vector",
                      "end": "vector", "length": "number", "angle": "number",
                      "youngs_modulus": "number", "density": "number", "area": "number",
                      "second_moment": "number", "n_elements": "count", "n_modes": "count",
                      "boundary": ("pinned-pinned", "clamped-free", "free-free"),
                      "damping_ratio": "number", "velocity": "vector",
                      "angular_velocity": "number"},
    "joint": {"type": ("revolute", "prismatic", "curve"), "name": "name", "bodies": "bodies",
              "at": "vector", "local_a": "vector", "local_b": "vector", "axis": "vector",
              "centre": "vector", "line": "vector", "circle": "number", "polar": "name",
              "polar_points": "curve_points"},
    "driver": {"joint": "name", "expression": "driver", "name": "name", "table": "rows"},
    "spring": {"bodies": "bodies", "at_a": "vector", "at_b": "vector", "stiffness": "number",
               "rest_length": "number", "damping": "number", "name": "name"},
    "force": {"body": "name", "force": "load_vector", "at": "vector", "name": "name"},
    "torque": {"body": "name", "torque": "load", "name": "name"},
    "rotational_spring": {"bodies": "bodies", "stiffness": "number", "damping": "number",
                          "rest_angle": "number", "name": "name"},
    "speed": {"joint": "name", "rate": "number"},
    "stop": {"joint": "name", "lower": "number", "upper": "number", "restitution": "number",
             "rest_speed": "number", "name": "name"},
    "friction": {"joint": "name", "mu": "number", "mu_static": "number", "radius": "number",
                 "length": "number", "transition_velocity": "number", "preload": "number",
                 "name": "name"},
    "gear": {"type": ("spur", "rack", "ratio"), "joints": "bodies", "name": "name",
             "radii": "vector", "radius": "number", "ratio": "number", "internal": "flag",
             "carrier": "name"},
    "channel": {"name": "name", "expression": "name", "unit": "name"},
    "output": {"plots": "plots", "save": "flag", "points": "points", "directory": "path",
               "export": "path", "reactions": "joints", "efforts": "flag", "animate": "flag",
               "table": "path"},
}
REQUIRED = {
    "body": ("name",), "flexible_beam": ("name", "start", "youngs_modulus", "density", "area",
                                         "second_moment"),
    "joint": ("type", "bodies"), "driver": ("joint",),
    "spring": ("bodies", "at_a", "at_b", "stiffness"), "force": ("body", "force"),
    "torque": ("body", "torque"), "rotational_spring": ("bodies", "stiffness"), "output": (),
    "speed": ("joint", "rate"), "channel": ("name", "expression"),
    "gear": ("type", "joints"), "stop": ("joint",), "friction": ("joint", "mu"),
}
_ARRAYS = ("body", "joint", "driver", "gear", "stop", "friction", "spring", "force",
           "torque", "rotational_spring", "speed", "channel")
_TOP = {"name": "name", "gravity": "vector", "parameters": "table", "simulation": "table",
        "output": "table", **{k: "array" for k in _ARRAYS}}


class _Reader:
    """Reads values of the schema's kinds from one scene, with the parameters in scope."""

    def __init__(self, file: str):
        self.file = file
        self.names: dict[str, float] = {}

    def error(self, where, message):
        return SceneError(f"{self.file}: {where}: {message}")

    def value(self, kind, value, where):
        if isinstance(kind, tuple):
            if value not in kind:
                raise self.error(where, f"must be one of {', '.join(map(repr, kind))}, got "
                                        f"{_show(value)}")
            return value
        if kind == "driver":
            # A law in t and the scene's parameters, checked here; the scene builder binds
            # the parameters it uses (`Driver(values=...)`: Parameters stay differentiable).
            if isinstance(value, str) and self.names:
                self._parsed(value, where)
            return value
        if kind in ("load", "load_vector"):
            return self._load(kind == "load_vector", value, where)
        if kind in ("name", "text", "path"):
            if not isinstance(value, str) or (kind != "text" and not value.strip()):
                raise self.error(where, f"expected a non-empty string, got {_kind(value)} "
                                        f"{_show(value)}")
            if kind == "path":
                self._path(value, where)
            return value
        if kind == "number":
            return evaluate(value, self.names, f"{self.file}: {where}")
        if kind == "count":
            x = self.value("number", value, where)
            if isinstance(x, Dual):
                raise self.error(where, "a count cannot depend on a Parameter")
            if x != int(x) or x < 1:
                raise self.error(where, f"must be a whole number ≥ 1, got {x:g}")
            return int(x)
        if kind == "flag":
            if not isinstance(value, bool):
                raise self.error(where, f"must be true or false, got {_kind(value)} "
                                        f"{_show(value)}")
            return value
        if kind in ("vector", "segment", "bodies"):
            if not isinstance(value, list) or len(value) != 2:
                what = {"vector": "two numbers", "segment": "two points [[x, y], [x, y]]",
                        "bodies": "two body names"}[kind]
                raise self.error(where, f"expected an array of {what}, got {_show(value)}")
            item = {"vector": "number", "segment": "vector", "bodies": "name"}[kind]
            return tuple(self.value(item, v, where) for v in value)
        if kind in ("rows", "polygon", "curve_points"):
            low, high, what = {"rows": (1, MAX_ROWS, "rows [t, value]"),
                               "polygon": (3, MAX_VERTICES, "points [x, y]"),
                               "curve_points": (4, MAX_ROWS, "points [phi, r]")}[kind]
            if not isinstance(value, list) or not low <= len(value) <= high:
                raise self.error(where, f"expected an array of {low} to {high} {what}, got "
                                        f"{_show(value)}")
            return [self.value("vector", v, where) for v in value]
        if kind == "plots":
            if not isinstance(value, list):
                raise self.error(where, f"expected an array of plot names, got {_show(value)}")
            return [self.value(PLOTS, v, where) for v in value]
        if kind == "joints":
            if value is True:
                return True
            if not isinstance(value, list):
                raise self.error(where, f"expected true or an array of joint names, got "
                                        f"{_show(value)}")
            return [self.value("name", v, where) for v in value]
        if kind == "points":
            if not isinstance(value, list) or not all(isinstance(p, list) and len(p) == 2
                                                      for p in value):
                raise self.error(where, "expected an array of [body name, [x, y]] pairs, got "
                                        f"{_show(value)}")
            return [(self.value("name", b, where), self.value("vector", p, where))
                    for b, p in value]
        raise AssertionError(kind)

    def _parsed(self, text, where):
        """`text` parsed as an expression of t and the parameters."""
        try:
            return parse(text, {"t", *self.names}, f"{self.file}: {where}")
        except ExpressionError as exc:
            raise SceneError(str(exc)) from None

    def _bound(self, text, where):
        """`text` parsed as an expression of t and the parameters, the parameters bound."""
        law = self._parsed(text, where)
        exact = sorted(k for k in law.names if isinstance(self.names.get(k), Dual))
        if exact:
            raise self.error(where, f"depends on the Parameter(s) {', '.join(exact)}: a "
                                    "load cannot depend on a Parameter yet")
        return law.bind(**{k: self.names[k] for k in law.names if k != "t"})

    def _load(self, many, value, where):
        """A torque (or with `many` a force's two components): numbers, or expressions of
        the parameters and the time t, then a load in time (`TimeLaw`)."""
        if many and (not isinstance(value, list) or len(value) != 2):
            raise self.error(where, f"expected an array of two numbers or expressions in t, "
                                    f"got {_show(value)}")
        laws = [self._bound(item, where) for item in (value if many else [value])]
        if all("t" not in law.names for law in laws):
            values = tuple(self.value("number", law.text, where) for law in laws)
            return values if many else values[0]
        return TimeLaw([law.text for law in laws], where)

    def _path(self, value, where):
        """A relative path that stays where it is put: no `..`, not absolute."""
        path = PurePath(value)
        if path.is_absolute() or path.drive or ".." in path.parts or "\0" in value \
                or not path.parts:
            raise self.error(where, f"must be a relative path inside the output directory "
                                    f"(no '..', not absolute), got {_show(value)}")

    def table(self, raw, schema_name, where):
        """The keys of one table, each read by its kind; unknown and missing keys named."""
        if not isinstance(raw, dict):
            raise self.error(where, f"expected a table, got {_kind(raw)} {_show(raw)}")
        schema = SCHEMA[schema_name]
        message = unknown_names(raw, schema, "this table")
        if message:
            raise self.error(where, message.replace("this table does not take",
                                                    "unknown key(s)"))
        for key in REQUIRED[schema_name]:
            if key not in raw:
                raise self.error(where, f"needs `{key}`")
        return {key: self.value(schema[key], value, f"{where} {key}")
                for key, value in raw.items()}


# Names a parameter may not take: it would silently stand for something else in a law.
RESERVED = {"t": "time, in driver laws", "pi": "the constant π", "e": "the constant e",
            **{name: "a function" for name in FUNCTIONS}}


def load_scene(path, parameters: dict | None = None, *, run: bool = True) -> Scene:
    """Build the mechanism described by the TOML file at `path`, checking every table and
    key first (see the module docstring); a malformed scene is a SceneError. `parameters`:
    numbers that replace the values of the scene's `[parameters]` of those names (the
    later parameters computed from them follow), as a parameter study varies them. With
    `run` false the scene may have no [simulation] table (a model: `load_mechanism`)."""
    path = Path(path)
    return scene_from(read_toml(path), path, parameters, run=run)


def scene_from(data: dict, path, parameters: dict | None = None, *, run: bool = True) -> Scene:
    """`load_scene` of a scene already read into `data` (a dict of the schema); `path`
    names it in messages."""
    path = Path(path)
    f = path.name
    r = _Reader(f)
    message = unknown_names(data, _TOP, "a scene")
    if message:
        raise SceneError(f"{f}: " + message.replace("a scene does not take",
                                                    "unknown top-level key(s)"))
    for key, kind in _TOP.items():
        if key in data and kind == "table" and not isinstance(data[key], dict):
            raise SceneError(f"{f}: `{key}` must be a table [{key}], got {_kind(data[key])} "
                             f"{_show(data[key])}")
        if key in data and kind == "array" and not (
                isinstance(data[key], list) and all(isinstance(t, dict) for t in data[key])):
            raise SceneError(f"{f}: `{key}` must be an array of tables [[{key}]], got "
                             f"{_kind(data[key])} {_show(data[key])}")
    declared = data.get("parameters", {})
    given = dict(parameters or {})
    unknown = [k for k in given if k not in declared]
    if unknown:
        raise SceneError(f"{f}: no [parameters] named {', '.join(map(repr, unknown))} to "
                         f"replace; parameters: {', '.join(declared) or '(none)'}")
    for key, value in declared.items():
        if not key.isidentifier():
            raise SceneError(f"{f}: [parameters] {key!r} is not a valid name (letters, digits "
                             "and underscores, not starting with a digit)")
        if key in RESERVED:
            raise SceneError(f"{f}: [parameters] {key!r} is a reserved name ({RESERVED[key]}); "
                             "choose another")
        replaced = given.get(key, value)
        r.names[key] = replaced if isinstance(replaced, Parameter) else \
            evaluate(replaced, r.names, f"{f}: [parameters] {key}")
    name = r.value("name", data.get("name", path.stem), "name")
    gravity = r.value("vector", data.get("gravity", [0.0, -9.81]), "gravity")
    tables = {key: [] for key in _ARRAYS}
    for key in _ARRAYS:
        for i, raw in enumerate(data.get(key, [])):
            label = raw.get("name") if isinstance(raw.get("name"), str) else None
            where = f"{key}[{i}]" + (f" ({label!r})" if label else "")
            schema = key
            if key == "body" and raw.get("type") == "flexible_beam":
                schema = "flexible_beam"
            tables[key].append((where, r.table(raw, schema, where)))
    output = r.table(data.get("output", {}), "output", "[output]")
    if "export" in output:
        from ..results.export import check_format
        try:
            check_format(output["export"])
        except ValueError as exc:
            raise r.error("[output] export", str(exc)) from None
    if "table" in output and PurePath(output["table"]).suffix.lower() != ".csv":
        raise r.error("[output] table", f"the table is written as CSV: its name ends in .csv, "
                                        f"got {_show(output['table'])}")
    mech = build(r, name, gravity, tables)
    for body, _ in output.get("points", []):
        body_named(r, mech, body, "[output] points")
    wanted = output.get("reactions")
    names = [j.name for j in mech.joints]
    for joint in wanted if isinstance(wanted, list) else ():
        if joint not in names:
            raise r.error("[output] reactions", f"no joint named {joint!r}; joints: "
                                                f"{', '.join(names) or '(none)'}")
    if (output.get("efforts") or "efforts" in output.get("plots", ())) and not mech.drivers:
        raise r.error("[output] efforts", "the mechanism has no driver")
    simulation = _simulation(r, data.get("simulation", {}), mech) \
        if run or "simulation" in data else {}
    return Scene(path, mech, simulation, output)


def read_toml(path) -> dict:
    """The TOML file at `path` (a str or Path; a scene in JSON where it ends in .json) as a
    dict; a SceneError names the file where it is missing, too large or not TOML (JSON)."""
    path = Path(path)
    f = path.name
    try:
        if path.stat().st_size > MAX_SCENE_BYTES:
            raise SceneError(f"{f}: the scene file is larger than {MAX_SCENE_BYTES} bytes")
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise SceneError(f"scene file {str(path)!r} does not exist") from None
    except IsADirectoryError:
        raise SceneError(f"{str(path)!r} is a directory, not a scene file") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{f}: not UTF-8 text (byte {exc.start}); save the scene as "
                         "UTF-8") from None
    except OSError as exc:
        raise SceneError(f"scene file {str(path)!r} cannot be read: "
                         f"{exc.strerror or exc}") from None
    if path.suffix.lower() == ".json":
        import json
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SceneError(f"{f}: not valid JSON: {exc}") from None
        except RecursionError:
            raise SceneError(f"{f}: nested too deeply to read") from None
        if not isinstance(data, dict):
            raise SceneError(f"{f}: a scene in JSON is an object, got {_kind(data)}")
        return data
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{f}: not valid TOML: {exc}") from None
    except RecursionError:
        raise SceneError(f"{f}: nested too deeply to read") from None


def _simulation(r, raw, mech) -> dict:
    """The [simulation] table as keyword arguments of `Mechanism.simulate`, each value read
    by the kind its `Option` declares and checked by `mechsim.run.solver`'s own checks."""
    from ..formulations import METHODS
    from ..options import Option
    from ..run.solver import SETTINGS, check_simulate_arguments

    where = "[simulation]"
    if "t_end" not in raw:
        raise r.error(where, "needs `t_end`")
    options = {k: o for c in METHODS.values() for k, o in c.options.items()}
    kinds = {**SETTINGS, **options, "t_end": Option.real(None),
             "method": Option.choice(None, tuple(METHODS)), "integrator": Option.choice(None, ())}
    message = unknown_names(raw, kinds, "[simulation]")
    if message:
        raise r.error(where, message.replace("[simulation] does not take", "unknown key(s)"))
    out = {}
    for key, value in raw.items():
        kind, at = kinds[key].kind, f"{where} {key}"
        if kind in ("real", "integer"):
            # A setting, not a design number: a Parameter's value (sample times are
            # fixed where sensitivities are taken).
            out[key] = value_of(r.value("number", value, at))
        elif kind == "pair":
            out[key] = r.value("vector", value, at)
        elif kind == "flag":
            out[key] = r.value("flag", value, at)
        else:
            out[key] = r.value("text", value, at)
    method = out.get("method")
    rest = {k: v for k, v in out.items() if k not in ("t_end", "method")}
    try:
        check_simulate_arguments(len(mech.coordinate_names), out["t_end"], method, rest)
    except ValueError as exc:
        raise r.error(where, str(exc)) from None
    return out


def load_mechanism(path):
    """The Mechanism of the scene at `path` (TOML, or JSON where it ends in .json): what
    `Mechanism.save` wrote, or any scene file."""
    return load_scene(path, run=False).mechanism
