"""Design files: some of a scene's parameters chosen for an objective on exact gradients
(`mechsim optimize DESIGN.toml`).

    scene = "../pump.toml"                  # the scene, relative to this file
    output = "out/pump_counterweight.toml"  # the design found (default: out/<name>.toml)
    gradient = "exact"                      # or "2-point", scipy's finite differences
    method = "least_squares"                # a path: least squares on its points' errors

    [parameters]                # the scene's [parameters] varied, from their values there,
    m_cw = [0.0, 8.0]           # each within [low, high]
    r_cw = [0.02, 0.20]

    [objective]                 # one of
    peak_effort = "motor"       # a driver's torque: its 16-norm mean, a smooth peak
    # rms_effort = "motor"      # its RMS
    # peak_joint_force = "O"    # a joint's transmitted force: the same of its magnitude
    # rms_joint_force = "O"
    # path = { body = "coupler", point = [0, 0], targets = [[x, y], ...] }

    [analysis]                  # the kinematic analysis the objective is taken over: a
    over = { driver = "motor", degrees = [0, 360, 2] }   # driver's range (from, to, step)
    # t_end = 1.0               # or times from 0 to t_end, output_step apart
    # output_step = 0.01

    [[constraint]]              # any number of them, over the same analysis
    transmission_angle = { bodies = ["coupler", "rocker"], minimum = 40.0 }   # degrees
    # grashof_crank = { links = ["a", "b", 0.25, "d"], margin = 0.005 }
    #   crank, coupler, rocker, ground: a parameter's name or a length [m]; the crank
    #   kept the shortest link of a Grashof four-bar (it turns fully)

A path's targets are reached at the samples of `over`, one each (prescribed timing).
`method` is scipy's minimizer (default L-BFGS-B, or SLSQP with constraints), or
"least_squares" for a path without constraints: trust-region least squares on the points'
errors and their exact Jacobian.
Every key, name and number is checked before any evaluation; nothing in the file is
executed. The design is written as a TOML table of the parameters' values with the
objective's value and the search's counts.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path, PurePath

import numpy as np

from ..design import optimize
from ..objectives import (EffortNorm, GrashofCrank, JointForceNorm, PathPoints,
                          TransmissionAngle)
from ..model import ModelError
from ..model.parameters import Parameter
from ..options import unknown_names
from .scene import load_scene, read_toml
from .study_file import read_with_scene

_TOP = {"scene", "output", "gradient", "method", "parameters", "objective", "analysis",
        "constraint"}
_METHODS = ("L-BFGS-B", "SLSQP", "trust-constr", "least_squares")
_OBJECTIVES = ("peak_effort", "rms_effort", "peak_joint_force", "rms_joint_force", "path")
PEAK_NORM = 16.0


class DesignFileError(ModelError):
    """A design file is malformed; the message names the file, the table and the key."""


@dataclass
class DesignFile:
    """A checked design file: the scene, the parameters' bounds, the objective (built
    for the scene's mechanism), the gradient and where the design goes."""
    path: Path
    scene: Path
    bounds: dict
    objective: object
    gradient: str
    output: Path
    constraints: tuple = ()
    method: str | None = None

    def run(self):
        """(the `mechsim.design.Design` found, the scene's mechanism set to it), from the
        scene's values of the parameters."""
        declared = read_toml(self.scene).get("parameters", {})
        loaded = load_scene(self.scene, {k: Parameter(k, float(declared[k]))
                                         for k in self.bounds})
        mech = loaded.mechanism
        design = optimize(mech, self.objective, list(self.bounds), bounds=self.bounds,
                          constraints=self.constraints, gradient=self.gradient,
                          method=self.method)
        return design, mech


def _scene_number(f, name, declared) -> None:
    """A DesignFileError where the scene does not give a varied parameter as a number."""
    value = declared[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DesignFileError(f"{f}: [parameters] {name}: the scene gives it as {value!r:.40}; "
                              "a varied parameter must be a number there")


def load_design(path) -> DesignFile:
    """Read and check the design file at `path` and the scene it names; a
    DesignFileError names the file, the table and the key."""
    path = Path(path)
    f = path.name
    data, scene, loaded = read_with_scene(path, _TOP, "a design file", DesignFileError)
    base = loaded.mechanism
    declared = read_toml(scene).get("parameters", {})
    bounds = _bounds(f, data.get("parameters"), declared)
    for name in bounds:
        _scene_number(f, name, declared)
    gradient = data.get("gradient", "exact")
    if gradient not in ("exact", "2-point", "3-point"):
        raise DesignFileError(f"{f}: `gradient` must be 'exact', '2-point' or '3-point', got "
                              f"{gradient!r:.40}")
    analysis = _analysis(f, data.get("analysis"), base)
    objective = _objective(f, data.get("objective"), base, analysis)
    output = data.get("output", f"out/{path.stem}.toml")
    if not isinstance(output, str) or PurePath(output).is_absolute() or \
            ".." in PurePath(output).parts or not output.endswith(".toml"):
        raise DesignFileError(f"{f}: `output` must be a relative path ending in .toml inside "
                              f"the working directory, got {output!r:.80}")
    constraints = _constraints(f, data.get("constraint", []), base, analysis)
    method = data.get("method")
    if method is not None and method not in _METHODS:
        raise DesignFileError(f"{f}: `method` must be one of {', '.join(_METHODS)}, got "
                              f"{method!r:.40}")
    if method == "least_squares" and (constraints or not hasattr(objective, "residuals")):
        raise DesignFileError(f"{f}: `method` 'least_squares' takes a path objective and no "
                              "[[constraint]]")
    return DesignFile(path, scene, bounds, objective, gradient, Path(output),
                      tuple(constraints), method)


def _constraints(f, tables, mech, analysis) -> list:
    """The [[constraint]] tables as mechsim constraints over the analysis."""
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise DesignFileError(f"{f}: `constraint` must be an array of tables [[constraint]]")
    out = []
    names = [b.name for b in mech.bodies]
    for i, table in enumerate(tables):
        where = f"{f}: [[constraint]] {i + 1}"
        if set(table) == {"grashof_crank"}:
            out.append(_grashof(where, table["grashof_crank"], mech))
            continue
        spec = table.get("transmission_angle")
        if set(table) != {"transmission_angle"} or not isinstance(spec, dict) or \
                set(spec) != {"bodies", "minimum"}:
            raise DesignFileError(f"{where}: expected transmission_angle = {{ bodies = "
                                  f"[\"a\", \"b\"], minimum = degrees }}, got {table!r:.80}")
        bodies, minimum = spec["bodies"], spec["minimum"]
        if not (isinstance(bodies, list) and len(bodies) == 2 and all(b in names for b in bodies)):
            raise DesignFileError(f"{where}: `bodies` must name two of the scene's bodies "
                                  f"({', '.join(names)}), got {bodies!r:.60}")
        if isinstance(minimum, bool) or not isinstance(minimum, (int, float)) or \
                not 0.0 < minimum < 90.0:
            raise DesignFileError(f"{where}: `minimum` must be degrees between 0 and 90, got "
                                  f"{minimum!r:.40}")
        out.append(TransmissionAngle(bodies[0], bodies[1], float(minimum),
                                     t_end=analysis.get("t_end"),
                                     output_step=analysis.get("output_step"),
                                     over=analysis.get("over")))
    return out


def _grashof(where, spec, mech) -> GrashofCrank:
    """A grashof_crank constraint: links (crank, coupler, rocker, ground), each a scene
    parameter's name or a length, and an optional margin."""
    if not (isinstance(spec, dict) and "links" in spec and set(spec) <= {"links", "margin"}
            and isinstance(spec["links"], list) and len(spec["links"]) == 4):
        raise DesignFileError(f"{where}: expected grashof_crank = {{ links = [crank, coupler, "
                              f"rocker, ground], margin = length }}, got {spec!r:.80}")
    for link in spec["links"]:
        if isinstance(link, str) and link not in mech.parameters:
            raise DesignFileError(f"{where}: grashof_crank: {link!r:.40} is not one of the "
                                  f"scene's [parameters]: {', '.join(mech.parameters)}")
    try:
        return GrashofCrank(*spec["links"], margin=spec.get("margin", 0.0))
    except ValueError as exc:
        raise DesignFileError(f"{where}: {exc}") from None


def _bounds(f, table, declared) -> dict:
    if not isinstance(table, dict) or not table:
        raise DesignFileError(f"{f}: [parameters] must name the scene's parameters to vary, "
                              "each with [low, high]")
    out = {}
    for name, pair in table.items():
        if name not in declared:
            raise DesignFileError(f"{f}: [parameters] {name!r} is not one of the scene's "
                                  f"[parameters]: {', '.join(declared) or '(none)'}")
        if not (isinstance(pair, list) and len(pair) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in pair)
                and pair[0] < pair[1]):
            raise DesignFileError(f"{f}: [parameters] {name}: expected [low, high] with "
                                  f"low < high, got {pair!r:.60}")
        out[name] = (float(pair[0]), float(pair[1]))
    return out


def _analysis(f, table, mech) -> dict:
    """kinematics() keywords: {"over": (driver, values)} or {"t_end", "output_step"}."""
    if not isinstance(table, dict):
        raise DesignFileError(f"{f}: [analysis] must give `over` or `t_end` and `output_step`")
    message = unknown_names(table, {"over": None, "t_end": None, "output_step": None},
                            "[analysis]")
    if message:
        raise DesignFileError(f"{f}: {message}")
    if "over" in table:
        over = table["over"]
        if not (isinstance(over, dict) and set(over) == {"driver", "degrees"}
                and isinstance(over["driver"], str) and isinstance(over["degrees"], list)
                and len(over["degrees"]) == 3
                and all(isinstance(x, (int, float)) for x in over["degrees"])):
            raise DesignFileError(f"{f}: [analysis] over: expected {{ driver = \"name\", "
                                  f"degrees = [from, to, step] }}, got {over!r:.80}")
        if over["driver"] not in [d.name for d in mech.drivers]:
            raise DesignFileError(f"{f}: [analysis] over: no driver {over['driver']!r}; "
                                  f"drivers: {', '.join(d.name for d in mech.drivers)}")
        start, stop, step = (float(x) for x in over["degrees"])
        if not step > 0 or not stop > start:
            raise DesignFileError(f"{f}: [analysis] over: degrees needs from < to and a "
                                  f"step > 0, got {over['degrees']}")
        values = np.radians(np.arange(start, stop + 0.5 * step, step))
        return {"over": (over["driver"], values)}
    if not {"t_end", "output_step"} <= set(table) or not all(
            isinstance(table[k], (int, float)) and table[k] > 0 for k in ("t_end", "output_step")):
        raise DesignFileError(f"{f}: [analysis] needs `over`, or positive `t_end` and "
                              "`output_step`")
    return {"t_end": float(table["t_end"]), "output_step": float(table["output_step"])}


def _objective(f, table, mech, analysis):
    if not isinstance(table, dict) or len(table) != 1 or next(iter(table)) not in _OBJECTIVES:
        raise DesignFileError(f"{f}: [objective] must give one of {', '.join(_OBJECTIVES)}, "
                              f"got {table!r:.80}")
    kind, subject = next(iter(table.items()))
    if kind in ("peak_effort", "rms_effort"):
        if subject not in [d.name for d in mech.drivers]:
            raise DesignFileError(f"{f}: [objective] {kind}: no driver {subject!r}; drivers: "
                                  f"{', '.join(d.name for d in mech.drivers)}")
        return EffortNorm(subject, PEAK_NORM if kind == "peak_effort" else 2.0,
                          t_end=analysis.get("t_end"), output_step=analysis.get("output_step"),
                          over=analysis.get("over"))
    if kind in ("peak_joint_force", "rms_joint_force"):
        joints = [j.name for j in mech.joints]
        if subject not in joints:
            raise DesignFileError(f"{f}: [objective] {kind}: no joint {subject!r:.40}; joints: "
                                  f"{', '.join(joints)}")
        return JointForceNorm(subject, PEAK_NORM if kind == "peak_joint_force" else 2.0,
                              t_end=analysis.get("t_end"),
                              output_step=analysis.get("output_step"),
                              over=analysis.get("over"))
    if "over" not in analysis:
        raise DesignFileError(f"{f}: [objective] path: its targets are timed by [analysis] "
                              "over (one target per sample)")
    if not (isinstance(subject, dict) and set(subject) == {"body", "point", "targets"}):
        raise DesignFileError(f"{f}: [objective] path: expected {{ body = \"name\", point = "
                              f"[x, y], targets = [[x, y], ...] }}, got {subject!r:.80}")
    if subject["body"] not in [b.name for b in mech.bodies]:
        raise DesignFileError(f"{f}: [objective] path: no body {subject['body']!r}")
    driver, values = analysis["over"]
    try:
        return PathPoints(subject["body"], subject["point"], subject["targets"], driver, values)
    except (ValueError, TypeError) as exc:
        raise DesignFileError(f"{f}: [objective] path: {exc}") from None


def write_design(spec: DesignFile, design) -> Path:
    """The design as TOML (the parameters' values, the objective's value, the counts) at
    the file's `output`, written safely (`mechsim.files`)."""
    from ..files import written
    lines = [f"# The design `mechsim optimize {spec.path.name}` found for {spec.scene.name}.",
             f"value = {design.value!r}", f"success = {str(design.success).lower()}",
             f"evaluations = {design.evaluations}", f"failures = {design.failures}", "",
             "[parameters]"]
    lines += [f"{k} = {v!r}" for k, v in design.parameters.items()]
    text = "\n".join(lines) + "\n"
    return written(spec.output, lambda p: p.write_text(text, encoding="utf-8"))
